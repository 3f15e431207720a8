// The checks every model make_brdf() knows must pass, run on each example parameter set of
// its registration (model_spec.h, registered_models()); a new model cannot skip them:
//  - it has examples, and they reach every key of its help (so a spec() that drops a key fails);
//  - spec round trip: parse -> spec() -> parse gives the same spec and the same f, f_view,
//    pdf, sample, pdf_glossy, sample_glossy to the bit on random direction pairs;
//  - reciprocity f(wo, wi) = f(wi, wo) (relative 1e-6) where registered reciprocal, and a
//    measurable asymmetry where registered not (with the reason stated);
//  - energy: directional albedo (quadrature_albedo) <= 1 + kAlbedoTol at 0 to 89 deg for the
//    example sets registered energy bounded;
//  - chi-square goodness of fit of sample()/pdf() and sample_glossy()/pdf_glossy().
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <ostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "sampling_check.h"
#include "shading/brdf/model_spec.h"

using namespace shading;
using namespace shading_test;

namespace {

// quadrature_albedo's error on glossy parts (MODELS.md 6): 0.36 % for a normalised Phong lobe
// n = 20 of albedo 1 at normal incidence, 0.7 % at most at 85 deg for the models measured there.
constexpr double kAlbedoTol = 5e-3;

struct Case {
    const ModelEntry* model;
    ModelExample example;
    int index;  // over all cases: seeds and viewing directions
};

// gtest names a case by its spec.
void PrintTo(const Case& c, std::ostream* os) { *os << c.example.spec; }

std::vector<Case> all_cases() {
    std::vector<Case> out;
    for (const ModelEntry& m : registered_models())
        for (const ModelExample& e : m.examples) out.push_back({&m, e, int(out.size())});
    return out;
}

std::string case_name(const testing::TestParamInfo<Case>& info) {
    int k = 0;
    for (const ModelExample& e : info.param.model->examples) {
        if (e.spec == info.param.example.spec) break;
        ++k;
    }
    return info.param.model->name + "_" + std::to_string(k);
}

uint64_t bits(double x) {
    uint64_t u;
    std::memcpy(&u, &x, sizeof u);
    return u;
}
bool same(const Rgb& a, const Rgb& b) { return bits(a.r) == bits(b.r) && bits(a.g) == bits(b.g) && bits(a.b) == bits(b.b); }
bool same(const Vec3& a, const Vec3& b) { return bits(a.x) == bits(b.x) && bits(a.y) == bits(b.y) && bits(a.z) == bits(b.z); }

// A direction from two uniforms: mostly the upper hemisphere, some exactly grazing or below.
Vec3 direction(Rng& rng) {
    const double u = rng(), phi = 2 * kPi * rng();
    if (u < 0.05) return spherical_direction(kPi / 2, phi);
    if (u < 0.10) return spherical_direction(kPi / 2 + rng(), phi);
    if (u < 0.15) return spherical_direction((89.9 + 0.1 * rng()) * kDegree, phi);
    return spherical_direction(rng() * kPi / 2, phi);
}

// The viewing direction of a case's sampling test.
Vec3 view_of(const Case& c) {
    const double thetas[] = {20, 45, 70};
    return spherical_direction(thetas[c.index % 3] * kDegree, (37 + 71 * c.index) * kDegree);
}

// Key names of a help text: the word before '=' that starts each line.
std::set<std::string> help_keys(const std::string& help) {
    std::set<std::string> out;
    std::istringstream lines(help);
    for (std::string line; std::getline(lines, line);) out.insert(line.substr(0, line.find('=')));
    return out;
}
// Key names a spec states.
std::set<std::string> spec_keys(const std::string& spec) {
    std::set<std::string> out;
    std::istringstream words(spec);
    for (std::string w; words >> w;)
        if (w.find('=') != std::string::npos) out.insert(w.substr(0, w.find('=')));
    return out;
}

class EveryModel : public testing::TestWithParam<Case> {};

}  // namespace

TEST(ModelRegistry, EveryModelHasExamples) {
    ASSERT_FALSE(registered_models().empty());
    for (const ModelEntry& m : registered_models()) {
        EXPECT_FALSE(m.examples.empty()) << m.name << " has no example parameter set";
        EXPECT_FALSE(m.summary.empty()) << m.name;
        EXPECT_TRUE(m.reciprocal || !m.not_reciprocal_because.empty()) << m.name << ": not reciprocal, why?";
    }
}

// A key no example states is a key the round trip below never checks.
TEST(ModelRegistry, ExamplesReachEveryKey) {
    for (const ModelEntry& m : registered_models()) {
        std::set<std::string> seen;
        for (const ModelExample& e : m.examples)
            for (const std::string& k : spec_keys(make_brdf(e.spec)->spec())) seen.insert(k);
        for (const std::string& k : help_keys(m.keys())) EXPECT_TRUE(seen.count(k)) << m.name << ": no example's spec() states " << k;
    }
}

