#include "shading/finish/finish.h"

#include "shading/core/suggest.h"
#include "shading/brdf/model_spec.h"
#include "shading/brdf/models.h"
#include "shading/subsurface/subsurface.h"
#include "shading/tables/table_sampler.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace shading {
namespace {

// Handles index fixed-size chunks allocated on demand and never moved, so readers
// (render threads) look a slot up without locking while the parser registers more.
constexpr int kChunkBits = 12;
constexpr int kChunkSize = 1 << kChunkBits;
constexpr int kMaxChunks = 256;  // ~1M live finish models

struct Slot {
    std::shared_ptr<const FinishModel> owner;   // guarded by the registry mutex
    std::atomic<const FinishModel*> model{nullptr};
    long refs = 0;                               // guarded by the registry mutex
};

struct Registry {
    std::mutex mutex;
    std::array<std::atomic<Slot*>, kMaxChunks> chunks{};
    std::vector<std::unique_ptr<Slot[]>> storage;
    std::vector<int> free_handles;
    int next = 1;  // handle 0 means "no model"
    std::size_t live = 0;

    Slot* slot(int handle) {
        if (handle <= 0 || (handle >> kChunkBits) >= kMaxChunks) return nullptr;
        Slot* chunk = chunks[handle >> kChunkBits].load(std::memory_order_acquire);
        return chunk ? &chunk[handle & (kChunkSize - 1)] : nullptr;
    }
};

Registry& registry() {
    static Registry r;
    return r;
}

}  // namespace

// Changes whenever a handle starts or stops naming a model (finish_model_generation).
std::atomic<std::uint64_t> detail::finish_generation{1};

int finish_model_register(std::shared_ptr<const FinishModel> model) {
    if (!model || !model->brdf) throw std::invalid_argument("finish model without a BRDF");
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    int handle;
    if (!r.free_handles.empty()) {
        handle = r.free_handles.back();
        r.free_handles.pop_back();
    } else {
        handle = r.next;
        int c = handle >> kChunkBits;
        if (c >= kMaxChunks) throw std::length_error("too many live finish models (limit 1048575)");
        if (!r.chunks[c].load(std::memory_order_relaxed)) {
            r.storage.emplace_back(new Slot[kChunkSize]);
            r.chunks[c].store(r.storage.back().get(), std::memory_order_release);
        }
        ++r.next;
    }
    Slot* s = r.slot(handle);
    s->owner = std::move(model);
    s->refs = 1;
    s->model.store(s->owner.get(), std::memory_order_release);
    ++r.live;
    detail::finish_generation.fetch_add(1, std::memory_order_acq_rel);
    return handle;
}

void finish_model_addref(int handle) {
    if (handle == 0) return;
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    Slot* s = r.slot(handle);
    if (s && s->refs > 0) ++s->refs;
}

void finish_model_release(int handle) {
    if (handle == 0) return;
    std::shared_ptr<const FinishModel> last;  // destroyed after the lock is released: a model
                                              // may own handles itself (a dipole's light loop)
    Registry& r = registry();
    {
        std::lock_guard<std::mutex> lock(r.mutex);
        Slot* s = r.slot(handle);
        if (!s || s->refs <= 0) return;
        if (--s->refs == 0) {
            s->model.store(nullptr, std::memory_order_release);
            last = std::move(s->owner);
            r.free_handles.push_back(handle);
            --r.live;
            detail::finish_generation.fetch_add(1, std::memory_order_acq_rel);
        }
    }
}

const FinishModel* detail::finish_model_lookup(int handle) {
    Slot* s = registry().slot(handle);
    return s ? s->model.load(std::memory_order_acquire) : nullptr;
}

int finish_model_with_tangent(int handle, const Vec3& tangent) {
    const FinishModel* m = finish_model_get(handle);
    if (!m || !m->brdf->anisotropic()) return handle;
    auto moved = std::make_shared<FinishModel>(*m);
    moved->tangent = tangent;
    moved->serial = FinishModel::next_finish_serial();  // views of the original do not fit it
    const int fresh = finish_model_register(std::move(moved));
    finish_model_release(handle);
    return fresh;
}

int finish_model_max_reflection_samples() {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    int most = 0;
    for (int h = 1; h < r.next; ++h) {
        const Slot* s = r.slot(h);
        if (s && s->refs > 0 && s->owner) most = std::max(most, s->owner->reflection_samples);
    }
    return most;
}

