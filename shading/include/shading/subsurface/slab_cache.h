// The slab profiles of thin geometry (slab.h) for one subsurface finish, one set per
// thickness node, each built on first use and read without a lock after.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>

#include "shading/core/vec.h"
#include "shading/subsurface/slab.h"

namespace shading {

class SlabCache {
public:
    // The profiles of a slab of thickness d (scene units).
    using Make = std::function<SlabProfiles(double d)>;
    // Thickness nodes d_k = d_min 2^(k/32) (neighbours 2.2 % apart), k = 0 .. up to d_max.
    SlabCache(double d_min, double d_max, Make make);
    ~SlabCache();
    SlabCache(const SlabCache&) = delete;
    SlabCache& operator=(const SlabCache&) = delete;

    // One node: its profiles and, per lookup spacing h, their near reflectance.
    struct Node {
        SlabProfiles p;
        // near_reflectance(h) of R (same) and of T in rho (opposite), kept per h (a list that
        // only grows, pushed with compare-exchange: lookups read it without a lock).
        void near(double h, Rgb* same, Rgb* opposite) const;
        ~Node();

    private:
        struct Near {
            double h;
            Rgb same, opposite;
            const Near* next;
        };
        mutable std::atomic<const Near*> near_list_{nullptr};
    };
    // The node nearest to d in log d (d below d_min: the first).
    const Node& node(double d) const;

private:
    double d_min_;
    std::size_t count_;
    Make make_;
    std::unique_ptr<std::atomic<const Node*>[]> nodes_;
    mutable std::mutex mutex_;
};

}  // namespace shading
