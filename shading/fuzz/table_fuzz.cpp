// libFuzzer target: the whole .brdf loader (load_table) on arbitrary bytes: header,
// value checks, the no-data fill, folding, pole averaging and the albedo, in every layout
// (half/difference tables: their pole means, albedo and angle lookups too).
//
// Every input is read as given and with its checksum fixed (fuzz_util.h), so mutations of
// the payload reach the value checks. The reject policy (POV-Ray's) runs on every input;
// the fill policy (brdftool's) only where the payload has no-data values, as it gives the
// same table otherwise. A table that loads must give finite, non-negative lookups and
// albedo, and encode_table must write a file whose header parses and whose payload holds
// the same floats. Loader errors are TableError; anything else is a crash.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz_util.h"
#include "shading/tables/table.h"

using namespace shading;

namespace {

void exercise(const BrdfTable& t) {
    const double dirs[][3] = {{0, 0, 1}, {0.6, 0, 0.8}, {-0.6, 0, 0.8}, {0.3, 0.4, 0.866}, {1, 0, 0}, {0.8, 0.6, 0}};
    for (const auto& a : dirs)
        for (const auto& b : dirs)
            for (Interp in : {Interp::Linear, Interp::Nearest}) {
                Rgb v = t.f(Vec3(a[0], a[1], a[2]), Vec3(b[0], b[1], b[2]), in);
                for (int c = 0; c < 3; ++c) fuzz_check(std::isfinite(v[c]) && v[c] >= 0, "finite non-negative lookup");
            }
    for (double th : {0.0, 0.3, 1.2, 1.5707963267948966}) {
        Rgb a = t.directional_albedo(th);
        for (int c = 0; c < 3; ++c) fuzz_check(std::isfinite(a[c]) && a[c] >= 0, "finite non-negative albedo");
    }
    if (t.halfdiff()) {  // the angle lookups, at the poles, the phi_d wrap and out of range
        const double angles[] = {0.0, 1e-12, 0.5, 1.5707963267948966, 3.14159265358979, -2.0, 1e300};
        for (double a : angles)
            for (double b : angles)
                for (Interp in : {Interp::Linear, Interp::Nearest}) {
                    Rgb v = t.eval_halfdiff(a, b, a + b, in);
                    for (int c = 0; c < 3; ++c) fuzz_check(std::isfinite(v[c]) && v[c] >= 0, "finite non-negative halfdiff");
                }
    }
    // The writer: its output must parse, and carry the same floats.
    std::vector<uint8_t> bytes = encode_table(t);
    TableHeader h = parse_table_header(bytes.data(), bytes.size(), "roundtrip.brdf");
    fuzz_check(h.payload_bytes == 4 * t.values().size(), "round trip size");
    fuzz_check(std::memcmp(bytes.data() + h.payload_offset, t.values().data(), h.payload_bytes) == 0,
               "round trip values (little-endian host)");
}

void load(const uint8_t* data, size_t size) {
    TableHeader h;
    if (!table_header(data, size, &h)) return;
    ValueScan s = scan_table_values(data, h);
    for (NoDataPolicy policy : {NoDataPolicy::Reject, NoDataPolicy::Fill}) {
        if (policy == NoDataPolicy::Fill && s.nan + s.negative == 0) break;
        LoadOptions opt;
        opt.nodata = policy;
        std::unique_ptr<BrdfTable> t;
        try {
            t = load_table(data, size, "fuzz.brdf", opt);
        } catch (const TableError&) {
            continue;
        }
        fuzz_check(s.inf == 0, "no table with an infinite value");
        fuzz_check(policy == NoDataPolicy::Fill || s.nan + s.negative == 0, "reject policy rejects no-data");
        exercise(*t);
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return run_with_fixed_checksum(data, size, load, fix_checksum);
}
