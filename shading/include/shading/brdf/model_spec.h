// Building analytic BRDFs from a textual spec, shared by brdftool and the tests.
//
// Spec grammar: "<model> key=value key=value ...", values are numbers or
// comma-separated RGB triples ("0.2,0.4,1.4") or words ("beckmann").
// Unknown models or keys, missing required keys and out-of-range values throw
// std::invalid_argument whose message names the offending key and the valid range.
#pragma once

#include <string>
#include <vector>

#include "shading/brdf/brdf.h"

namespace shading {

BrdfPtr make_brdf(const std::string& spec);

struct ModelHelp {
    std::string name;     // e.g. "lambert"
    std::string summary;  // one line
    std::string keys;     // keys with defaults and ranges, one per line
};
// Every model make_brdf knows, for `brdftool tabulate --help` and docs.
std::vector<ModelHelp> model_help();

}  // namespace shading
