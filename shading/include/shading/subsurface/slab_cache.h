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
    // Thickness nodes d_k = d_min 2^(k/8) (neighbours 9 % apart), k = 0 .. up to d_max; a
    // lookup interpolates linearly in ln d between the two nodes around its thickness.
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
    // The two nodes around d and the weight of the second, linear in ln d: a result at d is
    // (1 - t) x (a's) + t x (b's). Below d_min, or at a node: b is null and t 0.
    struct Around {
        const Node* a = nullptr;
        const Node* b = nullptr;
        double t = 0;
    };
    Around around(double d) const;

private:
    const Node& at(std::size_t i) const;  // node i, built on first use
    double d_min_;
    std::size_t count_;
    Make make_;
    std::unique_ptr<std::atomic<const Node*>[]> nodes_;
    std::unique_ptr<std::mutex[]> locks_;  // one per node: threads build different nodes at once
};

}  // namespace shading
