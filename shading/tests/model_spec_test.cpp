#include <gtest/gtest.h>

#include <stdexcept>

#include "shading/model_spec.h"

using namespace shading;

TEST(ModelSpec, LambertScalarAndRgb) {
    Vec3 w(0, 0, 1);
    BrdfPtr a = make_brdf("lambert rho=0.5");
    EXPECT_DOUBLE_EQ(a->f(w, w).g, 0.5 / kPi);
    BrdfPtr b = make_brdf("lambert rho=0.2,0.4,0.6");
    EXPECT_DOUBLE_EQ(b->f(w, w).r, 0.2 / kPi);
    EXPECT_DOUBLE_EQ(b->f(w, w).b, 0.6 / kPi);
    BrdfPtr c = make_brdf("  lambert  ");  // default rho 0.5
    EXPECT_DOUBLE_EQ(c->f(w, w).r, 0.5 / kPi);
}

TEST(ModelSpec, ErrorsNameTheKey) {
    auto msg = [](const std::string& spec) {
        try {
            make_brdf(spec);
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string("<no throw>");
    };
    EXPECT_NE(msg("lambert rho=1.5").find("rho"), std::string::npos);
    EXPECT_NE(msg("lambert rho=1.5").find("[0, 1]"), std::string::npos);
    EXPECT_NE(msg("lambert foo=1").find("foo"), std::string::npos);
    EXPECT_NE(msg("lambert rho=0.1,0.2").find("rho"), std::string::npos);
    EXPECT_NE(msg("lambert rho=abc").find("not a number"), std::string::npos);
    EXPECT_NE(msg("lambert rho=nan").find("rho"), std::string::npos);
    EXPECT_NE(msg("lambert rho=0.1 rho=0.2").find("more than once"), std::string::npos);
    EXPECT_NE(msg("nosuch").find("unknown model"), std::string::npos);
    EXPECT_NE(msg("").find("empty"), std::string::npos);
    EXPECT_NE(msg("lambert rho").find("key=value"), std::string::npos);
}

TEST(ModelSpec, HelpListsEveryModel) {
    auto help = model_help();
    ASSERT_FALSE(help.empty());
    for (auto& h : help) {
        EXPECT_FALSE(h.summary.empty()) << h.name;
        // Every model builds from its name alone (all keys have defaults).
        EXPECT_NO_THROW(make_brdf(h.name)) << h.name;
    }
}
