// libFuzzer target: the MERL .binary reader (MerlBrdf::parse) on arbitrary bytes, then
// the reference lookup, one conversion to a coarse table (30 deg nodes, fill policy,
// folded when the input's size is odd, to vary it) and the lossless conversion to a
// half/difference table (policy and channels varied by the input's size). Reader and conversion errors are
// TableError; any other exception, a sanitizer report or a failed check is a crash.
#include <cmath>
#include <cstdint>

#include "fuzz_util.h"
#include "shading/tables/merl.h"

using namespace shading;

namespace {
// True when the pair's bin coordinates (MERL's formulas) are at least 1e-6 of a bin away from
// every bin edge, and phi_d is defined (theta_h, theta_d > 0): there the two computations of
// the angles (merl.h's rotations, the table's dot products) must pick the same bin; at an
// edge they may round apart by an ulp.
bool clear_of_bin_edges(const Vec3& wi, const Vec3& wo, const MerlDims& d) {
    const HalfDiff hd = to_half_diff(wi, wo);
    if (!(hd.theta_h > 1e-6 && hd.theta_d > 1e-6)) return false;
    const double pd = hd.phi_d < 0 ? hd.phi_d + kPi : hd.phi_d;
    const double x[3] = {std::sqrt(hd.theta_h / (kPi / 2)) * d.theta_h, hd.theta_d / (kPi / 2) * d.theta_d,
                         pd / kPi * d.phi_d};
    for (double v : x)
        if (std::fabs(v - std::round(v)) < 1e-6) return false;
    return true;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::unique_ptr<MerlBrdf> m;
    try {
        m = MerlBrdf::parse(data, size, "fuzz.binary");
    } catch (const TableError&) {
        return 0;
    }
    fuzz_check(m->nodata_bins() <= m->dims().per_channel(), "no-data count within the bins");
    (void)m->describe();
    const double dirs[][3] = {{0, 0, 1}, {0.6, 0, 0.8}, {-0.6, 0, 0.8}, {0.3, 0.4, 0.866}, {1, 0, 0}, {-1, 0, 0}};
    for (const auto& a : dirs)
        for (const auto& b : dirs) {
            Vec3 wo(a[0], a[1], a[2]), wi(b[0], b[1], b[2]);
            MerlBrdf::Bin bin = m->bin(wi, wo);
            fuzz_check(bin.index < m->dims().per_channel(), "bin inside the data");
            Rgb v = m->f(wo, wi);
            for (int c = 0; c < 3; ++c) fuzz_check(std::isfinite(v[c]) && v[c] >= 0, "finite non-negative lookup");
        }
    MerlConvertOptions opt;
    opt.step_deg = 30;
    opt.nodata = NoDataPolicy::Fill;
    opt.fold = size % 2 == 1;
    try {
        std::unique_ptr<BrdfTable> t = merl_to_table(*m, opt);
        Rgb v = t->eval_iso(0.5, 0.5, 3.0);
        for (int c = 0; c < 3; ++c) fuzz_check(std::isfinite(v[c]) && v[c] >= 0, "finite non-negative table");
    } catch (const TableError&) {
    }
    // MERL's own grid as a half/difference table (dimensions >= 2), both policies: its
    // nearest lookups must be the reference lookup's values (to float32).
    const MerlDims& d = m->dims();
    if (d.theta_h < 2 || d.theta_d < 2 || d.phi_d < 2) return 0;
    MerlConvertOptions hd;
    hd.nodata = size % 3 == 0 ? NoDataPolicy::Reject : NoDataPolicy::Fill;
    hd.channels = size % 5 == 0 ? 1 : 3;
    try {
        std::unique_ptr<BrdfTable> t = merl_to_halfdiff(*m, hd);
        fuzz_check(t->info().nodata_filled <= d.per_channel(), "filled count within the bins");
        for (const auto& a : dirs)
            for (const auto& b : dirs) {
                Vec3 wo(a[0], a[1], a[2]), wi(b[0], b[1], b[2]);
                Rgb lin = t->f(wo, wi, Interp::Linear), near = t->f(wo, wi, Interp::Nearest);
                for (int c = 0; c < 3; ++c)
                    fuzz_check(std::isfinite(lin[c]) && lin[c] >= 0 && std::isfinite(near[c]) && near[c] >= 0,
                               "finite non-negative halfdiff lookup");
                if (hd.channels != 3 || !(wo.z > 0 && wi.z > 0) || !clear_of_bin_edges(wi, wo, d)) continue;
                Rgb ref = m->value(m->bin(wi, wo));
                for (int c = 0; c < 3; ++c)
                    if (ref[c] >= 0) fuzz_check(near[c] == double(float(ref[c])), "nearest lookup is MERL's bin");
            }
    } catch (const TableError&) {
    }
    return 0;
}
