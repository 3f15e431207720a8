// The point clouds of one subsurface finish, one per object, each built once while any number
// of render threads ask for it, and read without a lock once built.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "shading/subsurface/point_cloud.h"

namespace shading {

class CloudCache {
public:
    // Builds the cloud of one object: its parallel stages go through `parallel` (every thread
    // then waiting for this cloud works on them), the leader's own work through `sampler`.
    using Build = std::function<std::shared_ptr<const PointCloud>(const ParallelFor& parallel, SurfaceSampler& sampler)>;

    CloudCache();
    ~CloudCache();
    CloudCache(const CloudCache&) = delete;
    CloudCache& operator=(const CloudCache&) = delete;

    // The cloud of `key`, built by `build` through `sampler` the first time. Lock-free once
    // built. While it is being built, every thread that asks takes part (with its own sampler)
    // and returns when it is done; an error while building reaches every one of them. An empty
    // cloud is kept too.
    const PointCloud& get(const void* key, SurfaceSampler& sampler, const Build& build) const;

private:
    struct Entry;
    struct Index;
    mutable std::mutex mutex_;
    mutable std::vector<std::unique_ptr<Entry>> entries_;
    mutable std::vector<std::unique_ptr<const Index>> indexes_;  // every index published (readers may hold any)
    mutable std::atomic<const Index*> index_{nullptr};
};

}  // namespace shading
