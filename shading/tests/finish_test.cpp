// The adapter-facing finish layer: POV weights, albedo for indirect light, shared tables,
// the counted handle registry.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>
#include <vector>

#include "shading/finish/finish.h"
#include "shading/brdf/model_spec.h"
#include "shading/brdf/models.h"
#include "shading/tables/table.h"

using namespace shading;

namespace {

std::unique_ptr<BrdfTable> lambert_table(double rho, double step = 5.0) {
    Lambert l{Rgb(rho)};
    BuildOptions opt;
    return build_table(tabulate(l, TableGeometry::isotropic(step)), opt);
}

}  // namespace

TEST(Finish, LambertWeightIsPovDiffuse) {
    // POV's missing 1/pi: a Lambert BRDF rho/pi contributes rho * cos(theta_l), as `diffuse rho`.
    auto m = make_finish_model(std::make_shared<Lambert>(Rgb(0.2, 0.5, 0.8)));
    Vec3 n = normalize(Vec3(0.3, -0.2, 1.0));
    Vec3 eye = normalize(Vec3(-0.5, 0.1, 1.0)), light = normalize(Vec3(0.7, 0.4, 0.6));
    Rgb w = finish_light_weight(*m, n, eye, light, Rgb(1.0));
    double c = dot(n, light);
    EXPECT_NEAR(w.r, 0.2 * c, 1e-14);
    EXPECT_NEAR(w.g, 0.5 * c, 1e-14);
    EXPECT_NEAR(w.b, 0.8 * c, 1e-14);
    // Light below the surface or eye below: nothing.
    EXPECT_EQ(finish_light_weight(*m, n, eye, -light, Rgb(1.0)).max_component(), 0.0);
    EXPECT_EQ(finish_light_weight(*m, n, -eye, light, Rgb(1.0)).max_component(), 0.0);
}

TEST(Finish, ScaleAndTint) {
    auto m = make_finish_model(std::make_shared<Lambert>(Rgb(0.5)));
    m->scale = Rgb(2.0, 1.0, 0.5);
    Vec3 n(0, 0, 1), v(0, 0, 1), l(0, 0, 1);
    Rgb w = finish_light_weight(*m, n, v, l, Rgb(0.1, 0.2, 0.3));
    EXPECT_NEAR(w.r, 1.0, 1e-14);  // no tint: pigment ignored
    m->tint = true;
    w = finish_light_weight(*m, n, v, l, Rgb(0.1, 0.2, 0.3));
    EXPECT_NEAR(w.r, 0.1, 1e-14);
    EXPECT_NEAR(w.g, 0.1, 1e-14);
    EXPECT_NEAR(w.b, 0.075, 1e-14);
}

TEST(Finish, AlbedoOfLambertIsRho) {
    // The MIS quadrature (cosine grid + mirror lobes) is within 0.1 % for a constant BRDF
    // (measured 3e-4 low: lobe samples near the horizon are dropped).
    auto m = make_finish_model(std::make_shared<Lambert>(Rgb(0.7)));
    ASSERT_EQ(m->albedo_nodes().size(), size_t(FinishModel::kAlbedoNodes));
    for (const Rgb& a : m->albedo_nodes()) EXPECT_NEAR(a.g, 0.7, 7e-4);
    // Indirect light: POV's ambient colour times rho, like `diffuse 0.7`.
    Vec3 n(0, 0, 1);
    EXPECT_NEAR(finish_indirect_weight(*m, n, normalize(Vec3(1, 0, 1)), Rgb(1.0)).r, 0.7, 7e-4);
    // Lights POV gives no highlight: Lambert of the albedo, 0.7 cos.
    Vec3 l = normalize(Vec3(0, 1, 2));
    EXPECT_NEAR(finish_diffuse_light_weight(*m, n, l, Rgb(1.0)).b, 0.7 * l.z, 7e-4 * l.z);
}

TEST(Finish, AlbedoOfANarrowLobeIsResolved) {
    // A near-mirror lobe without Fresnel (F = 1, Smith G ~ 1 away from grazing) reflects
    // ~all light: a grid of cosine-weighted directions alone misses it (0.91 at normal,
    // 0.12 at 84 deg with 64 x 128 strata); the mirror-lobe components resolve it.
    auto m = make_finish_model(make_brdf("microfacet d=beckmann m=0.05"));
    EXPECT_NEAR(finish_model_albedo(*m, 1.0).g, 1.0, 0.01);
    EXPECT_NEAR(finish_model_albedo(*m, 0.5).g, 1.0, 0.01);
    EXPECT_GT(finish_model_albedo(*m, std::cos(84 * kPi / 180)).g, 0.9);
}

