// The adapter-facing side of the library: finish models that POV-Ray's FINISH refers
// to by an integer handle, and the single function that turns a model into POV's
// light contribution. Nothing here knows POV-Ray types; the patches convert vectors
// and colours at the call site.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "shading/brdf.h"
#include "shading/table.h"

namespace shading {

struct FinishModel {
    BrdfPtr brdf;            // the reflection model (analytic or tabulated), 1/sr
    Rgb scale{1.0};          // user scale on the whole BRDF
    bool tint = false;       // multiply by the pigment colour (off: the BRDF carries its own colour)
    Vec3 tangent{1, 0, 0};   // world-space tangent hint for anisotropic models (see Frame)
    // Directional albedo a(theta) = integral of f cos over the hemisphere, at kAlbedoNodes
    // equally spaced theta in [0, 90] deg (scale and tint not applied). Filled by
    // make_finish_model; used for indirect light and for lights POV gives no highlight.
    std::vector<Rgb> albedo;
    static constexpr int kAlbedoNodes = 46;  // every 2 deg
    // Set by make_finish_model for an isotropic table: finish_light_weight then reads the
    // table from the three cosines directly, without building a local frame.
    const BrdfTable* iso_table = nullptr;
    Interp iso_interp = Interp::Linear;
};

// A finish model around `brdf` with its directional albedo computed: a table's own
// (BrdfTable::directional_albedo), otherwise a quadrature of the model
// (multiple importance sampling of a cosine grid and mirror lobes, 46 nodes: ~55 ms per
// microfacet model, once per distinct spec; see finish.cpp).
std::shared_ptr<FinishModel> make_finish_model(BrdfPtr brdf);

// make_finish_model(make_brdf(spec)), memoised by spec while some model made from it lives:
// finishes that repeat a spec share its BRDF and skip the albedo quadrature (~55 ms).
// Scale, tint and tangent of the returned (fresh) model are the caller's to set.
std::shared_ptr<FinishModel> make_finish_model_from_spec(const std::string& spec);

// The model's directional albedo at cos(theta) (linear between nodes; scale/tint not applied).
Rgb finish_model_albedo(const FinishModel& model, double cos_theta);

// A table as a Brdf with its own interpolation choice, so finishes that name the same file
// with different `interpolate` settings share one table.
BrdfPtr table_brdf(std::shared_ptr<const BrdfTable> table, Interp interp);

// Tables shared by every finish (and thread) that names the same key (the resolved path):
// `load` runs only when no live table has that key; the table lives while a finish holds it.
std::shared_ptr<const BrdfTable> shared_table(const std::string& key,
                                              const std::function<std::unique_ptr<BrdfTable>()>& load);
struct SharedTableStats {
    std::size_t live_tables = 0, live_bytes = 0;  // now
    std::size_t peak_tables = 0, peak_bytes = 0;  // highest since the process started
    std::size_t loads = 0, reuses = 0;            // files read, and requests served from memory
};
SharedTableStats shared_table_stats();

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

// Lights for which POV computes no highlight (radiosity gather rays, fill lights): the model
// acts as a Lambertian surface of its directional albedo at the light, weight a(theta_l) cos.
Rgb finish_diffuse_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_light, const Rgb& pigment);

// Indirect (radiosity) light: uniform incident light reflects a(theta_eye) of it, so POV's
// ambient colour is multiplied by the directional albedo towards the eye (times scale, tint).
Rgb finish_indirect_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment);

}  // namespace shading
