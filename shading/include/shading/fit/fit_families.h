// The model families the fitter knows (fit.h, fit_model): each family's shape parameters,
// the models it fits as a linear combination, and how a solution becomes a spec. Used by
// fit.cpp only.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"
#include "shading/core/optimize.h"
#include "shading/fit/fit.h"

namespace shading {
namespace fit_detail {

// A shape (non-linear) parameter of a family: its bounds and the starts of the scan.
struct ShapeParam {
    std::string name;
    double lo, hi;
    bool log;                    // optimised as log(x)
    std::vector<double> starts;  // scan values
};

struct SpecOut {
    std::string spec;
    std::vector<FitParam> linear;  // linear parameters as the spec states them
    bool clamped = false;
};

// How the lobe scales enter: fitted, fixed at 1, or 1 - kd (the conductor's).
enum class ScaleMode { Free, One, OneMinusKd };

struct Family {
    std::string name;
    std::vector<ShapeParam> shape;
    bool has_kd = true;
    ScaleMode scale = ScaleMode::Free;
    int nbases = 1;
    // The models whose linear combination (per channel, plus kd/pi) is fitted, built
    // directly from the shape parameters x (no spec text in the optimiser's loop).
    std::function<std::vector<BrdfPtr>(const Vector&)> bases;
    // kd and the per-basis coefficients per channel -> the printed spec (6 digits).
    std::function<SpecOut(const Vector&, const Rgb&, const std::vector<Rgb>&)> spec;
    std::function<bool(const Vector&)> valid_start = nullptr;
};

// The family of a canonical name (fit_families()); throws std::invalid_argument otherwise.
Family make_family(const std::string& name);

}  // namespace fit_detail
}  // namespace shading