TEST(Finish, AlbedoOfMicrofacetFollowsFresnel) {
    // A smooth-ish dielectric microfacet lobe: albedo grows toward grazing (Fresnel), and
    // near normal it is about F0 = 0.04 (minus a little shadowing).
    auto m = make_finish_model(make_brdf("microfacet d=tr m=0.2 f=dielectric eta=1.5"));
    Rgb a0 = finish_model_albedo(*m, 1.0), a80 = finish_model_albedo(*m, std::cos(80 * kPi / 180));
    EXPECT_NEAR(a0.r, 0.04, 0.004);
    EXPECT_GT(a80.r, 2 * a0.r);
    EXPECT_LT(a80.r, 1.0);
}

TEST(Finish, AlbedoOfTableUsesTheTable) {
    std::shared_ptr<const BrdfTable> t = lambert_table(0.4);
    auto m = make_finish_model(t, Interp::Linear);
    for (double c : {1.0, 0.5, 0.1}) EXPECT_NEAR(finish_model_albedo(*m, c).r, 0.4, 2e-3) << c;
}

TEST(Finish, TableViewKeepsItsOwnInterpolation) {
    auto grid = tabulate(*make_brdf("phong_normalized ks=1 n=20"), TableGeometry::isotropic(10.0));
    std::shared_ptr<const BrdfTable> t = build_table(grid, BuildOptions{});
    BrdfPtr nearest = table_brdf(t, Interp::Nearest), linear = table_brdf(t, Interp::Linear);
    // Between nodes the two differ; at a node they agree.
    Vec3 wo = spherical_direction(25 * kPi / 180, 0), wi = spherical_direction(33 * kPi / 180, kPi);
    EXPECT_NE(nearest->f(wo, wi).r, linear->f(wo, wi).r);
    Vec3 no = spherical_direction(20 * kPi / 180, 0), ni = spherical_direction(30 * kPi / 180, kPi);
    EXPECT_NEAR(nearest->f(no, ni).r, linear->f(no, ni).r, 1e-6 * linear->f(no, ni).r);
}

TEST(Finish, IsotropicTableFastPathEqualsTheFramePath) {
    // finish_light_weight reads isotropic tables from cosines; it must agree with the
    // generic path (local frame, Brdf::f, pov_weight) everywhere, grazing and pole included.
    auto grid = tabulate(*make_brdf("microfacet d=beckmann m=0.25 f=dielectric eta=1.5 kd=0.2 rho_s=0.8"),
                         TableGeometry::isotropic(2.0));
    std::shared_ptr<const BrdfTable> t = build_table(grid, BuildOptions{});
    for (Interp interp : {Interp::Linear, Interp::Nearest}) {
        auto m = make_finish_model(t, interp);
        ASSERT_EQ(m->iso_table, t.get());
        uint64_t state = 12345;
        auto rnd = [&] {
            state = state * 6364136223846793005ULL + 1442695040888963407ULL;
            return double(state >> 11) * 0x1.0p-53;
        };
        auto dir = [&] { return normalize(Vec3(2 * rnd() - 1, 2 * rnd() - 1, 2 * rnd() - 1)); };
        int checked = 0;
        for (int k = 0; k < 20000; ++k) {
            Vec3 n = dir(), v = dir(), l = dir();
            if (k % 7 == 0) v = normalize(v - n * dot(n, v) + n * 1e-7);  // grazing eye
            if (k % 11 == 0) l = n;                                      // light at the pole
            Frame fr = Frame::from_normal(n);
            Rgb want = pov_weight(*m->brdf, fr.to_local(v), fr.to_local(l));
            Rgb got = finish_light_weight(*m, n, v, l, Rgb(1.0));
            // Nearest lookups may round a coordinate that sits within an ulp of a cell edge
            // the other way; count such cases instead of comparing them.
            if (interp == Interp::Nearest && std::fabs(got.g - want.g) > 1e-8 * (1 + want.g)) continue;
            ASSERT_NEAR(got.g, want.g, 1e-8 * (1 + want.g)) << k;  // acos vs atan2 rounding
            ++checked;
        }
        EXPECT_GT(checked, 19900);
    }
}

