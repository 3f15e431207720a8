// The facade POV-Ray's patches call for BRDF finishes: finish models that a FINISH refers to
// by an integer handle, and what a model gives each kind of light and ray (direct lights,
// fill lights, indirect light, glossy rays). Dipole finishes: dipole_finish.h. Nothing here
// knows POV-Ray types; the patches convert vectors and colours at the call site.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"
#include "shading/tables/table.h"

namespace shading {

class Subsurface;  // subsurface.h

// One reference to a registered finish model (finish_model_register), released on destruction.
class ModelHandle {
public:
    explicit ModelHandle(int handle) : handle_(handle) {}
    ~ModelHandle();
    ModelHandle(const ModelHandle&) = delete;
    ModelHandle& operator=(const ModelHandle&) = delete;
    int get() const { return handle_; }

private:
    int handle_;
};

// The directional albedo a(theta) of one BRDF at FinishModel::kAlbedoNodes angles, computed
// on first use (thread-safe, std::call_once) and shared by every finish model of that BRDF:
// declaring a finish costs nothing until a render needs its albedo (indirect light, fill
// lights, glossy-ray weights). Tables use their own (BrdfTable::directional_albedo), analytic
// models a quadrature.
class AlbedoNodes {
public:
    // `table`: the table behind `brdf` (read with `interp`), if it is one: its own albedo.
    explicit AlbedoNodes(BrdfPtr brdf, std::shared_ptr<const BrdfTable> table = nullptr, Interp interp = Interp::Linear);
    const std::vector<Rgb>& get() const;
    bool computed() const { return done_.load(std::memory_order_acquire); }
    const BrdfPtr& brdf() const { return brdf_; }
    const BrdfTable* table() const { return table_.get(); }
    Interp interpolation() const { return interp_; }

private:
    BrdfPtr brdf_;
    std::shared_ptr<const BrdfTable> table_;
    Interp interp_;
    mutable std::once_flag once_;
    mutable std::vector<Rgb> nodes_;
    mutable std::atomic<bool> done_{false};
};

// Something the user should hear about a finish, and where the finish was written.
struct FinishNote {
    std::string file;
    int line = 0;
    std::string text;
    bool operator==(const FinishNote& o) const { return file == o.file && line == o.line && text == o.text; }
};

struct FinishModel {
    BrdfPtr brdf;            // the reflection model (analytic or tabulated), 1/sr
    Rgb scale{1.0};          // user scale on the whole BRDF
    bool tint = false;       // multiply by the pigment colour (off: the BRDF carries its own colour)
    Vec3 tangent{1, 0, 0};   // world-space tangent hint for anisotropic models (see Frame)
    // Directional albedo a(theta) = integral of f cos over the hemisphere, at kAlbedoNodes
    // equally spaced theta in [0, 90] deg (scale and tint not applied), for a viewer at
    // azimuth 0 (along the tangent: an anisotropic model's albedo at other azimuths differs).
    // Set by make_finish_model, computed when first read; used for indirect light, for lights
    // POV gives no highlight, and for the weight of glossy reflection rays.
    std::shared_ptr<const AlbedoNodes> albedo;
    const std::vector<Rgb>& albedo_nodes() const { return albedo->get(); }
    static constexpr int kAlbedoNodes = 46;  // every 2 deg
    // Set by make_finish_model for an isotropic table: finish_light_weight then reads the
    // table from the three cosines directly, without building a local frame.
    const BrdfTable* iso_table = nullptr;
    Interp iso_interp = Interp::Linear;
    // Set instead of iso_table for a half/difference table (layout 3): read from the world
    // vectors directly (BrdfTable::eval_halfdiff_dirs), with iso_interp.
    const BrdfTable* halfdiff_table = nullptr;
    // Albedo of the model's Lambertian base (Brdf::lambert_base), set by make_finish_model.
    Rgb base{0.0};
    // Finish `samples N` (0: off, at most kMaxReflectionSamples): the model's glossy part,
    // f - base/pi, also reflects the scene, through N rays importance-sampled from its lobe
    // (finish_reflection_sample). Indirect (radiosity) light then reaches only the base
    // (finish_indirect_weight), so no light is counted twice.
    int reflection_samples = 0;
    static constexpr int kMaxReflectionSamples = 4096;
    // A `dipole { }` finish: the subsurface light (subsurface.h) the renderer adds at every
    // point, while `brdf` holds its single scattering plus any coat (DipoleSurfaceBrdf).
    std::shared_ptr<const Subsurface> subsurface;
    bool has_subsurface() const { return subsurface != nullptr; }
    // With a subsurface: the coat's own BRDF (null: none), which `brdf` holds above the dipole.
    BrdfPtr coat;
    // What the user should hear about this finish if a scene uses it (finish_model_notes).
    std::vector<FinishNote> notes;
    // With a subsurface: a registered model whose BRDF is Ft(eta, cos_i)/pi
    // (TransmittanceBrdf); lit by the renderer's light loop it yields the transmitted
    // irradiance E_t at a point. Set by finish_model_with_subsurface, shared by copies, the
    // handle released with the last of them.
    std::shared_ptr<const ModelHandle> transmittance;
    int transmittance_handle() const;
    // Which model this is, unique in the process (a FinishView remembers it). A copy that
    // changes anything a view depends on needs a fresh one (next_finish_serial()).
    std::uint64_t serial = next_finish_serial();
    static std::uint64_t next_finish_serial();
};

// What every light at one shading point shares, computed once per hit: the model, the normal
// and the direction to the eye it was made for, and what the lookup needs of them (the
// viewer's theta_r position in an isotropic table; otherwise the local frame and the viewer
// in it). finish_light_weight(view, ...) then costs one table read or model evaluation per
// light. A view is a pure function of (model, n, to_eye): reusing one or making it afresh
// gives the same bits.
struct FinishView {
    const FinishModel* model = nullptr;
    std::uint64_t serial = 0;  // model->serial
    int handle = 0;                  // finish_view_of: the handle it was made for, and the
    std::uint64_t generation = 0;    //   registry generation then
    Vec3 n, to_eye;
    double cos_o = 0, sin2_o = 0;  // n . to_eye and 1 - cos_o^2
    BrdfTable::AxisPos theta_r;    // isotropic tables
    Frame frame;                   // other models
    Vec3 wo;
    BrdfViewCache brdf;            //   and what the model keeps of wo (Brdf::prepare_view)
    // The light finish_light_prefetch was last asked about, and its table coordinates.
    struct Pending {
        Vec3 to_light;
        bool valid = false;
        double cos_i = 0;
        BrdfTable::IsoRead read;  // isotropic tables
        BrdfTable::HdRead hd;     // half/difference tables
    } pending;
    // Whether this view was made for `m` at (n, to_eye), bit for bit.
    bool is_for(const FinishModel& m, const Vec3& n_, const Vec3& to_eye_) const {
        return serial == m.serial && n.x == n_.x && n.y == n_.y && n.z == n_.z && to_eye.x == to_eye_.x &&
               to_eye.y == to_eye_.y && to_eye.z == to_eye_.z;
    }
};
void finish_view(const FinishModel& model, const Vec3& n, const Vec3& to_eye, FinishView* view);
// The renderer's form, per light: `view` itself when it was made for this handle, normal and
// eye and no handle has changed its model since (finish_model_generation: no registry
// lookup), else remade (finish_view_remake); null for a handle without a model.
namespace detail {
extern std::atomic<std::uint64_t> finish_generation;
}
inline std::uint64_t finish_model_generation() { return detail::finish_generation.load(std::memory_order_acquire); }
const FinishView* finish_view_remake(int handle, const Vec3& n, const Vec3& to_eye, FinishView* view);
inline const FinishView* finish_view_of(int handle, const Vec3& n, const Vec3& to_eye, FinishView* v) {
    if (handle != 0 && v->handle == handle && v->generation == finish_model_generation() && v->n.x == n.x &&
        v->n.y == n.y && v->n.z == n.z && v->to_eye.x == to_eye.x && v->to_eye.y == to_eye.y && v->to_eye.z == to_eye.z)
        return v;
    return finish_view_remake(handle, n, to_eye, v);
}

// A finish model around `brdf`, its directional albedo to be computed on first use
// (AlbedoNodes).
std::shared_ptr<FinishModel> make_finish_model(BrdfPtr brdf);
// A finish model around a table read with `interp` (table_brdf): the renderer reads an isotropic
// or half/difference table directly (FinishModel::iso_table, halfdiff_table), and the albedo is
// the table's own.
std::shared_ptr<FinishModel> make_finish_model(std::shared_ptr<const BrdfTable> table, Interp interp);

// make_finish_model(make_brdf(spec)), memoised by spec while some model made from it lives:
// finishes that repeat a spec share its BRDF and its albedo (computed once, if ever).
// Scale, tint and tangent of the returned (fresh) model are the caller's to set.
std::shared_ptr<FinishModel> make_finish_model_from_spec(const std::string& spec);

// `coat` (may be null: no coat) with the subsurface `s` under it: a new model whose brdf is
// DipoleSurfaceBrdf(s, coat's own BRDF without any earlier dipole), keeping the coat's scale,
// tint, tangent and reflection samples, and whose `transmittance` model is registered here.
// The albedo is recomputed (lazily) for the sum.
std::shared_ptr<FinishModel> finish_model_with_subsurface(const FinishModel* coat, std::shared_ptr<const Subsurface> s);

// The dipole of `dipole` (a model with a subsurface) under a new `coat`: a brdf_model or brdf_table
// written after the dipole in one finish. Keeps the dipole's notes.
std::shared_ptr<FinishModel> finish_model_with_coat(const FinishModel& dipole, const FinishModel* coat);

// The model's directional albedo at cos(theta) (linear between nodes; scale/tint not applied).
Rgb finish_model_albedo(const FinishModel& model, double cos_theta);

// A file the renderer located under its own rules (library path, I/O restrictions), for the
// library to read when it needs the bytes.
struct FoundFile {
    std::string key;  // the resolved path: finishes naming one file share what was read from it
    // Its size in bytes: negative when it cannot be read; a folder may answer INT64_MAX.
    std::function<std::int64_t()> size;
    // Reads `bytes` bytes from the start into `to`; false when fewer came.
    std::function<bool(std::uint8_t* to, std::size_t bytes)> read;
};
// Locates `name` for the library; null when it is not found or the I/O restrictions refuse it.
using FindFile = std::function<std::unique_ptr<FoundFile>(const std::string& name)>;

// A `brdf_table` finish: the table in `file` (the scene's name for it is `source`), read only
// when no live table has its key, checked whole (load_table) and never larger than the largest
// table the loader accepts. Throws std::invalid_argument, TableError: "SOURCE: offset N: ...".
std::shared_ptr<FinishModel> make_table_finish(const std::string& source, const FoundFile& file, bool interpolate);
// Why `name` could not be opened: not found (and where the renderer looked), or found at
// `found` and refused or unreadable (locate.h explain_unopened).
std::string finish_file_unopened(const std::string& name, const std::string& found,
                                 const std::vector<std::string>& library_paths);

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
    // Sampling data of tables that glossy rays (`samples N`) sample (TableSampler, built on
    // first use, one per table): bytes now and at most.
    std::size_t sampler_bytes = 0, peak_sampler_bytes = 0;
};
SharedTableStats shared_table_stats();

