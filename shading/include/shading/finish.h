// The adapter-facing side of the library: finish models that POV-Ray's FINISH refers
// to by an integer handle, and the single function that turns a model into POV's
// light contribution. Nothing here knows POV-Ray types; the patches convert vectors
// and colours at the call site.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "shading/brdf.h"

namespace shading {

struct FinishModel {
    BrdfPtr brdf;            // the reflection model (analytic or tabulated), 1/sr
    Rgb scale{1.0};          // user scale on the whole BRDF
    bool tint = false;       // multiply by the pigment colour (off: the BRDF carries its own colour)
    Vec3 tangent{1, 0, 0};   // world-space tangent hint for anisotropic models (see Frame)
    std::string source;      // what the user wrote (file name or model spec), for messages/statistics
    std::size_t bytes = 0;   // memory owned by the model but not counted elsewhere (tables report their own)
};

// Counted registry, process-wide. register returns a handle > 0 holding one reference.
// addref/release accept 0 (no model) as a no-op, so FINISH copies need no special case.
// get() is lock-free and valid while a reference is held (rendering holds the scene's).
int finish_model_register(std::shared_ptr<const FinishModel> model);
void finish_model_addref(int handle);
void finish_model_release(int handle);
const FinishModel* finish_model_get(int handle);
std::size_t finish_model_live_count();

// POV's contribution of one light: pixel += finish_light_weight(...) * light colour.
// n: unit shading normal; to_eye, to_light: unit vectors leaving the surface (world
// space). Applies pov_weight() (pi * f * cos_i), the user scale and the optional tint.
Rgb finish_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Vec3& to_light,
                        const Rgb& pigment);

}  // namespace shading