TEST(Finish, GrazingCellOfATableIsNoFirefly) {
    // A microfacet lobe diverges like 1/cos at the grazing mirror pair while f cos stays
    // finite; the table's 90 deg node is sampled half a step inside so the last cell
    // interpolates finite values: f cos in the cell stays near the model's.
    BrdfPtr model = make_brdf("microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.5 rho_s=0.5");
    std::shared_ptr<const BrdfTable> t = build_table(tabulate(*model, TableGeometry::isotropic(1.0)), BuildOptions{});
    double worst = 0;
    for (double th : {89.1, 89.5, 89.9, 89.99}) {
        Vec3 wi = spherical_direction(th * kPi / 180, 0), wo = spherical_direction(th * kPi / 180, kPi);
        double got = t->f(wo, wi).g * wi.z, want = model->f(wo, wi).g * wi.z;
        worst = std::max(worst, got / want);
        EXPECT_LT(got, 1.1 * want) << th;
    }
    EXPECT_GT(worst, 0.1);
}

TEST(Finish, ModelsFromTheSameSpecShareTheirBrdf) {
    const std::string spec = "microfacet d=beckmann m=0.21 f=dielectric eta=1.4";
    auto a = make_finish_model_from_spec(spec);
    auto b = make_finish_model_from_spec(spec);
    EXPECT_NE(a.get(), b.get());              // each finish owns its scale/tint/tangent
    EXPECT_EQ(a->brdf.get(), b->brdf.get());  // ... and shares the BRDF and its albedo
    EXPECT_EQ(a->albedo.get(), b->albedo.get());  // one albedo, computed lazily, at most once
    EXPECT_FALSE(a->albedo->computed());           // declaring a finish costs no quadrature
    EXPECT_GT(finish_model_albedo(*b, 1.0).g, 0.0);
    EXPECT_TRUE(a->albedo->computed());
    a->scale = Rgb(3.0);
    EXPECT_EQ(make_finish_model_from_spec(spec)->scale.r, 1.0);  // no state leaks between finishes
    EXPECT_THROW(make_finish_model_from_spec("microfacet d=nonsense"), std::exception);
}

TEST(SharedTable, LoadsOncePerKeyAndFreesWithTheLastUser) {
    SharedTableStats s0 = shared_table_stats();
    int calls = 0;
    auto loader = [&] {
        ++calls;
        return lambert_table(0.5);
    };
    auto a = shared_table("test:/tables/a.brdf", loader);
    auto b = shared_table("test:/tables/a.brdf", loader);
    auto c = shared_table("test:/tables/c.brdf", loader);
    EXPECT_EQ(calls, 2);
    EXPECT_EQ(a.get(), b.get());
    EXPECT_NE(a.get(), c.get());
    SharedTableStats s1 = shared_table_stats();
    EXPECT_EQ(s1.live_tables, s0.live_tables + 2);
    EXPECT_EQ(s1.live_bytes, s0.live_bytes + a->bytes_used() + c->bytes_used());
    EXPECT_EQ(s1.loads, s0.loads + 2);
    EXPECT_EQ(s1.reuses, s0.reuses + 1);
    EXPECT_GE(s1.peak_bytes, s1.live_bytes);
    a.reset();
    b.reset();
    c.reset();
    SharedTableStats s2 = shared_table_stats();
    EXPECT_EQ(s2.live_tables, s0.live_tables);
    EXPECT_EQ(s2.live_bytes, s0.live_bytes);
    // Gone: the next request loads again.
    auto d = shared_table("test:/tables/a.brdf", loader);
    EXPECT_EQ(calls, 3);
}

TEST(SharedTable, LoaderErrorsPropagateAndRegisterNothing) {
    SharedTableStats s0 = shared_table_stats();
    EXPECT_THROW(shared_table("test:/broken", []() -> std::unique_ptr<BrdfTable> {
                     throw TableError("broken: offset 0: expected magic, found junk");
                 }),
                 TableError);
    EXPECT_EQ(shared_table_stats().live_tables, s0.live_tables);
}