TEST_P(EveryModel, SpecRoundTripIsBitIdentical) {
    const Case& c = GetParam();
    const BrdfPtr a = make_brdf(c.example.spec);
    const std::string spec = a->spec();
    ASSERT_EQ(spec.rfind(c.model->name + " ", 0), 0u) << spec;
    const BrdfPtr b = make_brdf(spec);
    EXPECT_EQ(b->spec(), spec);
    EXPECT_NO_THROW(make_brdf(a->spec(6))) << a->spec(6);
    EXPECT_TRUE(same(a->lambert_base(), b->lambert_base())) << spec;
    EXPECT_EQ(a->anisotropic(), b->anisotropic()) << spec;
    Rng rng(1000 + c.index);
    int differ = 0;
    for (int k = 0; k < 2000; ++k) {
        const Vec3 wo = direction(rng), wi = direction(rng);
        const double u1 = rng(), u2 = rng();
        BrdfViewCache ca, cb;
        a->prepare_view(wo, &ca);
        b->prepare_view(wo, &cb);
        differ += !same(a->f(wo, wi), b->f(wo, wi)) + !same(a->f_view(wo, wi, ca), b->f_view(wo, wi, cb)) +
                  (bits(a->pdf(wo, wi)) != bits(b->pdf(wo, wi))) +
                  (bits(a->pdf_glossy(wo, wi)) != bits(b->pdf_glossy(wo, wi))) +
                  !same(a->sample(wo, u1, u2), b->sample(wo, u1, u2)) +
                  !same(a->sample_glossy(wo, u1, u2), b->sample_glossy(wo, u1, u2));
    }
    EXPECT_EQ(differ, 0) << c.example.spec << " -> " << spec;
}

TEST_P(EveryModel, Reciprocity) {
    const Case& c = GetParam();
    const BrdfPtr b = make_brdf(c.example.spec);
    Rng rng(2000 + c.index);
    int asymmetric = 0;
    for (int k = 0; k < 2000; ++k) {
        Vec3 wo = direction(rng), wi = direction(rng);
        if (k % 10 == 0) wi = mirror_z(wo);  // the mirror pair, grazing ones included
        const Rgb x = b->f(wo, wi), y = b->f(wi, wo);
        for (int ch = 0; ch < 3; ++ch)
            if (std::abs(x[ch] - y[ch]) > 1e-6 * std::max(std::abs(x[ch]), std::abs(y[ch])) + 1e-300) ++asymmetric;
    }
    if (c.model->reciprocal)
        EXPECT_EQ(asymmetric, 0) << c.example.spec;
    else
        EXPECT_GT(asymmetric, 0) << c.example.spec << ": registered not reciprocal (" << c.model->not_reciprocal_because
                                 << ") but is on every pair tried";
}

// Finite and non-negative for every example; at most 1 for those registered energy bounded.
TEST_P(EveryModel, EnergyAtMostOne) {
    const Case& c = GetParam();
    const BrdfPtr b = make_brdf(c.example.spec);
    for (double deg : {0.0, 30.0, 60.0, 80.0, 89.0}) {
        const Rgb a = quadrature_albedo(*b, deg * kDegree);
        for (int ch = 0; ch < 3; ++ch) {
            EXPECT_TRUE(std::isfinite(a[ch]) && a[ch] >= 0) << c.example.spec << " at " << deg << " deg";
            if (c.example.energy_bounded) {
                EXPECT_LE(a[ch], 1.0 + kAlbedoTol) << c.example.spec << " at " << deg << " deg";
            }
        }
    }
}

// Sidak: the family of chi-square tests (two per case) rejects a right sampler with
// probability 1 %.
double chi2_level() {
    static const double level = 1.0 - std::pow(1.0 - 0.01, 1.0 / (2.0 * all_cases().size()));
    return level;
}

TEST_P(EveryModel, SamplerMatchesPdf) {
    const Case& c = GetParam();
    expect_sampler_matches_pdf(*make_brdf(c.example.spec), view_of(c), false, chi2_level(), 3000 + c.index, 32, 1e-3,
                               c.example.spec);
}

TEST_P(EveryModel, GlossySamplerMatchesPdf) {
    const Case& c = GetParam();
    expect_sampler_matches_pdf(*make_brdf(c.example.spec), view_of(c), true, chi2_level(), 4000 + c.index, 32, 1e-3,
                               c.example.spec);
}

INSTANTIATE_TEST_SUITE_P(Registered, EveryModel, testing::ValuesIn(all_cases()), case_name);
