// The exact-profile table file (.ssp, specified in shading/DIPOLE.md 10.4): its image
// (ProfileTables::serialize), checksum, loader and the shared cache; see ss_profile.h.
#include "shading/subsurface/ss_profile.h"

#include <algorithm>
#include <cstring>
#include <map>
#include <mutex>
#include <sstream>

#include "shading/core/bytes.h"
#include "shading/subsurface/ss_profile_curve.h"

namespace shading {

using namespace ss_detail;
using detail::hex64;
using bytes::put_f32;
using bytes::put_f64;
using bytes::put_u32;
using bytes::put_u64;
using bytes::rd_f32;
using bytes::rd_f64;
using bytes::rd_u32;
using bytes::rd_u64;

namespace {

constexpr char kMagic[8] = {'P', 'V', 'S', 'S', 'P', 'R', 'O', 'F'};
constexpr std::size_t kFixedHeader = 168;
constexpr std::uint32_t kFlagTransmission = 1;
constexpr int kFixedFields = 6;  // multi, single, ballistic, tail_k, tail_a, rho_tail

int record_floats(const ProfileBuildSettings& s) {
    return kFixedFields + s.angle_nodes + 2 * int(s.cos_inside.size()) + s.bins.count +
           s.band_count() * (1 + s.angle_nodes) + (int(s.cos_inside.size()) - 1) * s.oblique_azimuths * s.angle_nodes;
}

}  // namespace

std::string ProfileTables::describe() const {
    const ProfileBuildSettings& s = settings;
    std::ostringstream o;
    auto list = [&](const std::vector<double>& v) {
        std::string t;
        for (double x : v) t += (t.empty() ? "" : ",") + (x == kInf ? std::string("inf") : num(x));
        return t;
    };
    o << "exact subsurface profiles, generator " << generator_version << ", " << (faces == 2 ? "slabs" : "semi-infinite")
      << "\n  g: " << list(s.g) << "\n  eta: " << list(s.eta) << "\n  thickness (mfp): " << list(s.thickness)
      << "\n  albedo: " << s.albedos << " nodes, u = -ln(1 - alpha) from " << num(s.u_0) << " step " << num(s.u_step)
      << " (alpha " << num(albedo(0)) << " .. " << num(albedo(s.albedos - 1)) << ")"
      << "\n  radius: " << s.bins.count << " nodes, 0 and " << s.bins.per_decade << " per decade from "
      << num(s.bins.rho_0) << " transport mfp"
      << "\n  inside incidence cosines: " << list(s.cos_inside) << "\n  angle: " << s.angle_nodes
      << " inside-radiance samples (next-event to " << num(s.radiance_orders) << "/(1-g) events, then " << s.angle_bins
      << " bins)"
      << "\n  oblique exits: " << (s.oblique_azimuths > 0 ? std::to_string(s.oblique_azimuths) + " azimuths, orders to " + std::to_string(s.oblique_orders) + "/(1-g) their own" : std::string("none"))
      << "\n  exit-distance bands: " << (s.exit_bands.empty() ? std::string("none") : "edges " + list(s.exit_bands) + " transport mfp")
      << "\n  photons per node: " << s.photons << (faces == 2 ? " (x (d (1-g) / 1.6)^2 within [1, 8] at normal incidence)" : "")
      << " + " << s.short_photons << " short (" << num(s.short_orders)
      << "/(1-g) events), roulette from " << num(s.roulette_order) << "/(1-g) events, oblique " << num(s.oblique_fraction)
      << ", seed " << s.seed << "\n  records: " << records.size() << ", " << record_floats(s) << " floats each\n";
    return o.str();
}

// ---------------------------------------------------------------- the file

std::vector<std::uint8_t> ProfileTables::serialize() const {
    const ProfileBuildSettings& s = settings;
    std::vector<std::uint8_t> b(kMagic, kMagic + 8);
    b.reserve(kFixedHeader + 64 * 8 + records.size() * 4 * std::size_t(record_floats(s)));
    put_u32(b, kProfileFormatVersion);                   // 8
    put_u32(b, 0);                                       // 12 payload offset (patched)
    put_u64(b, 0);                                       // 16 payload bytes (patched)
    put_u64(b, 0);                                       // 24 checksum (patched)
    put_u32(b, generator_version);                       // 32
    put_u32(b, faces == 2 ? kFlagTransmission : 0);      // 36
    put_u32(b, std::uint32_t(s.g.size()));               // 40
    put_u32(b, std::uint32_t(s.eta.size()));             // 44
    put_u32(b, std::uint32_t(s.thickness.size()));       // 48
    put_u32(b, std::uint32_t(s.albedos));                // 52
    put_u32(b, std::uint32_t(s.bins.count));             // 56
    put_u32(b, std::uint32_t(s.bins.per_decade));        // 60
    put_u32(b, std::uint32_t(s.cos_inside.size()));      // 64
    put_u32(b, std::uint32_t(s.angle_nodes));            // 68
    put_u32(b, std::uint32_t(s.angle_bins));             // 72
    put_u32(b, std::uint32_t(s.exit_bands.size()));     // 76 exit-distance band edges
    put_f64(b, s.bins.rho_0);                            // 80
    put_f64(b, s.u_0);                                   // 88
    put_f64(b, s.u_step);                                // 96
    put_f64(b, s.short_orders);                          // 104
    put_f64(b, s.roulette_order);                        // 112
    put_f64(b, s.oblique_fraction);                      // 120
    put_u64(b, s.photons);                               // 128
    put_u64(b, s.short_photons);                         // 136
    put_u64(b, s.seed);                                  // 144
    put_f64(b, s.radiance_orders);                       // 152
    put_u32(b, std::uint32_t(s.oblique_azimuths));       // 160 oblique exits' azimuths (0: none)
    put_u32(b, std::uint32_t(s.oblique_azimuths > 0 ? s.oblique_orders : 0));  // 164 their orders (0: none)
    for (double v : s.g) put_f64(b, v);
    for (double v : s.eta) put_f64(b, v);
    for (double v : s.thickness) put_f64(b, v);
    for (double v : s.cos_inside) put_f64(b, v);
    for (double v : s.exit_bands) put_f64(b, v);
    while (b.size() % 16) b.push_back(0);
    const std::size_t off = b.size();
    for (const FaceRecord& r : records) {
        for (double v : {r.multi, r.single, r.ballistic, r.tail_k, r.tail_a, r.rho_tail}) put_f32(b, float(v));
        for (double v : r.angle) put_f32(b, float(v));
        for (double v : r.incidence) put_f32(b, float(v));
        for (double v : r.shift) put_f32(b, float(v));
        for (double v : r.profile) put_f32(b, float(v));
        for (double v : r.band_rho) put_f32(b, float(v));
        for (double v : r.band_ratio) put_f32(b, float(v));
        for (double v : r.oblique) put_f32(b, float(v));
    }
    bytes::wr_u32(b, 12, std::uint32_t(off));
    bytes::wr_u64(b, 16, b.size() - off);
    bytes::wr_u64(b, 24, profile_file_checksum(b.data(), b.size()));  // last: it covers the fields above
    return b;
}

std::uint64_t profile_file_checksum(const std::uint8_t* data, std::size_t size) {
    // fnv1a64 over [0, 24), eight zeros, [32, size): no copy.
    static const std::uint8_t zeros[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    std::uint64_t h = fnv1a64(data, std::min<std::size_t>(size, 24));
    if (size > 24) h = fnv1a64(zeros, std::min<std::size_t>(size, 32) - 24, h);
    if (size > 32) h = fnv1a64(data + 32, size - 32, h);
    return h;
}

std::shared_ptr<const ProfileTables> load_profile_tables(const std::uint8_t* data, std::size_t size,
                                                         const std::string& name) {
    auto fail = [&](std::size_t offset, const std::string& what) -> void {
        throw ProfileError(name + ": offset " + std::to_string(offset) + ": " + what);
    };
    if (size < kFixedHeader)
        fail(size, "expected a header of " + std::to_string(kFixedHeader) + " bytes, found a file of " + std::to_string(size) +
                       " bytes (truncated, or not a .ssp file)");
    if (std::memcmp(data, kMagic, 8) != 0) fail(0, "expected the magic \"PVSSPROF\" (not an exact-profile table)");
    const std::uint32_t version = rd_u32(data + 8);
    if (version != kProfileFormatVersion)
        fail(8, "expected format version " + std::to_string(kProfileFormatVersion) + ", found " + std::to_string(version) +
                    " (rebuild it: make brdf-data, or sstool build --if-stale -o FILE)");
    // Before any field is believed: a changed header field (a count, a step) would otherwise
    // give a table that loads and evaluates to something else.
    const std::uint64_t sum = profile_file_checksum(data, size), stored_sum = rd_u64(data + 24);
    if (sum != stored_sum)
        fail(24, "expected the file's checksum " + hex64(sum) + ", found " + hex64(stored_sum) +
                     " (the file is damaged or was edited: rebuild it with make brdf-data, or sstool build --if-stale -o FILE)");
    auto t = std::make_shared<ProfileTables>();
    t->name = name;
    ProfileBuildSettings& s = t->settings;
    t->generator_version = rd_u32(data + 32);
    const std::uint32_t flags = rd_u32(data + 36);
    if (flags & ~kFlagTransmission) fail(36, "expected flags 0 or 1, found " + std::to_string(flags));
    t->faces = (flags & kFlagTransmission) ? 2 : 1;
    struct Count {
        std::size_t at;
        const char* what;
        std::uint32_t lo, hi;
    };
    const Count counts[] = {{40, "g nodes", 1, 64},          {44, "eta nodes", 1, 64},     {48, "thickness nodes", 1, 64},
                            {52, "albedo nodes", 4, 1000},   {56, "radial nodes", 4, 1000}, {60, "radial nodes per decade", 1, 100},
                            {64, "incidence nodes", 1, 64}, {68, "angle samples", 2, 32},  {72, "angle bins", 4, 1000}};
    std::uint32_t n[9];
    for (int i = 0; i < 9; ++i) {
        n[i] = rd_u32(data + counts[i].at);
        if (n[i] < counts[i].lo || n[i] > counts[i].hi)
            fail(counts[i].at, std::string("expected ") + std::to_string(counts[i].lo) + " to " + std::to_string(counts[i].hi) +
                                   " " + counts[i].what + ", found " + std::to_string(n[i]));
    }
    s.albedos = int(n[3]);
    s.bins.count = int(n[4]);
    s.bins.per_decade = int(n[5]);
    s.angle_nodes = int(n[7]);
    s.angle_bins = int(n[8]);
    s.bins.rho_0 = rd_f64(data + 80);
    s.u_0 = rd_f64(data + 88);
    s.u_step = rd_f64(data + 96);
    s.short_orders = rd_f64(data + 104);
    s.roulette_order = rd_f64(data + 112);
    s.oblique_fraction = rd_f64(data + 120);
    s.photons = rd_u64(data + 128);
    s.short_photons = rd_u64(data + 136);
    s.seed = rd_u64(data + 144);
    s.radiance_orders = rd_f64(data + 152);
    const std::uint32_t band_edges = rd_u32(data + 76);
    if (band_edges > 15) fail(76, "expected 0 to 15 exit-distance band edges, found " + std::to_string(band_edges));
    if (band_edges > 0 && t->faces == 2) fail(76, "expected no exit-distance bands in a slab table (flags 1), found " +
                                                     std::to_string(band_edges) + " edges");
    const std::uint32_t azimuths = rd_u32(data + 160);
    if (azimuths == 1 || azimuths > 32) fail(160, "expected 0, or 2 to 32 oblique exit azimuths, found " + std::to_string(azimuths));
    if (azimuths > 0 && t->faces == 2)
        fail(160, "expected no oblique exits in a slab table (flags 1), found " + std::to_string(azimuths) + " azimuths");
    s.oblique_azimuths = int(azimuths);
    const std::uint32_t oblique_orders = rd_u32(data + 164);
    if (azimuths > 0 ? !(oblique_orders >= 1 && oblique_orders <= 100000) : oblique_orders != 0)
        fail(164, std::string("expected ") + (azimuths > 0 ? "1 to 100000 oblique exit orders" : "0 oblique exit orders (no azimuths)") +
                      ", found " + std::to_string(oblique_orders));
    if (azimuths > 0) s.oblique_orders = int(oblique_orders);
    if (!(s.bins.rho_0 > 0 && s.bins.rho_0 < 1e3)) fail(80, "expected the first radius in (0, 1000), found " + num(s.bins.rho_0));
    // The generator's settings (the file's identity for --if-stale): ranges of ProfileBuildSettings.
    if (!(s.short_orders >= 1 && s.short_orders <= 1e6)) fail(104, "expected short orders in [1, 1e6], found " + num(s.short_orders));
    if (!(s.roulette_order >= 1 && s.roulette_order <= 1e9))
        fail(112, "expected a roulette order in [1, 1e9], found " + num(s.roulette_order));
    if (!(s.oblique_fraction > 0 && s.oblique_fraction <= 1))
        fail(120, "expected an oblique fraction in (0, 1], found " + num(s.oblique_fraction));
    if (s.photons < 1) fail(128, "expected at least one photon, found 0");
    if (!(s.radiance_orders >= 2 && s.radiance_orders <= 1e5))
        fail(152, "expected radiance orders in [2, 1e5], found " + num(s.radiance_orders));
    if (!(s.u_0 >= 0 && s.u_0 <= 30)) fail(88, "expected the first albedo node u in [0, 30], found " + num(s.u_0));
    if (!(s.u_step > 0 && s.u_0 + (s.albedos - 1) * s.u_step <= 30))
        fail(96, "expected an albedo step > 0 with the last node u <= 30, found " + num(s.u_step));
    // Axes.
    std::size_t at = kFixedHeader;
    const std::size_t axis_bytes = 8 * (std::size_t(n[0]) + n[1] + n[2] + n[6] + band_edges);
    if (size < at + axis_bytes)
        fail(size, "expected " + std::to_string(axis_bytes) + " bytes of axes after the header, found " +
                       std::to_string(size - at));
    auto read_axis = [&](std::vector<double>& v, std::uint32_t count, const char* what, double lo, double hi, bool allow_inf) {
        v.resize(count);
        for (std::uint32_t i = 0; i < count; ++i, at += 8) {
            v[i] = rd_f64(data + at);
            const bool ok = (v[i] >= lo && v[i] <= hi) || (allow_inf && v[i] == kInf);
            if (!ok) fail(at, std::string(what) + " node " + std::to_string(i) + ": expected a value in [" + num(lo) + ", " + num(hi) +
                                  "]" + (allow_inf ? " or inf" : "") + ", found " + num(v[i]));
            if (i > 0 && !(v[i] > v[i - 1]))
                fail(at, std::string(what) + " node " + std::to_string(i) + ": expected increasing values, found " + num(v[i]) +
                             " after " + num(v[i - 1]));
        }
    };
    read_axis(s.g, n[0], "g", 0.0, 0.99, false);
    read_axis(s.eta, n[1], "eta", 1.0, 4.0, false);
    const std::size_t thickness_at = at;
    read_axis(s.thickness, n[2], "thickness", 1e-3, 1e6, true);
    read_axis(s.cos_inside, n[6], "inside incidence cosine", 0.01, 1.0, false);
    if (s.cos_inside.back() != 1.0) fail(at - 8, "expected the last inside incidence cosine to be 1, found " + num(s.cos_inside.back()));
    read_axis(s.exit_bands, band_edges, "exit-distance band edge", 1e-6, 1e3, false);
    if (t->faces == 1 && !(s.thickness.size() == 1 && s.thickness[0] == kInf))
        fail(thickness_at, "expected one thickness node, inf, in a reflection-only table (flags 0)");
    const std::size_t off = (at + 15) & ~std::size_t(15);
    const std::uint32_t stored_off = rd_u32(data + 12);
    if (stored_off != off) fail(12, "expected the payload offset " + std::to_string(off) + ", found " + std::to_string(stored_off));
    const std::size_t R = std::size_t(record_floats(s));
    const std::size_t nrec = std::size_t(n[0]) * n[1] * n[2] * t->faces * s.albedos;
    const std::uint64_t bytes = std::uint64_t(nrec) * R * 4;
    const std::uint64_t stored_bytes = rd_u64(data + 16);
    if (stored_bytes != bytes)
        fail(16, "expected " + std::to_string(bytes) + " payload bytes for these axes, found " + std::to_string(stored_bytes));
    if (size < off || size - off != bytes)
        fail(std::min(size, off + std::size_t(bytes)), "expected the file to end after " + std::to_string(bytes) +
                                                           " payload bytes at offset " + std::to_string(off) + ", found a file of " +
                                                           std::to_string(size) + " bytes");
    for (std::size_t p = at; p < off; ++p)
        if (data[p] != 0) fail(p, "expected zero padding before the payload");
    // Records.
    t->records.resize(nrec);
    std::size_t p = off;
    const std::size_t ne = n[1], nd = n[2];
    for (std::size_t i = 0; i < nrec; ++i) {
        const std::size_t k = i % s.albedos, face = (i / s.albedos) % t->faces, rest = i / s.albedos / t->faces;
        const std::size_t id = rest % nd, ie = (rest / nd) % ne, ig = rest / nd / ne;
        auto label = [&](const std::string& field) {
            return "g=" + num(s.g[ig]) + " eta=" + num(s.eta[ie]) + " d=" + num(s.thickness[id]) +
                   (face ? " transmission" : " reflection") + " albedo=" + num(t->albedo(int(k))) + " " + field;
        };
        // The field's name is made only for a message: `field`, and " INDEX" when index >= 0,
        // out of line (a string per value read, and the call the message kept from inlining,
        // were ~70 % of loading the files).
        auto out_of_range = [&](const char* field, int index, double lo, double hi, double v)
                                __attribute__((noinline, cold)) {
            fail(p, label(index < 0 ? std::string(field) : std::string(field) + " " + std::to_string(index)) +
                        ": expected a value in [" + num(lo) + ", " + num(hi) + "], found " + num(v));
        };
        auto value = [&](const char* field, int index, double lo, double hi) {
            const double v = rd_f32(data + p);
            if (!(v >= lo && v <= hi)) out_of_range(field, index, lo, hi, v);
            p += 4;
            return v;
        };
        FaceRecord& r = t->records[i];
        r.multi = value("total", -1, 0.0, 1.5);
        r.single = value("single", -1, 0.0, 1.5);
        r.ballistic = value("ballistic", -1, 0.0, 1.5);
        r.tail_k = value("tail rate", -1, 0.0, 1e6);
        r.tail_a = value("tail amplitude", -1, 0.0, kMaxTailAmplitude);
        r.rho_tail = value("tail radius", -1, 1e-6, 1e6);
        r.angle.resize(s.angle_nodes);
        for (int j = 0; j < s.angle_nodes; ++j) r.angle[j] = value("angle sample", j, 0.0, 1e6);
        r.incidence.resize(s.cos_inside.size());
        for (std::size_t j = 0; j < s.cos_inside.size(); ++j)
            r.incidence[j] = value("incidence factor", int(j), 1e-6, 1e6);
        if (std::fabs(r.incidence.back() - 1.0) > 1e-6)
            fail(p - 4, label("incidence factor at normal incidence") + ": expected 1, found " + num(r.incidence.back()));
        r.shift.resize(s.cos_inside.size());
        for (std::size_t j = 0; j < s.cos_inside.size(); ++j)
            r.shift[j] = value("exit shift", int(j), 0.0, 100.0);
        if (r.shift.back() != 0.0)
            fail(p - 4, label("exit shift at normal incidence") + ": expected 0, found " + num(r.shift.back()));
        r.profile.resize(s.bins.count);
        for (int b = 0; b < s.bins.count; ++b) r.profile[b] = value("radius node", b, 0.0, 1e30);
        const int B = s.band_count();
        r.band_rho.resize(std::size_t(B));
        for (int b = 0; b < B; ++b) r.band_rho[std::size_t(b)] = value("band distance", b, 0.0, 1e6);
        r.band_ratio.resize(std::size_t(B) * s.angle_nodes);
        for (std::size_t j = 0; j < r.band_ratio.size(); ++j) r.band_ratio[j] = value("band exit ratio", int(j), 0.0, 100.0);
        r.oblique.resize((s.cos_inside.size() - 1) * std::size_t(s.oblique_azimuths) * s.angle_nodes);
        for (std::size_t j = 0; j < r.oblique.size(); ++j) r.oblique[j] = value("oblique exit sample", int(j), 0.0, 1e6);
    }
    return t;
}

std::shared_ptr<const ProfileTables> shared_profile_tables(
    const std::string& key, const std::function<std::shared_ptr<const ProfileTables>()>& load) {
    static std::mutex mutex;
    static std::map<std::string, std::weak_ptr<const ProfileTables>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    if (auto live = cache[key].lock()) return live;
    std::shared_ptr<const ProfileTables> t = load();
    cache[key] = t;
    return t;
}

}  // namespace shading