TEST(FinishRegistry, HandlesAreCountedAndLookupsLockFree) {
    std::size_t live0 = finish_model_live_count();
    int h = finish_model_register(make_finish_model(std::make_shared<Lambert>(Rgb(0.5))));
    ASSERT_GT(h, 0);
    EXPECT_EQ(finish_model_live_count(), live0 + 1);
    finish_model_addref(h);  // a copied FINISH
    finish_model_release(h);
    ASSERT_NE(finish_model_get(h), nullptr);
    // Many readers while the parser registers more models.
    std::vector<std::thread> readers;
    std::atomic<int> bad{0};
    for (int k = 0; k < 4; ++k)
        readers.emplace_back([&] {
            for (int i = 0; i < 20000; ++i)
                if (finish_model_get(h) == nullptr) ++bad;
        });
    std::vector<int> more;
    auto cheap = std::make_shared<FinishModel>();  // no albedo quadrature: only the handles matter here
    cheap->brdf = std::make_shared<Lambert>(Rgb(0.1));
    for (int i = 0; i < 5000; ++i) more.push_back(finish_model_register(cheap));
    for (auto& t : readers) t.join();
    EXPECT_EQ(bad.load(), 0);
    for (int m : more) finish_model_release(m);
    finish_model_release(h);
    EXPECT_EQ(finish_model_get(h), nullptr);
    EXPECT_EQ(finish_model_live_count(), live0);
    finish_model_release(0);  // no model: a no-op
    finish_model_addref(0);
}

namespace {
// Sum over a point's N reflection rays of weight * L with L = 1 everywhere (a white furnace):
// the glossy part's directional albedo, estimated. Averaged over `points` seeds.
Rgb furnace_reflection(const FinishModel& m, const Vec3& n, const Vec3& eye, int points) {
    Rgb sum;
    for (int p = 0; p < points; ++p) {
        std::uint64_t seed = finish_sample_seed(Vec3(p * 0.37, 1.0 / (p + 1), 2.0), eye);
        for (int k = 0; k < m.reflection_samples; ++k) {
            Vec3 dir;
            Rgb w;
            if (!finish_reflection_sample(m, n, eye, Rgb(1.0), seed, k, &dir, &w)) continue;
            EXPECT_NEAR(length(dir), 1.0, 1e-12);
            EXPECT_GT(dot(dir, n), 0.0);
            sum += w;
        }
    }
    return sum * (1.0 / points);
}
}  // namespace

TEST(GlossyReflection, WhiteFurnaceGivesTheGlossyAlbedo) {
    // Uniform unit radiance: the reflection rays must sum to a(theta) - base, the glossy part
    // of the directional albedo (quadrature of make_finish_model), for every sampler: the
    // microfacet and Ward lobes, and the default mixture (tables, Lafortune, POV phong).
    const char* specs[] = {
        "microfacet d=beckmann m=0.2 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8",
        "microfacet d=tr m=0.05 kd=0.5 rho_s=0.5 f=dielectric eta=1.5",
        "microfacet form=survey d=blinn n1=60 g=vcavity rho_s=0.4 kd=0.3",
        "ward rho_d=0.3 rho_s=0.2 ax=0.05 ay=0.25",
        "lafortune kd=0.2 lobe=-1,-1,1,30,0.6",
        "phong_pov phong=0.5 phong_size=40 diffuse=0.4",
    };
    const Vec3 n = normalize(Vec3(0.2, 0.3, 1.0));
    for (const char* spec : specs) {
        auto m = make_finish_model(make_brdf(spec));
        m->reflection_samples = 64;
        m->tangent = Vec3(1, 0, 0);
        for (double th : {0.0, 45.0, 75.0}) {
            // phi = 0 in the model's frame: the albedo nodes are computed there (for the
            // anisotropic Ward the albedo depends on phi too).
            const Frame fr = Frame::from_normal_tangent(n, m->tangent);
            const Vec3 eye = fr.to_world(spherical_direction(th * kPi / 180, 0.0));
            Rgb est = furnace_reflection(*m, n, eye, 400);
            Rgb want = finish_model_albedo(*m, dot(n, eye)) - m->base;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(est[c], want[c], 0.01 * want[c] + 2e-3) << spec << " theta=" << th << " channel " << c;
        }
    }
}

