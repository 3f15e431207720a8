#include "shading/finish.h"

#include <array>
#include <atomic>
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
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    Slot* s = r.slot(handle);
    if (!s || s->refs <= 0) return;
    if (--s->refs == 0) {
        s->model.store(nullptr, std::memory_order_release);
        s->owner.reset();
        r.free_handles.push_back(handle);
        --r.live;
    }
}

const FinishModel* finish_model_get(int handle) {
    Slot* s = registry().slot(handle);
    return s ? s->model.load(std::memory_order_acquire) : nullptr;
}

std::size_t finish_model_live_count() {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    return r.live;
}

Rgb finish_light_weight(const FinishModel& model, const Vec3& n, const Vec3& to_eye, const Vec3& to_light,
                        const Rgb& pigment) {
    const Frame frame = model.brdf->anisotropic() ? Frame::from_normal_tangent(n, model.tangent)
                                                  : Frame::from_normal(n);
    Rgb w = pov_weight(*model.brdf, frame.to_local(to_eye), frame.to_local(to_light)) * model.scale;
    return model.tint ? w * pigment : w;
}

}  // namespace shading
