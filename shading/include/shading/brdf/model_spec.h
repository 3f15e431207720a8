// Building analytic BRDFs from a textual spec, shared by brdftool, the finish facade and the
// tests, and the registry of the models make_brdf() knows.
//
// Spec grammar: "<model> key=value key=value ...", values are numbers or
// comma-separated RGB triples ("0.2,0.4,1.4") or words ("beckmann").
// Unknown models or keys, missing required keys and out-of-range values throw
// std::invalid_argument whose message names the offending key and the valid range.
// Brdf::spec() writes a model back in this grammar.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "shading/brdf/brdf.h"

namespace shading {

class SpecArgs;  // spec_args.h

BrdfPtr make_brdf(const std::string& spec);

struct ModelHelp {
    std::string name;     // e.g. "lambert"
    std::string summary;  // one line
    std::string keys;     // keys with defaults and ranges, one per line
};
// Every model make_brdf knows, for `brdftool tabulate --help` and docs.
std::vector<ModelHelp> model_help();

// One parameter set of a registered model, run by the generic test
// (tests/model_registry_test.cpp): spec round trip, reciprocity, energy, chi-square sampling.
struct ModelExample {
    std::string spec;
    bool energy_bounded = true;  // directional albedo <= 1 expected at every angle
};

// A model as make_brdf() knows it. Each is defined in its own file (src/brdf/<model>.cpp)
// and registered by one line in model_spec.cpp.
struct ModelEntry {
    std::string name, summary;
    std::function<std::string()> keys;       // help lines, defaults read from the class
    std::function<BrdfPtr(SpecArgs&)> make;  // reads the keys it knows; make_brdf rejects the rest
    bool reciprocal = true;                  // f(wo, wi) = f(wi, wo)
    std::string not_reciprocal_because;      // when not
    std::vector<ModelExample> examples;      // at least one
    // Built-in rough render costs of its fit families (fit.h CostTable): family prefix, ratio.
    std::vector<std::pair<std::string, double>> costs;
};
const std::vector<ModelEntry>& registered_models();

}  // namespace shading