std::vector<FinishNote> finish_model_notes() {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    std::vector<FinishNote> notes;
    for (int h = 1; h < r.next; ++h) {
        const Slot* s = r.slot(h);
        if (s && s->refs > 0 && s->owner)
            for (const FinishNote& note : s->owner->notes)
                if (std::find(notes.begin(), notes.end(), note) == notes.end()) notes.push_back(note);
    }
    return notes;
}

std::string did_you_mean(const std::string& word, const std::vector<std::string>& names) {
    const std::string meant = closest_name(word, names);
    return meant.empty() ? meant : "did you mean '" + meant + "'?";
}

std::size_t finish_model_live_count() {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    return r.live;
}

std::uint64_t FinishModel::next_finish_serial() {
    static std::atomic<std::uint64_t> next{1};
    return next.fetch_add(1, std::memory_order_relaxed);
}

const FinishView* finish_view_remake(int handle, const Vec3& n, const Vec3& to_eye, FinishView* v) {
    const std::uint64_t generation = finish_model_generation();
    // The handle still names the model the view was made from while no handle has changed
    // its model since (the next hit on the same finish: no registry lookup).
    const FinishModel* model =
        handle != 0 && v->handle == handle && v->generation == generation ? v->model : finish_model_get(handle);
    if (!model) return nullptr;
    finish_view(*model, n, to_eye, v);
    v->handle = handle;
    v->generation = generation;
    return v;
}

void finish_view(const FinishModel& model, const Vec3& n, const Vec3& to_eye, FinishView* v) {
    v->handle = 0;  // made from a model, not a handle (finish_view_of sets these)
    v->generation = 0;
    v->model = &model;
    v->serial = model.serial;
    v->pending.valid = false;  // a prefetched light belongs to the view it was made in
    v->n = n;
    v->to_eye = to_eye;
    v->cos_o = dot(n, to_eye);
    v->sin2_o = 1.0 - v->cos_o * v->cos_o;
    if (model.iso_table) {
        if (v->cos_o > 0) v->theta_r = model.iso_table->locate_theta_r_cos(v->cos_o, model.iso_interp);
        return;
    }
    if (model.halfdiff_table) return;  // looked up from world vectors, no frame
    v->frame = model.brdf->anisotropic() ? Frame::from_normal_tangent(n, model.tangent) : Frame::from_normal(n);
    v->wo = v->frame.to_local(to_eye);
    model.brdf->prepare_view(v->wo, &v->brdf);
}

namespace {
// cos(theta_i) into *ci; false when the light or the viewer is below the surface.
bool both_above(const FinishView& v, const Vec3& to_light, double* ci) {
    *ci = dot(v.n, to_light);
    return *ci > 0 && v.cos_o > 0;
}
// Isotropic table: cosines straight from world vectors, no frame. cos phi (phi = phi_r -
// phi_i) is l.v minus the product of the normal components, over sin(theta_i) sin(theta_r);
// at a pole (product 0) phi is undefined and the table's pole rows do not depend on it.
// False when the light or the viewer is below the surface.
bool table_cosines(const FinishView& v, const Vec3& to_light, double* ci, double* cp) {
    if (!both_above(v, to_light, ci)) return false;
    const double ss = (1.0 - *ci * *ci) * v.sin2_o;
    *cp = ss > 0 ? (dot(to_light, v.to_eye) - *ci * v.cos_o) / std::sqrt(ss) : 1.0;
    return true;
}
}  // namespace

void finish_light_prefetch(FinishView* v, const Vec3& to_light) {
    const FinishModel& model = *v->model;
    v->pending.valid = false;
    FinishView::Pending& p = v->pending;
    if (model.halfdiff_table) {
        if (!both_above(*v, to_light, &p.cos_i)) return;
        model.halfdiff_table->prepare_halfdiff_dirs(v->n, to_light, v->to_eye, p.cos_i, v->cos_o, model.iso_interp, &p.hd);
        p.to_light = to_light;
        p.valid = true;
        return;
    }
    if (!model.iso_table) return;
    double cos_phi;
    if (!table_cosines(*v, to_light, &p.cos_i, &cos_phi)) return;
    model.iso_table->prepare_iso_cos(p.cos_i, v->theta_r, cos_phi, model.iso_interp, &p.read);
    p.to_light = to_light;
    p.valid = true;
}