// The statistics lines of every table and subsurface finish of the process so far (table memory,
// files read, subsurface clouds, points, lookups, thin geometry, warnings), for POV's render
// statistics; none when no such finish ran.
std::vector<std::string> finish_statistics();

// Counted registry, process-wide. register returns a handle > 0 holding one reference.
// addref/release accept 0 (no model) as a no-op, so FINISH copies need no special case.
// get() is lock-free and valid while a reference is held (rendering holds the scene's); for
// handle 0 (a stock finish) it answers null inline, so the renderer's per-hit hooks cost a
// stock finish one test, no call.
int finish_model_register(std::shared_ptr<const FinishModel> model);
void finish_model_addref(int handle);
void finish_model_release(int handle);
namespace detail {
const FinishModel* finish_model_lookup(int handle);  // finish_model_get for handle != 0
}
inline const FinishModel* finish_model_get(int handle) {
    return handle == 0 ? nullptr : detail::finish_model_lookup(handle);
}
std::size_t finish_model_live_count();
// The notes (FinishModel::notes) of the live finish models, each once, in the order of their
// handles: after parsing, the finishes the scene's objects use.
std::vector<FinishNote> finish_model_notes();

// "did you mean 'X'?" for the name in `names` closest to a misspelt `word` (core/suggest.h
// closest_name), or empty when none is close.
std::string did_you_mean(const std::string& word, const std::vector<std::string>& names);
// The largest `samples` (reflection_samples) among the live finish models, 0 if none: the
// parser's estimate of what glossy rays will cost with area lights.
int finish_model_max_reflection_samples();
// finish_model_generation() (above, inline): a number that changes whenever some handle
// starts or stops naming a model (registration, last release); a handle read at one
// generation names the same model while it is current.

