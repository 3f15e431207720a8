#include <gtest/gtest.h>

#include <sstream>
#include <stdexcept>

#include "shading/brdf/model_spec.h"

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

// The help prints each default from the model's class; writing that default explicitly
// must build the same BRDF as leaving the key out (help and defaults cannot drift apart).
TEST(ModelSpec, HelpDefaultsAreTheDefaults) {
    const Vec3 dirs[][2] = {{spherical_direction(0.3, 0.0), spherical_direction(0.5, 2.0)},
                            {spherical_direction(1.2, 0.4), spherical_direction(0.2, 3.5)},
                            {spherical_direction(0.7, 1.0), spherical_direction(0.7, 1.0 + kPi)}};
    int checked = 0;
    for (const ModelHelp& h : model_help()) {
        BrdfPtr plain;
        std::istringstream lines(h.keys);
        std::string line;
        while (std::getline(lines, line)) {
            const size_t eq = line.find('='), def = line.find(", default ");
            if (eq == std::string::npos || def == std::string::npos) continue;
            std::string value = line.substr(def + 10);
            value = value.substr(0, value.find_first_of(" ,;("));
            if (value.empty() || value == "alpha" || value == "one") continue;  // "default alpha", lobes
            // A key that belongs to one choice of a word key ("f=dielectric: ...") is compared
            // under that choice.
            std::string base = h.name;
            const size_t choice = line.find(" f=");
            if (choice != std::string::npos && choice < def) base += line.substr(choice, line.find(':', choice) - choice);
            plain = make_brdf(base);
            const std::string spec = base + " " + line.substr(0, eq) + "=" + value;
            BrdfPtr with = make_brdf(spec);
            for (const auto& d : dirs) {
                const Rgb a = plain->f(d[0], d[1]), b = with->f(d[0], d[1]);
                for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(a[c], b[c]) << spec;
            }
            ++checked;
        }
    }
    EXPECT_GE(checked, 20);  // every model's defaulted keys
}
