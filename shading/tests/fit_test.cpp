// Fitting models to tables (fit.h): the metric's definition, recovery of known parameters
// from tabulated models (clean, noisy, with missing cells and outliers), families, costs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <random>

#include "shading/core/bytes.h"
#include "shading/fit/fit.h"
#include "shading/brdf/model_spec.h"
#include "shading/tables/table.h"

using namespace shading;

namespace {

TableGrid grid_of(const std::string& spec, double step) {
    return tabulate(*make_brdf(spec), TableGeometry::isotropic(step, 3));
}

std::map<std::string, double> params_of(const FitResult& r) {
    std::map<std::string, double> m;
    for (const FitParam& p : r.params) m[p.name] = p.value;
    return m;
}

FitResult fit(const TableGrid& g, const std::string& family, FitOptions o = {}) {
    return fit_model(fit_samples(g), family, o);
}

TEST(FitMetric, IsTheDocumentedCosWeightedRelativeRmse) {
    TableGrid g = grid_of("microfacet d=beckmann m=0.3 kd=0.3 rho_s=0.7", 10);
    EXPECT_LT(table_error(*make_brdf("microfacet d=beckmann m=0.3 kd=0.3 rho_s=0.7"), g).rel_rmse, 1e-7);  // float32
    // A model 10 % brighter everywhere: E = 0.1 whatever the weights.
    TableGrid lam = grid_of("lambert rho=0.5", 10);
    EXPECT_NEAR(table_error(*make_brdf("lambert rho=0.55"), lam).rel_rmse, 0.1, 1e-6);
    // Weights are cos(theta_i) by node: a table wrong only at theta_i = 60 deg by +100 %
    // gives E^2 = cos60 x n60 / sum_i cos(theta_i) x n_i (every row holds the same cells).
    TableGrid bad = lam;
    const TableGeometry& geo = bad.geom;
    for (uint32_t r = 0; r < geo.n[1]; ++r)
        for (uint32_t p = 0; p < geo.n[2]; ++p)
            for (int c = 0; c < 3; ++c) bad.at(6, r, p, 0, c) *= 2.0f;
    double sum_cos = 0;
    for (uint32_t i = 0; i + 1 < geo.n[0]; ++i) sum_cos += std::cos(i * 10.0 * kPi / 180);
    ErrorStats e = table_error(*make_brdf("lambert rho=0.5"), bad);
    // E = sqrt(sum w (m - t)^2 / sum w t^2): row 6 has t = 2 m.
    double want = std::sqrt(0.5 * 1.0 / (sum_cos - 0.5 + 0.5 * 4.0));
    EXPECT_NEAR(e.rel_rmse, want, 1e-6);
    // No-data cells are excluded and counted.
    bad.at(3, 3, 3, 0, 1) = std::numeric_limits<float>::quiet_NaN();
    ErrorStats e2 = table_error(*make_brdf("lambert rho=0.5"), bad);
    EXPECT_EQ(e2.nodata_cells, 1u);
    EXPECT_EQ(e2.cells + 1, e.cells);
}

TEST(Fit, RecoversMicrofacetDielectricExactly) {
    const std::string spec = "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7";
    FitResult r = fit(grid_of(spec, 10), "microfacet d=beckmann g=smith f=dielectric");
    auto p = params_of(r);
    EXPECT_NEAR(p["m"], 0.3, 1e-4);
    EXPECT_NEAR(p["eta"], 1.5, 1e-3);
    EXPECT_NEAR(p["kd_g"], 0.3, 1e-4);
    EXPECT_NEAR(p["rho_s_b"], 0.7, 1e-4);
    EXPECT_LT(r.sample_error, 1e-5);
    EXPECT_EQ(pov_finish_snippet(r.spec), "finish { brdf_model { \"" + r.spec + "\" } }");
}

TEST(Fit, RecoversTrWithNoiseMissingCellsAndOutliers) {
    const std::string spec = "microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.5,0.06,0.04 rho_s=0.5";
    TableGrid g = grid_of(spec, 5);
    MeasurementSim sim;
    sim.noise = 0.02;
    sim.missing = 0.05;
    sim.seed = 3;
    uint64_t missing = simulate_measurement(g, sim);
    ASSERT_GT(missing, 100u);
    // 0.5 % of the values become 5x outliers (spikes of a broken detector reading).
    std::mt19937_64 rng(11);
    for (float& v : g.values)
        if (v >= 0 && std::uniform_real_distribution<double>(0, 1)(rng) < 0.005) v *= 5.0f;
    FitData d = fit_samples(g);
    EXPECT_GT(d.nodata_cells, 0u);
    FitResult r = fit_model(d, "microfacet d=tr g=smith f=dielectric");
    auto p = params_of(r);
    EXPECT_NEAR(p["m"], 0.15, 0.15 * 0.01);
    EXPECT_NEAR(p["eta"], 1.5, 0.03);
    EXPECT_NEAR(p["kd_r"], 0.5, 0.01);
    EXPECT_NEAR(p["kd_g"], 0.06, 0.003);
    EXPECT_NEAR(p["rho_s_g"], 0.5, 0.02);
    // The diffuse estimate (step 2) is already close.
    EXPECT_NEAR(r.kd_estimate.r, 0.5, 0.02);
}

TEST(Fit, RobustWeightsResistOutliers) {
    TableGrid g = grid_of("microfacet d=beckmann m=0.2 kd=0.2 rho_s=0.6", 5);
    std::mt19937_64 rng(5);
    for (float& v : g.values)
        if (std::uniform_real_distribution<double>(0, 1)(rng) < 0.01) v *= 20.0f;
    FitOptions plain;
    plain.irls_rounds = 1;
    auto robust = params_of(fit(g, "microfacet d=beckmann g=smith f=none"));
    auto ls = params_of(fit(g, "microfacet d=beckmann g=smith f=none", plain));
    EXPECT_NEAR(robust["m"], 0.2, 0.005);  // measured 0.2029; plain least squares: kd off by 28 %
    EXPECT_NEAR(robust["kd_r"], 0.2, 0.01);
    EXPECT_GT(std::abs(ls["kd_r"] - 0.2), 3 * std::abs(robust["kd_r"] - 0.2));
}

TEST(Fit, RecoversWardOrenNayarLafortuneAndLambert) {
    auto w = params_of(fit(grid_of("ward rho_d=0.4 rho_s=0.2 alpha=0.12", 5), "ward"));
    EXPECT_NEAR(w["alpha"], 0.12, 1e-3);
    EXPECT_NEAR(w["rho_d_r"], 0.4, 1e-3);
    EXPECT_NEAR(w["rho_s_r"], 0.2, 1e-3);
    auto on = params_of(fit(grid_of("oren_nayar rho=0.7,0.5,0.3 sigma=0.4", 10), "oren_nayar"));
    EXPECT_NEAR(on["sigma"], 0.4, 1e-3);
    EXPECT_NEAR(on["rho_b"], 0.3, 1e-3);
    // A lobe in the fitter's own parameterisation: C = (-c, -c, c R), c = ((n+2)/(2 pi))^(1/n).
    const double n = 30, R = 0.8, c = std::pow((n + 2) / (2 * kPi), 1 / n);
    char spec[200];
    std::snprintf(spec, sizeof spec, "lafortune kd=0.25 lobe=%.17g,%.17g,%.17g,30,0.4", -c, -c, c * R);
    auto lf = params_of(fit(grid_of(spec, 5), "lafortune k=1"));
    EXPECT_NEAR(lf["lobe1_n"], 30, 0.05);
    EXPECT_NEAR(lf["lobe1_cz_over_cxy"], 0.8, 1e-3);
    EXPECT_NEAR(lf["lobe1_w_g"], 0.4, 1e-3);
    EXPECT_NEAR(lf["kd_r"], 0.25, 1e-3);
    FitResult lam = fit(grid_of("lambert rho=0.3,0.5,0.7", 10), "lambert");
    EXPECT_NEAR(params_of(lam)["rho_g"], 0.5, 1e-6);
}

TEST(Fit, ConductorRecoversRoughnessAndReflectance) {
    TableGrid g = grid_of("microfacet d=tr m=0.35 f=conductor n=0.238,1.007,1.240 k=3.626,2.582,2.393", 10);
    FitResult r = fit(g, "microfacet d=tr g=smith f=conductor");
    auto p = params_of(r);
    EXPECT_NEAR(p["m"], 0.35, 0.35 * 0.01);
    EXPECT_NEAR(p["kd_r"], 0.0, 0.01);
    EXPECT_LT(table_error(*make_brdf(r.spec), g).rel_rmse, 0.01);
}

TEST(Fit, WrongFamilyFitsWorseThanTheRightOne) {
    TableGrid g = grid_of("microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.5 rho_s=0.5", 10);
    double right = table_error(*make_brdf(fit(g, "microfacet d=tr g=smith f=dielectric").spec), g).rel_rmse;
    double lambert = table_error(*make_brdf(fit(g, "lambert").spec), g).rel_rmse;
    EXPECT_LT(right, 1e-4);
    EXPECT_GT(lambert, 0.3);
}

TEST(Fit, FamiliesAndPatterns) {
    EXPECT_EQ(fit_families().size(), 38u);
    EXPECT_EQ(expand_families("microfacet").size(), 32u);
    EXPECT_EQ(expand_families("microfacet d=tr").size(), 8u);
    EXPECT_EQ(expand_families("microfacet g=smith f=schlick").size(), 4u);
    EXPECT_EQ(expand_families("lafortune k=3"), std::vector<std::string>{"lafortune k=3"});
    EXPECT_EQ(expand_families("ward"), std::vector<std::string>{"ward"});
    EXPECT_THROW(expand_families("microfacet d=ggx"), std::invalid_argument);
    EXPECT_THROW(expand_families("phong"), std::invalid_argument);
}

TEST(Fit, LoadTableGridKeepsNoDataCells) {
    auto t = build_table(grid_of("lambert rho=0.5", 10), BuildOptions{});
    std::vector<uint8_t> b = encode_table(*t);
    const TableHeader h = parse_table_header(b.data(), b.size(), "x");
    float nan = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(&b[h.payload_offset + 4 * 30], &nan, 4);  // cell 10, channel 0
    uint64_t sum = fnv1a64(b.data() + h.payload_offset, h.payload_bytes);
    for (int k = 0; k < 8; ++k) b[88 + k] = uint8_t(sum >> (8 * k));
    const std::string path = ::testing::TempDir() + "fit_nodata.brdf";
    write_file_bytes(path, b);
    TableGrid g = load_table_grid(path);
    EXPECT_TRUE(std::isnan(g.values[30]));
    EXPECT_EQ(fit_samples(g).nodata_cells, 1u);
    EXPECT_EQ(table_error(*make_brdf("lambert rho=0.5"), g).nodata_cells, 1u);
    std::remove(path.c_str());
}

TEST(Fit, CostTables) {
    CostTable b = builtin_costs();
    EXPECT_LT(b.cost_of("lambert"), b.cost_of("microfacet d=gaussian g=smith f=none"));
    EXPECT_EQ(b.cost_of("no such family"), 1.0);
    const std::string path = ::testing::TempDir() + "costs.txt";
    {
        std::ofstream o(path);
        o << "# measured\nmicrofacet d=tr 1.4  # trailing comment\nmicrofacet 1.2\ntable 1.1\n";
    }
    CostTable c = load_costs(path);
    EXPECT_DOUBLE_EQ(c.cost_of("microfacet d=tr g=smith f=none"), 1.4);
    EXPECT_DOUBLE_EQ(c.cost_of("microfacet d=blinn g=smith f=none"), 1.2);
    EXPECT_DOUBLE_EQ(c.cost_of("table"), 1.1);
    {
        std::ofstream o(path);
        o << "ward x\n";
    }
    EXPECT_THROW(load_costs(path), TableError);
    std::remove(path.c_str());
}

// The grammar of cost files, shared with harness/tools/cost.py (tests/test_reader_fuzz.py runs
// the same cases through both): refused lines name the line and the byte offset.
TEST(Fit, CostFileGrammar) {
    using Entries = std::vector<std::pair<std::string, double>>;
    EXPECT_EQ(parse_costs("# c\nlambert 1.02\nmicrofacet d=tr   1.3  # x\n", "c.txt").entries,
              (Entries{{"lambert", 1.02}, {"microfacet d=tr", 1.3}}));
    EXPECT_EQ(parse_costs("lambert\t1.5\r\nward\v2\f\n", "c.txt").entries, (Entries{{"lambert", 1.5}, {"ward", 2.0}}));
    EXPECT_EQ(parse_costs("lambert .5\nlambert +5.\n", "c.txt").cost_of("lambert"), 5.0);
    EXPECT_TRUE(parse_costs("", "c.txt").entries.empty());
    const std::pair<std::string, std::string> bad[] = {
        // Regression (costs_fuzz, corpus/costs/bad-ratio-nul.txt): strtod stopped at the NUL
        // and the old check (*end == '\0') took "1.5\0junk" for 1.5.
        {std::string("lambert 1.5\0junk\n", 17), "c.txt: line 1, offset 8: expected RATIO, a decimal number"},
        {std::string("lam\0bert 1.5\n", 13), "c.txt: line 1, offset 3: expected a family name in printable ASCII"},
        {"lambert inf\n", "c.txt: line 1, offset 8: expected RATIO, a decimal number, found 'inf'"},
        {"lambert nan\n", "c.txt: line 1, offset 8: expected RATIO, a decimal number"},
        {"lambert 1e999\n", "c.txt: line 1, offset 8: expected RATIO in [1e-06, 1e+06], found '1e999'"},
        {"lambert 0x1p2\n", "c.txt: line 1, offset 8: expected RATIO, a decimal number"},
        {"lambert 1_0\n", "c.txt: line 1, offset 8: expected RATIO, a decimal number"},
        {"ok 1\nlambert 0\n", "c.txt: line 2, offset 13: expected RATIO in [1e-06, 1e+06], found '0'"},
        {"ok 1\n\nward x\n", "c.txt: line 3, offset 11: expected RATIO, a decimal number, found 'x'"},
        {"lambert\n", "c.txt: line 1, offset 0: expected 'FAMILY RATIO' (two or more words), found 'lambert' alone"},
        {"lamb\xc3\xa9rt 1.0\n", "c.txt: line 1, offset 4: expected a family name in printable ASCII, found '\\xc3'"},
        {"lambert\xa0" "1.0\n", "c.txt: line 1, offset 0: expected 'FAMILY RATIO' (two or more words)"},
    };
    for (const auto& [text, want] : bad) {
        try {
            parse_costs(text, "c.txt");
            ADD_FAILURE() << "accepted: " << text;
        } catch (const TableError& e) {
            EXPECT_EQ(std::string(e.what()).substr(0, want.size()), want);
        }
    }
}

}  // namespace