// The model of `handle` with its world-space tangent (the anisotropy `direction`) replaced,
// for finishes that move with their object or texture (POV's transforms): a new registered
// model sharing the BRDF and its albedo, and the caller's reference moves from `handle` to
// the returned handle. A model whose BRDF is not anisotropic never reads its tangent and
// comes back unchanged (same handle); so does handle 0.
int finish_model_with_tangent(int handle, const Vec3& tangent);

// POV's contribution of one light: pixel += finish_light_weight(...) * light colour.
// n: unit shading normal; to_eye, to_light: unit vectors leaving the surface (world
// space). Applies pov_weight() (pi * f * cos_i), the user scale and the optional tint.
// The renderer makes one FinishView per hit and calls the view form for each light; the
// other form makes the view itself (same result).
// Inline for a light finish_light_prefetch located (the renderer's per-light call then holds
// the table read); otherwise finish_light_weight_fresh.
namespace detail {
// A table's value f as the light's weight (pov_weight): pi f cos_i, the user scale, the tint.
inline Rgb table_light_weight(const FinishModel& model, const Rgb& f, double cos_i, const Rgb& pigment) {
    const Rgb w = f * (kPi * cos_i) * model.scale;
    return model.tint ? w * pigment : w;
}
}  // namespace detail
Rgb finish_light_weight_fresh(const FinishView& view, const Vec3& to_light, const Rgb& pigment);
inline Rgb finish_light_weight(const FinishView& view, const Vec3& to_light, const Rgb& pigment) {
    const FinishView::Pending& p = view.pending;
    if (!(p.valid && p.to_light.x == to_light.x && p.to_light.y == to_light.y && p.to_light.z == to_light.z))
        return finish_light_weight_fresh(view, to_light, pigment);
    const FinishModel& model = *view.model;
    const Rgb f = model.halfdiff_table ? BrdfTable::read_halfdiff(p.hd) : BrdfTable::read_iso(p.read);
    return detail::table_light_weight(model, f, p.cos_i, pigment);
}
// Starts reading the table cells a light will need (isotropic tables; a no-op otherwise) and
// remembers their coordinates in the view: called before the renderer's shadow test, it lets
// the memory latency of the read overlap the test; finish_light_weight for the same light
// then uses them (the same bits as without).
void finish_light_prefetch(FinishView* view, const Vec3& to_light);
Rgb finish_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Vec3& to_light,
                        const Rgb& pigment);