// finish_light_weight without a prefetched light (finish.h: the prefetched one inline).
Rgb finish_light_weight_fresh(const FinishView& v, const Vec3& to_light, const Rgb& pigment) {
    const FinishModel& model = *v.model;
    if (model.halfdiff_table || model.iso_table) {
        Rgb f;
        double ci;
        if (model.halfdiff_table) {
            if (!both_above(v, to_light, &ci)) return Rgb(0.0);
            f = model.halfdiff_table->eval_halfdiff_dirs(v.n, to_light, v.to_eye, model.iso_interp);
        } else {
            double cp;
            if (!table_cosines(v, to_light, &ci, &cp)) return Rgb(0.0);
            f = model.iso_table->eval_iso_cos(ci, v.theta_r, cp, model.iso_interp);
        }
        return detail::table_light_weight(model, f, ci, pigment);
    }
    Rgb w = pov_weight(*model.brdf, v.wo, v.frame.to_local(to_light), v.brdf) * model.scale;
    return model.tint ? w * pigment : w;
}

Rgb finish_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Vec3& to_light,
                        const Rgb& pigment) {
    FinishView v;
    finish_view(model, n, to_eye, &v);
    return finish_light_weight(v, to_light, pigment);
}

Rgb finish_diffuse_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_light, const Rgb& pigment) {
    double c = dot(n, to_light);
    if (!(c > 0)) return Rgb(0.0);
    Rgb w = finish_model_albedo(model, c) * model.scale * c;
    return model.tint ? w * pigment : w;
}

Rgb finish_indirect_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment) {
    double c = dot(n, to_eye);
    if (!(c > 0)) return Rgb(0.0);
    Rgb w = (model.reflection_samples > 0 ? model.base : finish_model_albedo(model, c)) * model.scale;
    return model.tint ? w * pigment : w;
}

Rgb finish_glossy_albedo(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment) {
    double c = dot(n, to_eye);
    if (!(c > 0)) return Rgb(0.0);
    Rgb a = finish_model_albedo(model, c) - model.base;
    Rgb w = Rgb(std::max(0.0, a.r), std::max(0.0, a.g), std::max(0.0, a.b)) * model.scale;
    return model.tint ? w * pigment : w;
}

namespace {
// splitmix64 (Steele, Lea & Flood 2014): a bijective 64-bit mixer.
std::uint64_t mix64(std::uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}
std::uint64_t bits(double v) {
    std::uint64_t b;
    std::memcpy(&b, &v, sizeof b);
    return b;
}
double unit_double(std::uint64_t x) { return double(x >> 11) * 0x1.0p-53; }  // [0, 1)
}  // namespace

std::uint64_t finish_sample_seed(const Vec3& point, const Vec3& direction) {
    std::uint64_t h = 0;
    for (double v : {point.x, point.y, point.z, direction.x, direction.y, direction.z}) h = mix64(h ^ bits(v));
    return h;
}

bool finish_reflection_sample(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Rgb& pigment,
                              std::uint64_t seed, int k, Vec3* dir, Rgb* weight) {
    const int count = model.reflection_samples;
    if (count <= 0 || k < 0 || k >= count) return false;
    const Frame frame = model.brdf->anisotropic() ? Frame::from_normal_tangent(n, model.tangent)
                                                  : Frame::from_normal(n);
    const Vec3 wo = frame.to_local(to_eye);
    if (!(wo.z > 0)) return false;
    constexpr double kInvPhi = 0.6180339887498949;  // golden ratio - 1
    const double r1 = unit_double(mix64(seed)), r2 = unit_double(mix64(seed ^ 0x5851f42d4c957f2dull));
    double u1 = (k + 0.5) / count + r1, u2 = std::fmod(k * kInvPhi, 1.0) + r2;
    u1 = std::min(u1 - std::floor(u1), kOneMinusEps);
    u2 = std::min(u2 - std::floor(u2), kOneMinusEps);
    const Vec3 wi = model.brdf->sample_glossy(wo, u1, u2);
    if (!(wi.z > 0)) return false;
    const double pdf = model.brdf->pdf_glossy(wo, wi);
    if (!(pdf > 0) || !std::isfinite(pdf)) return false;
    Rgb f = model.brdf->f(wo, wi) - lambert_f(model.base);
    f = Rgb(std::max(0.0, f.r), std::max(0.0, f.g), std::max(0.0, f.b));  // rounding below the base
    Rgb w = f * (wi.z / (pdf * count)) * model.scale;
    *weight = model.tint ? w * pigment : w;
    *dir = frame.to_world(wi);
    return true;
}