TEST(GlossyReflection, SamplesAreRepeatableAndStratified) {
    auto m = make_finish_model(make_brdf("microfacet d=beckmann m=0.3"));
    m->reflection_samples = 16;
    const Vec3 n(0, 0, 1), eye = normalize(Vec3(0.3, 0.1, 1.0));
    const std::uint64_t s1 = finish_sample_seed(Vec3(1, 2, 3), Vec3(0, 0, -1));
    EXPECT_EQ(s1, finish_sample_seed(Vec3(1, 2, 3), Vec3(0, 0, -1)));
    EXPECT_NE(s1, finish_sample_seed(Vec3(1, 2, 3.0000000001), Vec3(0, 0, -1)));
    Vec3 d1, d2;
    Rgb w1, w2;
    ASSERT_TRUE(finish_reflection_sample(*m, n, eye, Rgb(1.0), s1, 3, &d1, &w1));
    ASSERT_TRUE(finish_reflection_sample(*m, n, eye, Rgb(1.0), s1, 3, &d2, &w2));
    EXPECT_EQ(d1.x, d2.x);
    EXPECT_EQ(w1.r, w2.r);
    // Out of range k, no samples requested, eye below the surface: no ray.
    EXPECT_FALSE(finish_reflection_sample(*m, n, eye, Rgb(1.0), s1, 16, &d1, &w1));
    EXPECT_FALSE(finish_reflection_sample(*m, n, -eye, Rgb(1.0), s1, 0, &d1, &w1));
    m->reflection_samples = 0;
    EXPECT_FALSE(finish_reflection_sample(*m, n, eye, Rgb(1.0), s1, 0, &d1, &w1));
    // Stratification: the N samples of one point fall in N distinct u1 strata, so their
    // half-vector elevations spread out instead of clustering (lattice, not independent).
    m->reflection_samples = 256;
    double mean = 0;
    int got = 0;
    for (int k = 0; k < 256; ++k)
        if (finish_reflection_sample(*m, n, eye, Rgb(1.0), s1, k, &d1, &w1)) {
            mean += w1.r;
            ++got;
        }
    // One point's 256-sample estimate is already within 2 % of the albedo.
    EXPECT_NEAR(mean, finish_model_albedo(*m, eye.z).r, 0.02 * finish_model_albedo(*m, eye.z).r);
    EXPECT_GT(got, 200);
}

TEST(GlossyReflection, IndirectWeightKeepsOnlyTheBase) {
    // With reflection rays the glossy part no longer takes radiosity light (no double count).
    auto m = make_finish_model(make_brdf("microfacet d=beckmann m=0.3 kd=0.4,0.3,0.2 rho_s=0.5"));
    const Vec3 n(0, 0, 1), eye = normalize(Vec3(0.5, 0, 1));
    Rgb full = finish_indirect_weight(*m, n, eye, Rgb(1.0));
    EXPECT_GT(full.r, 0.6);
    m->reflection_samples = 8;
    Rgb base = finish_indirect_weight(*m, n, eye, Rgb(1.0));
    EXPECT_DOUBLE_EQ(base.r, 0.4);
    EXPECT_DOUBLE_EQ(base.g, 0.3);
    EXPECT_DOUBLE_EQ(base.b, 0.2);
    // A table has no separable base: all of it is sampled.
    auto t = make_finish_model(std::shared_ptr<const BrdfTable>(lambert_table(0.5)), Interp::Linear);
    EXPECT_EQ(t->base.max_component(), 0.0);
}

TEST(FinishRegistry, TangentReplacedOnlyForAnisotropicModels) {
    // POV's transforms move an anisotropic finish's direction with its object: a new model
    // with the new tangent, sharing the BRDF and albedo; the old handle's reference moves.
    auto aniso = make_finish_model(make_brdf("ward ax=0.05 ay=0.3 rho_s=0.3"));
    aniso->tangent = Vec3(1, 0, 0);
    const size_t live = finish_model_live_count();
    const int h = finish_model_register(aniso);
    finish_model_addref(h);  // a second finish (an object copy) still holds the original
    const int moved = finish_model_with_tangent(h, Vec3(0, 2, 0));
    ASSERT_NE(moved, h);
    const FinishModel* m = finish_model_get(moved);
    ASSERT_NE(m, nullptr);
    EXPECT_EQ(m->tangent.y, 2.0);
    EXPECT_EQ(m->brdf, aniso->brdf);
    EXPECT_EQ(m->albedo, aniso->albedo);
    EXPECT_EQ(finish_model_get(h)->tangent.x, 1.0);  // the other holder keeps its direction
    // The frame follows: a light along the new tangent sees the lobe's ay = 0.3 side.
    const Vec3 n(0, 0, 1), eye = normalize(Vec3(0.3, 0.4, 1.0));
    const Frame fr = Frame::from_normal_tangent(n, Vec3(0, 1, 0));
    const Rgb want = pov_weight(*aniso->brdf, fr.to_local(eye), fr.to_local(normalize(Vec3(-0.2, -0.5, 1.0))));
    const Rgb got = finish_light_weight(*m, n, eye, normalize(Vec3(-0.2, -0.5, 1.0)), Rgb(1.0));
    EXPECT_NEAR(got.g, want.g, 1e-12 * want.g);
    finish_model_release(moved);
    finish_model_release(h);
    EXPECT_EQ(finish_model_live_count(), live);
    // Isotropic models ignore the tangent: same handle back, nothing registered.
    const int iso = finish_model_register(make_finish_model(make_brdf("microfacet d=beckmann m=0.3")));
    EXPECT_EQ(finish_model_with_tangent(iso, Vec3(0, 1, 0)), iso);
    finish_model_release(iso);
    EXPECT_EQ(finish_model_with_tangent(0, Vec3(0, 1, 0)), 0);
    EXPECT_EQ(finish_model_live_count(), live);
}

