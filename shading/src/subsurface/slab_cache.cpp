// SlabCache: slab profiles per thickness node, built once under a mutex, read through atomic
// pointers; see slab_cache.h.
#include "shading/subsurface/slab_cache.h"

#include <algorithm>
#include <cmath>

#include "shading/subsurface/rd_profile.h"

namespace shading {

namespace {

// Thickness nodes per octave; a lookup interpolates between the two around it. Linear in
// ln d at 8 per octave errs by ~(ln 2 / 8)^2 / 8 |f''| (f of ln d): for T ~ e^{-k d},
// 9.4e-4 (k d)^2 of T, below the 1.1 % k d of the nearest of 32 per octave wherever
// k d < 11 (a slab is thinner than that where T matters) -- and no steps.
constexpr double kPerOctave = 8;

}  // namespace

SlabCache::SlabCache(double d_min, double d_max, Make make)
    : d_min_(d_min),
      count_(std::size_t(std::ceil(kPerOctave * std::log2(d_max / d_min))) + 1),
      make_(std::move(make)),
      nodes_(new std::atomic<const Node*>[count_]),
      locks_(new std::mutex[count_]) {
    for (std::size_t k = 0; k < count_; ++k) nodes_[k].store(nullptr, std::memory_order_relaxed);
}

SlabCache::~SlabCache() {
    for (std::size_t k = 0; k < count_; ++k) delete nodes_[k].load();
}

const SlabCache::Node& SlabCache::at(std::size_t i) const {
    if (const Node* n = nodes_[i].load(std::memory_order_acquire)) return *n;
    std::lock_guard<std::mutex> lock(locks_[i]);
    if (const Node* n = nodes_[i].load(std::memory_order_acquire)) return *n;
    auto made = std::make_unique<Node>();
    made->p = make_(d_min_ * std::exp2(double(i) / kPerOctave));
    const Node* n = made.release();
    nodes_[i].store(n, std::memory_order_release);
    return *n;
}

const SlabCache::Node& SlabCache::node(double d) const {
    const double k = std::round(kPerOctave * std::log2(std::max(d, d_min_) / d_min_));
    return at(std::size_t(std::min(double(count_ - 1), std::max(0.0, k))));
}

SlabCache::Around SlabCache::around(double d) const {
    const double x = std::min(double(count_ - 1), std::max(0.0, kPerOctave * std::log2(std::max(d, d_min_) / d_min_)));
    const double k = std::floor(x);
    Around out;
    out.a = &at(std::size_t(k));
    out.t = x - k;
    if (out.t > 0) {
        out.b = &at(std::size_t(k) + 1);
    } else {
        out.t = 0;
    }
    return out;
}

SlabCache::Node::~Node() {
    for (const Near* n = near_list_.load(); n;) {
        const Near* next = n->next;
        delete n;
        n = next;
    }
}

void SlabCache::Node::near(double h, Rgb* same, Rgb* opposite) const {
    const Near* head = near_list_.load(std::memory_order_acquire);
    for (const Near* n = head; n; n = n->next)
        if (n->h == h) {
            *same = n->same;
            *opposite = n->opposite;
            return;
        }
    Near* made = new Near{h, p.same->near_reflectance(h), p.transmit->near_reflectance(h), head};
    // Another thread may have pushed meanwhile (maybe the same h: harmless, equal values).
    while (!near_list_.compare_exchange_weak(made->next, made, std::memory_order_acq_rel)) {
    }
    *same = made->same;
    *opposite = made->opposite;
}

}  // namespace shading