Rgb finish_model_albedo(const FinishModel& model, double cos_theta) {
    if (!model.albedo) return Rgb(0.0);
    const std::vector<Rgb>& a = model.albedo_nodes();
    if (a.empty()) return Rgb(0.0);
    double x = std::acos(std::clamp(cos_theta, 0.0, 1.0)) / (kPi / 2) * double(a.size() - 1);
    std::size_t i = std::min(std::size_t(x), a.size() - 2);
    double t = x - double(i);
    return a[i] * (1.0 - t) + a[i + 1] * t;
}

namespace {

class TableView final : public Brdf {
public:
    TableView(std::shared_ptr<const BrdfTable> t, Interp i) : table_(std::move(t)), interp_(i) {}
    Rgb f(const Vec3& wo, const Vec3& wi) const override { return table_->f(wo, wi, interp_); }
    bool anisotropic() const override { return table_->anisotropic(); }
    // The table's own sampler (built once per table, whatever the interpolation: it covers
    // every cell where either lookup is positive).
    Vec3 sample(const Vec3& wo, double u1, double u2) const override { return table_->sample(wo, u1, u2); }
    double pdf(const Vec3& wo, const Vec3& wi) const override { return table_->pdf(wo, wi); }
    std::string describe() const override { return table_->describe() + " interp=" + to_string(interp_); }
    const BrdfTable& table() const { return *table_; }
    Interp interpolation() const { return interp_; }

private:
    std::shared_ptr<const BrdfTable> table_;
    Interp interp_;
};

}  // namespace

BrdfPtr table_brdf(std::shared_ptr<const BrdfTable> table, Interp interp) {
    if (!table) throw std::invalid_argument("table_brdf: no table");
    return std::make_shared<TableView>(std::move(table), interp);
}

namespace {
std::shared_ptr<FinishModel> finish_model_around(std::shared_ptr<const AlbedoNodes> albedo) {
    auto m = std::make_shared<FinishModel>();
    m->brdf = albedo->brdf();
    m->base = m->brdf->lambert_base();
    const BrdfTable* table = albedo->table();
    if (table) m->iso_interp = albedo->interpolation();
    if (table && table->halfdiff())
        m->halfdiff_table = table;
    else if (table && !table->anisotropic())
        m->iso_table = table;
    m->albedo = std::move(albedo);
    return m;
}
}  // namespace

AlbedoNodes::AlbedoNodes(BrdfPtr brdf, std::shared_ptr<const BrdfTable> table, Interp interp)
    : brdf_(std::move(brdf)), table_(std::move(table)), interp_(interp) {
    if (!brdf_) throw std::invalid_argument("AlbedoNodes: no BRDF");
}

const std::vector<Rgb>& AlbedoNodes::get() const {
    std::call_once(once_, [this] {
        const BrdfTable* table = table_.get();
        std::vector<Rgb> nodes(FinishModel::kAlbedoNodes);
        for (int k = 0; k < FinishModel::kAlbedoNodes; ++k) {
            // The grazing node itself is degenerate (wo in the surface); use 89.9 deg there.
            double th = std::min(k * (kPi / 2) / (FinishModel::kAlbedoNodes - 1), 89.9 * kPi / 180);
            nodes[k] = table ? table->directional_albedo(th) : quadrature_albedo(*brdf_, th);
        }
        nodes_ = std::move(nodes);
        done_.store(true, std::memory_order_release);
    });
    return nodes_;
}

std::shared_ptr<FinishModel> make_finish_model(BrdfPtr brdf) {
    if (!brdf) throw std::invalid_argument("make_finish_model: no BRDF");
    return finish_model_around(std::make_shared<const AlbedoNodes>(std::move(brdf)));
}

std::shared_ptr<FinishModel> make_finish_model(std::shared_ptr<const BrdfTable> table, Interp interp) {
    if (!table) throw std::invalid_argument("make_finish_model: no table");
    BrdfPtr view = table_brdf(table, interp);
    return finish_model_around(std::make_shared<const AlbedoNodes>(std::move(view), std::move(table), interp));
}