TEST(Finish, OneViewPerHitGivesTheSameBitsAsAFreshOne) {
    // The renderer makes one FinishView per hit and reuses it for every light: the weights
    // must equal those of finish_light_weight(model, ...) to the bit, for tables (the
    // cosine path) and models (the frame path), isotropic and anisotropic.
    BuildOptions fold;
    fold.fold = true;
    std::shared_ptr<const BrdfTable> t =
        build_table(tabulate(*make_brdf("microfacet d=beckmann m=0.25 kd=0.2 rho_s=0.8"), TableGeometry::isotropic(2.0)),
                    fold);
    std::vector<std::shared_ptr<FinishModel>> models = {
        make_finish_model(t, Interp::Linear), make_finish_model(t, Interp::Nearest),
        make_finish_model(make_brdf("microfacet d=beckmann m=0.2 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8")),
        make_finish_model(make_brdf("ward ax=0.05 ay=0.3 rho_s=0.3"))};
    models.back()->tangent = Vec3(0.3, 1.0, 0.2);
    uint64_t state = 99;
    auto rnd = [&] {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return double(state >> 11) * 0x1.0p-53;
    };
    auto dir = [&] { return normalize(Vec3(2 * rnd() - 1, 2 * rnd() - 1, 2 * rnd() - 1)); };
    for (const auto& m : models) {
        FinishView view;
        for (int hit = 0; hit < 500; ++hit) {
            const Vec3 n = dir(), eye = dir();
            EXPECT_FALSE(view.is_for(*m, n, eye));
            finish_view(*m, n, eye, &view);
            ASSERT_TRUE(view.is_for(*m, n, eye));
            for (int light = 0; light < 8; ++light) {
                const Vec3 l = dir();
                const Rgb a = finish_light_weight(view, l, Rgb(0.5, 0.7, 0.9));
                const Rgb b = finish_light_weight(*m, n, eye, l, Rgb(0.5, 0.7, 0.9));
                ASSERT_EQ(a.r, b.r);
                ASSERT_EQ(a.g, b.g);
                ASSERT_EQ(a.b, b.b);
                if (!m->iso_table) {
                    // The prepared viewer (Brdf::prepare_view, e.g. Smith's Lambda(wo)) is the
                    // plain f(wo, wi) to the bit.
                    const Rgb c = pov_weight(*m->brdf, view.wo, view.frame.to_local(l)) * m->scale;
                    ASSERT_EQ(a.g, c.g);  // tint off: the pigment is not applied
                }
            }
        }
        // A copy with a new tangent is another model: the view does not fit it.
        const int h = finish_model_register(m);
        const int moved = finish_model_with_tangent(h, Vec3(0, 0, 1));
        if (m->brdf->anisotropic()) {
            EXPECT_FALSE(view.is_for(*finish_model_get(moved), view.n, view.to_eye));
        }
        finish_model_release(moved);
    }
}

TEST(FinishRegistry, MaxReflectionSamplesOfLiveModels) {
    const int before = finish_model_max_reflection_samples();
    auto a = make_finish_model(make_brdf("lambert"));
    a->reflection_samples = before + 7;
    const int h = finish_model_register(a);
    EXPECT_EQ(finish_model_max_reflection_samples(), before + 7);
    finish_model_release(h);
    EXPECT_EQ(finish_model_max_reflection_samples(), before);
}