// Lights seen by radiosity gather rays (for which POV computes no highlight): the model acts
// as a Lambertian surface of its directional albedo at the light, weight a(theta_l) cos (by
// reciprocity the light's reflectance; approximate for POV's non-reciprocal phong/specular).
// Fill (shadowless) lights get the full model (finish_light_weight), unlike POV's highlights.
Rgb finish_diffuse_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_light, const Rgb& pigment);

// Indirect (radiosity) light: uniform incident light reflects a(theta_eye) of it, so POV's
// ambient colour is multiplied by the directional albedo towards the eye (times scale, tint);
// with reflection_samples > 0 only the Lambertian base's albedo (the sampled rays carry the rest).
Rgb finish_indirect_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment);

// Glossy reflection (reflection_samples > 0). Ray k (0 <= k < N = reflection_samples) at a
// surface point: *dir, the world direction to trace, and *weight, the factor on the colour
// it brings back, f_glossy cos_i / (pdf_glossy N) times scale and tint, so that
// pixel += sum_k weight_k * traced_k estimates the reflected radiance without bias.
// (u1, u2) of ray k come from a rank-1 lattice, ((k + 1/2)/N, k/phi mod 1), rotated by two
// numbers drawn from `seed`: stratified in both dimensions, repeatable. Returns false when
// the sample gives nothing (below the surface, or zero density); it still counts toward N.
bool finish_reflection_sample(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment,
                              std::uint64_t seed, int k, Vec3* dir, Rgb* weight);

// The fraction of uniform light the reflection rays bring back at this view: the directional
// albedo minus the Lambertian base, times scale and tint (for POV's adaptive depth control,
// like `reflection`'s amount for a mirror ray).
Rgb finish_glossy_albedo(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment);

// Seed for a surface point's reflection rays: a hash of the bit patterns of the hit point and
// of the incoming ray's direction. Images are then the same in every run and for any number
// of render threads or tile order.
std::uint64_t finish_sample_seed(const Vec3& point, const Vec3& direction);

}  // namespace shading