std::shared_ptr<FinishModel> finish_model_with_subsurface(const FinishModel* coat, std::shared_ptr<const Subsurface> s) {
    // the coat's own BRDF, without the dipole an earlier `dipole { }` of the finish put under it
    const BrdfPtr coat_brdf = !coat ? nullptr : coat->has_subsurface() ? coat->coat : coat->brdf;
    auto m = make_finish_model(std::make_shared<DipoleSurfaceBrdf>(s, coat_brdf));
    if (coat) {
        m->scale = coat->scale;
        m->tint = coat->tint;
        m->tangent = coat->tangent;
        m->reflection_samples = coat->reflection_samples;
    }
    m->transmittance = std::make_shared<const ModelHandle>(
        finish_model_register(make_finish_model(std::make_shared<TransmittanceBrdf>(s->model_ptr()))));
    m->subsurface = std::move(s);
    m->coat = coat_brdf;
    return m;
}

std::shared_ptr<FinishModel> finish_model_with_coat(const FinishModel& dipole, const FinishModel* coat) {
    std::shared_ptr<FinishModel> m = finish_model_with_subsurface(coat, dipole.subsurface);
    m->notes = dipole.notes;
    return m;
}

ModelHandle::~ModelHandle() { finish_model_release(handle_); }

int FinishModel::transmittance_handle() const { return transmittance ? transmittance->get() : 0; }

std::shared_ptr<FinishModel> make_finish_model_from_spec(const std::string& spec) {
    // The BRDF and its (lazy) albedo, shared while some finish uses them.
    static std::mutex mutex;
    static std::map<std::string, std::weak_ptr<const AlbedoNodes>> cache;
    {
        std::lock_guard<std::mutex> lock(mutex);
        auto it = cache.find(spec);
        if (it != cache.end())
            if (auto albedo = it->second.lock()) return finish_model_around(std::move(albedo));
    }
    std::shared_ptr<FinishModel> m = make_finish_model(make_brdf(spec));  // may throw: caches nothing
    std::lock_guard<std::mutex> lock(mutex);
    cache[spec] = m->albedo;
    return m;
}

// ---------------------------------------------------------------- shared tables

namespace {

struct TableCache {
    std::mutex mutex;
    std::map<std::string, std::weak_ptr<const BrdfTable>> tables;
    SharedTableStats stats;
};

TableCache& table_cache() {
    static TableCache c;
    return c;
}

}  // namespace

std::shared_ptr<const BrdfTable> shared_table(const std::string& key,
                                              const std::function<std::unique_ptr<BrdfTable>()>& load) {
    TableCache& c = table_cache();
    {
        std::lock_guard<std::mutex> lock(c.mutex);
        auto it = c.tables.find(key);
        if (it != c.tables.end()) {
            if (auto t = it->second.lock()) {
                ++c.stats.reuses;
                return t;
            }
        }
    }
    // Load outside the lock (it reads a file); a concurrent load of the same key keeps the first.
    std::unique_ptr<BrdfTable> fresh = load();
    if (!fresh) throw std::invalid_argument("shared_table: loader returned no table for " + key);
    const std::size_t bytes = fresh->bytes_used();
    std::lock_guard<std::mutex> lock(c.mutex);
    auto& slot = c.tables[key];
    if (auto t = slot.lock()) {
        ++c.stats.reuses;
        return t;
    }
    // The deleter keeps the statistics true when the last finish lets go.
    std::shared_ptr<const BrdfTable> t(fresh.release(), [bytes](const BrdfTable* p) {
        delete p;
        TableCache& cc = table_cache();
        std::lock_guard<std::mutex> l(cc.mutex);
        --cc.stats.live_tables;
        cc.stats.live_bytes -= bytes;
    });
    slot = t;
    ++c.stats.loads;
    ++c.stats.live_tables;
    c.stats.live_bytes += bytes;
    c.stats.peak_tables = std::max(c.stats.peak_tables, c.stats.live_tables);
    c.stats.peak_bytes = std::max(c.stats.peak_bytes, c.stats.live_bytes);
    return t;
}

SharedTableStats shared_table_stats() {
    TableCache& c = table_cache();
    SharedTableStats s;
    {
        std::lock_guard<std::mutex> lock(c.mutex);
        s = c.stats;
    }
    const TableSampler::Memory m = TableSampler::memory();
    s.sampler_bytes = m.live;
    s.peak_sampler_bytes = m.peak;
    return s;
}

}  // namespace shading