TEST(Finish, PrefetchedLightGivesTheSameBits) {
    // finish_light_prefetch locates a light (and prefetches its cells) before the renderer's
    // shadow test; finish_light_weight then reuses that, or recomputes for any other light.
    BuildOptions fold;
    fold.fold = true;
    std::shared_ptr<const BrdfTable> t =
        build_table(tabulate(*make_brdf("microfacet d=beckmann m=0.2 kd=0.3 rho_s=0.7"), TableGeometry::isotropic(2.0)), fold);
    for (Interp interp : {Interp::Linear, Interp::Nearest}) {
        auto m = make_finish_model(t, interp);
        const Vec3 n = normalize(Vec3(0.1, 0.2, 1.0)), eye = normalize(Vec3(0.4, -0.3, 1.0));
        FinishView v;
        finish_view(*m, n, eye, &v);
        for (int k = 0; k < 200; ++k) {
            const Vec3 l = normalize(Vec3(std::sin(0.37 * k), std::cos(0.53 * k), 0.2 + 0.01 * k));
            const Rgb plain = finish_light_weight(*m, n, eye, l, Rgb(1.0));
            finish_light_prefetch(&v, l);
            const Rgb pre = finish_light_weight(v, l, Rgb(1.0));
            ASSERT_EQ(pre.r, plain.r);
            ASSERT_EQ(pre.b, plain.b);
            const Vec3 other = normalize(l + Vec3(0.01, 0, 0));  // not the prefetched light
            ASSERT_EQ(finish_light_weight(v, other, Rgb(1.0)).g, finish_light_weight(*m, n, eye, other, Rgb(1.0)).g);
        }
        finish_light_prefetch(&v, normalize(Vec3(0.3, 0.1, 1.0)));
        EXPECT_TRUE(v.pending.valid);
        finish_view(*m, n, normalize(Vec3(0, 0.5, 1.0)), &v);  // another hit: the prefetch is gone
        EXPECT_FALSE(v.pending.valid);
        finish_light_prefetch(&v, Vec3(0, 0, -1));  // a light below the surface: nothing to read
        EXPECT_FALSE(v.pending.valid);
    }
}

TEST(Finish, PrefetchedTableReadIsTheFreshLookup) {
    // The renderer locates a light's table rows before its shadow test
    // (finish_light_prefetch) and reads them after (finish_light_weight): for both table
    // layouts and both interpolations the weight is bit for bit the one without the
    // prefetch, a prefetch made for another light is not used, and the half/difference
    // weight is its direct lookup (eval_halfdiff_dirs) times pi cos(theta_i) and the scale.
    BuildOptions fold;
    fold.fold = true;
    const auto spec = "microfacet d=beckmann m=0.1 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8 kd=0.2 rho_s=0.8";
    std::shared_ptr<const BrdfTable> iso = build_table(tabulate(*make_brdf(spec), TableGeometry::isotropic(2.0)), fold);
    std::shared_ptr<const BrdfTable> hd =
        build_table(tabulate(*make_brdf(spec), TableGeometry::halfdiff(48, 32, 16)), BuildOptions());
    ASSERT_TRUE(hd->halfdiff());
    const Vec3 n = normalize(Vec3(-0.2, 0.1, 1.0)), eye = normalize(Vec3(0.3, 0.35, 1.0));
    const Rgb pigment(0.9, 0.5, 0.25);
    for (const auto& t : {iso, hd})
        for (Interp interp : {Interp::Linear, Interp::Nearest}) {
            auto m = make_finish_model(t, interp);
            m->scale = Rgb(0.5, 1.0, 2.0);
            int nonzero = 0;
            for (int k = 0; k < 300; ++k) {
                const Vec3 l = normalize(Vec3(std::sin(0.41 * k), std::cos(0.29 * k), 0.8 * std::sin(0.13 * k) + 0.1));
                const Vec3 other = normalize(Vec3(l.y, -l.x, l.z + 0.5));
                FinishView fresh, pre, stale;
                finish_view(*m, n, eye, &fresh);
                finish_view(*m, n, eye, &pre);
                finish_view(*m, n, eye, &stale);
                const Rgb want = finish_light_weight(fresh, l, pigment);
                finish_light_prefetch(&pre, l);
                finish_light_prefetch(&stale, other);
                const Rgb got = finish_light_weight(pre, l, pigment), got_stale = finish_light_weight(stale, l, pigment);
                const double ci = dot(n, l);
                EXPECT_EQ(pre.pending.valid, ci > 0) << k;
                for (int c = 0; c < 3; ++c) {
                    ASSERT_EQ(got[c], want[c]) << k << " " << c;
                    ASSERT_EQ(got_stale[c], want[c]) << k << " " << c;
                }
                if (!(ci > 0)) continue;
                ++nonzero;
                if (t == hd) {
                    const Rgb direct = hd->eval_halfdiff_dirs(n, l, eye, interp) * (kPi * ci) * m->scale;
                    for (int c = 0; c < 3; ++c) ASSERT_EQ(got[c], direct[c]) << k << " " << c;
                }
            }
            EXPECT_GT(nonzero, 100);
        }
}

