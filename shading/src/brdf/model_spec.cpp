// make_brdf(): textual model specs -> analytic BRDFs, through the registry of models (model_spec.h).
#include "shading/brdf/model_spec.h"

#include <sstream>
#include <utility>

#include "shading/brdf/spec_args.h"

namespace shading {

// ---------------------------------------------------------------- the registry
// One line per model, in help order. MODEL(x) names `ModelEntry x_model()`, defined in the
// model's file under src/brdf/ with its class, keys, parser, spec writer, examples and costs
// (phong_pov and blinn_pov share pov_highlights.cpp). MODELS.md 8: adding a model.
#define SHADING_BRDF_MODELS(MODEL) \
    MODEL(lambert)                 \
    MODEL(phong_pov)               \
    MODEL(blinn_pov)               \
    MODEL(phong_normalized)        \
    MODEL(microfacet)              \
    MODEL(ward)                    \
    MODEL(oren_nayar)              \
    MODEL(lafortune)

#define SHADING_DECLARE_MODEL(x) ModelEntry x##_model();
SHADING_BRDF_MODELS(SHADING_DECLARE_MODEL)
#undef SHADING_DECLARE_MODEL

const std::vector<ModelEntry>& registered_models() {
#define SHADING_LIST_MODEL(x) x##_model(),
    static const std::vector<ModelEntry> models = {SHADING_BRDF_MODELS(SHADING_LIST_MODEL)};
#undef SHADING_LIST_MODEL
    return models;
}

// ---------------------------------------------------------------- make_brdf

BrdfPtr make_brdf(const std::string& spec) {
    std::istringstream s(spec);
    std::string model, tok;
    if (!(s >> model)) spec_error("empty spec; expected '<model> key=value ...'");
    std::vector<std::pair<std::string, std::string>> kv;
    while (s >> tok) {
        auto eq = tok.find('=');
        if (eq == std::string::npos || eq == 0) spec_error(model + ": expected key=value, got '" + tok + "'");
        kv.emplace_back(tok.substr(0, eq), tok.substr(eq + 1));
    }
    for (const ModelEntry& m : registered_models()) {
        if (m.name != model) continue;
        SpecArgs args(model, std::move(kv));
        BrdfPtr b = m.make(args);
        args.finish();
        return b;
    }
    std::string names;
    for (const ModelEntry& m : registered_models()) names += (names.empty() ? "" : ", ") + m.name;
    spec_error("unknown model '" + model + "'; known: " + names);
}

std::vector<ModelHelp> model_help() {
    std::vector<ModelHelp> out;
    for (const ModelEntry& m : registered_models()) out.push_back({m.name, m.summary, m.keys()});
    return out;
}

}  // namespace shading
