// libFuzzer target: the MERL .binary reader (MerlBrdf::parse) on arbitrary bytes, then
// the reference lookup and one conversion to a coarse table (30 deg nodes, fill policy,
// folded when the input's size is odd, to vary it). Reader and conversion errors are
// TableError; any other exception, a sanitizer report or a failed check is a crash.
#include <cmath>
#include <cstdint>

#include "fuzz_util.h"
#include "shading/merl.h"

using namespace shading;

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
    return 0;
}