TEST(Finish, ViewLookupOfATableIsTheTableTimesPiCosine) {
    // The renderer's per-light path for isotropic tables (inline in finish.h) against the
    // table's angle lookup (libm acos/atan2 in BrdfTable::f, another code path) times
    // pi cos(theta_i), the user scale and the tint; zero below the surface either side.
    BuildOptions fold;
    fold.fold = true;
    std::shared_ptr<const BrdfTable> t =
        build_table(tabulate(*make_brdf("microfacet d=beckmann m=0.2 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8"),
                             TableGeometry::isotropic(2.0)), fold);
    double top = 0;
    for (float v : t->values()) top = std::max(top, double(v));
    for (Interp interp : {Interp::Linear, Interp::Nearest})
        for (bool tint : {false, true}) {
            auto m = make_finish_model(t, interp);
            m->scale = Rgb(0.5, 1.0, 2.0);
            m->tint = tint;
            const Rgb pigment(0.9, 0.5, 0.25);
            const Vec3 n = normalize(Vec3(0.1, 0.2, 1.0)), eye = normalize(Vec3(0.4, -0.3, 1.0));
            const Frame fr = Frame::from_normal(n);
            FinishView v;
            finish_view(*m, n, eye, &v);
            int nonzero = 0;
            for (int k = 0; k < 400; ++k) {
                const Vec3 l = normalize(Vec3(std::sin(0.37 * k), std::cos(0.53 * k), 0.9 * std::sin(0.11 * k)));
                const Rgb got = finish_light_weight(v, l, pigment);
                const double ci = dot(n, l);
                if (!(ci > 0)) {
                    ASSERT_EQ(got.r + got.g + got.b, 0.0) << k;
                    continue;
                }
                ++nonzero;
                Rgb want = t->f(fr.to_local(eye), fr.to_local(l), interp) * (kPi * ci) * m->scale;
                if (tint) want = want * pigment;
                // Nearest lookups may pick the other node where the two paths' angles straddle
                // a cell's midpoint; none of these directions does.
                for (int c = 0; c < 3; ++c) ASSERT_NEAR(got[c], want[c], 1e-8 * top * kPi * 2) << k << " " << c;
            }
            EXPECT_GT(nonzero, 100);
        }
}

TEST(FinishRegistry, ViewOfAHandleNeedsNoLookupUntilTheRegistryChanges) {
    auto m = make_finish_model(make_brdf("microfacet d=beckmann m=0.3"));
    const int h = finish_model_register(m);
    const Vec3 n(0, 0, 1), eye = normalize(Vec3(0.2, 0.1, 1.0));
    FinishView v;
    ASSERT_EQ(finish_view_of(h, n, eye, &v), &v);
    EXPECT_EQ(v.model, m.get());
    EXPECT_EQ(v.handle, h);
    const std::uint64_t g = v.generation;
    EXPECT_EQ(g, finish_model_generation());
    ASSERT_EQ(finish_view_of(h, n, eye, &v), &v);  // same key: kept
    EXPECT_EQ(v.generation, g);
    // Another registration changes the generation: the next call looks the handle up again.
    const int other = finish_model_register(make_finish_model(make_brdf("lambert")));
    EXPECT_NE(finish_model_generation(), g);
    ASSERT_EQ(finish_view_of(h, n, eye, &v), &v);
    EXPECT_EQ(v.model, m.get());
    EXPECT_EQ(v.generation, finish_model_generation());
    finish_model_release(other);
    // A released handle has no model: no view.
    finish_model_release(h);
    EXPECT_EQ(finish_view_of(h, n, eye, &v), nullptr);
    EXPECT_EQ(finish_view_of(0, n, eye, &v), nullptr);
}
