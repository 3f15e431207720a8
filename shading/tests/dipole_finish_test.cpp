// The dipole finish's own pieces that need an object's lights (dipole_finish.h), against a
// stand-in object: one parallel light, no shadows, no geometry beyond what is asked.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "shading/finish/dipole_finish.h"
#include "shading/subsurface/subsurface.h"

using namespace shading;

namespace {

// A parallel light of colour 1 from `to_light`, unshadowed everywhere.
class OneLight : public DipoleObject {
public:
    explicit OneLight(const Vec3& to_light) : to_light_(normalize(to_light)) {}
    bool bounds(Vec3*, Vec3*) override { return false; }
    void line_hits(int, const Vec3&, std::vector<Hit>*) override {}
    Rgb irradiance(const Vec3&, const Vec3&) override { return Rgb(0.0); }
    std::string describe() override { return "one light"; }
    double thickness(const Vec3&, const Vec3&) override { return kInf; }
    int light_count() override { return 1; }
    bool light_direction(int, const Vec3&, Vec3* to_light) override {
        *to_light = to_light_;
        return true;
    }
    Rgb light_colour(int, const Vec3&, const Vec3&, const Vec3&) override {
        ++queries;
        return Rgb(1.0);
    }
    int queries = 0;

private:
    Vec3 to_light_;
};

}  // namespace

// Lit on the face seen: the slab's single scattering less the half-space's, times pi cos_i. A
// thin slab at ior 1.3 under grazing light reflects more single scattering than the
// half-space (the far face sends the beam back up): the difference is positive there and
// must be added, not skipped as negligible; under light near the normal it is negative
// (the far face cuts the depth short). A slab many mean free paths thick adds nothing and
// asks for no light (the shadow ray is skipped).
TEST(DipoleFinish, SlabSingleScatteringCorrectsTheHalfSpaceOnTheLitFace) {
    const Medium m = Medium::from_reduced(Rgb(0.9, 0.5, 0.2), Rgb(0.1, 0.5, 0.8), 1.3, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    ASSERT_TRUE(s.slab_single_at_lookup());
    const Vec3 x(0, 0, 0), n(0, 0, 1);
    for (double ti : {1.5, 0.2}) {
        const Vec3 wi = spherical_direction(ti, 0.0), to_eye = spherical_direction(ti > 1.0 ? 1.5 : 0.3, 3.0);
        const double d = ti > 1.0 ? 1.0 : 0.3;
        ASSERT_LT(d, s.slab_threshold());
        OneLight light(wi);
        const Rgb got = slab_single_scatter(s, light, x, n, to_eye, d);
        const Rgb want = (s.dipole().single_scatter_slab(to_eye, wi, d) - s.dipole().single_scatter_brdf(to_eye, wi)) *
                         (kPi * wi.z);
        EXPECT_EQ(light.queries, 1);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(got[c], want[c], 1e-15) << ti << " " << c;
            if (ti > 1.0) EXPECT_GT(got[c], 0.0) << c;  // grazing: more than the half-space
        }
        if (ti < 1.0) EXPECT_LT(got.r, 0.0);
    }
    OneLight light(Vec3(0.2, 0, 1));
    const Rgb thick = slab_single_scatter(s, light, x, n, Vec3(0, 0, 1), 60.0);
    EXPECT_EQ(thick.r, 0.0);
    EXPECT_EQ(light.queries, 0);
}
