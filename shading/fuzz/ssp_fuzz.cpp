// libFuzzer target: the exact-profile table loader (load_profile_tables) on arbitrary bytes, and
// the evaluation of what it accepts.
//
// Every input is read as given and with its checksum field (bytes 24..31) replaced by the
// file's checksum (profile_file_checksum: the whole file, format 3), so mutations of the header
// and the payload reach the field and value checks. An accepted file must serialise back to the same bytes (the
// format has one canonical form) and give finite, non-negative profiles, totals and factors at
// reduced albedos from 0 to 1 anywhere inside its g and eta range. Loader errors are
// ProfileError; anything else (or a failed check) is a crash.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "fuzz_util.h"
#include "shading/subsurface/ss_profile.h"
#include "shading/core/bytes.h"

using namespace shading;

namespace {

bool fix_ssp_checksum(const uint8_t* data, size_t size, std::vector<uint8_t>& out) {
    if (size < 32) return false;
    out.assign(data, data + size);
    bytes::wr_u64(out, 24, profile_file_checksum(out.data(), size));
    return true;
}

void exercise(const ProfileTables& t, const uint8_t* data, size_t size) {
    const std::vector<uint8_t> again = t.serialize();
    fuzz_check(again.size() == size && std::memcmp(again.data(), data, size) == 0, "canonical round trip");
    const ProfileBuildSettings& s = t.settings;
    const double inf = std::numeric_limits<double>::infinity();
    for (double gf : {0.0, 0.5, 1.0})
        for (double ef : {0.0, 0.37, 1.0})
            for (double ap : {0.0, 0.2, 0.9, 0.9999, 1.0}) {
                const double g = s.g.front() + gf * (s.g.back() - s.g.front());
                const double eta = s.eta.front() + ef * (s.eta.back() - s.eta.front());
                const bool semi = s.thickness.back() == inf;
                const double d = semi ? inf : std::sqrt(s.thickness.front() * s.thickness.back()) * (1.0 - ap * g);
                for (int face = 0; face < t.faces; ++face) {
                    try {
                        const ChannelProfile p(t, ap, g, eta, d, face);
                        fuzz_check(std::isfinite(p.total()) && p.total() >= 0, "finite total");
                        for (double r : {0.0, 1e-3, 0.3, 7.0, 5e3}) {
                            const double v = p.rd(r), dv = p.disc(r);
                            fuzz_check(std::isfinite(v) && v >= 0 && std::isfinite(dv) && dv >= 0, "finite profile");
                        }
                        for (double c : {0.0, 0.2, 1.0}) {
                            const double x = p.exit_factor(c), n = p.entry_factor(c);
                            fuzz_check(std::isfinite(x) && x >= 0 && std::isfinite(n) && n >= 0, "finite factors");
                        }
                    } catch (const std::invalid_argument&) {
                        // a slab thickness outside the nodes at this g: reported, not a crash
                        fuzz_check(!semi, "semi-infinite tables evaluate everywhere in range");
                    }
                }
            }
}

void load(const uint8_t* data, size_t size) {
    std::shared_ptr<const ProfileTables> t;
    try {
        t = load_profile_tables(data, size, "fuzz.ssp");
    } catch (const ProfileError&) {
        return;
    }
    exercise(*t, data, size);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return run_with_fixed_checksum(data, size, load, fix_ssp_checksum);
}
