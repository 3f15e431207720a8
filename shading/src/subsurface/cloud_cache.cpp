// CloudCache: per-object clouds, built cooperatively, read lock-free; see cloud_cache.h.
//
// Lookups read an immutable sorted index (key -> entry) through one atomic pointer and the
// entry's `ready` pointer: no lock once a cloud exists. A new key copies the index under the
// mutex and publishes the copy; old copies stay alive until the cache goes (a reader may
// still be looking at one). Building: the first thread to ask is the leader and runs the
// sampling; it hands each parallel stage (lines, irradiance) to every thread that asks for the
// same cloud meanwhile: they take chunks of the stage with their own sampler until it is done
// and return when the cloud is.

#include "shading/subsurface/cloud_cache.h"

#include <algorithm>
#include <condition_variable>
#include <exception>

namespace shading {

namespace {

using Task = std::function<void(std::size_t, SurfaceSampler&)>;

struct Stage {
    Stage(std::size_t n_, const Task& f) : n(n_), fn(f) {}
    std::size_t n;
    Task fn;
    std::atomic<std::size_t> next{0};
    std::size_t done = 0;       // guarded by the entry's mutex
    std::exception_ptr error;   // the same
};

}  // namespace

struct CloudCache::Entry {
    const void* key = nullptr;
    std::atomic<const PointCloud*> ready{nullptr};
    std::shared_ptr<const PointCloud> cloud;
    std::mutex m;
    std::condition_variable cv;
    bool started = false, finished = false;
    std::exception_ptr error;
    std::shared_ptr<Stage> stage;
    std::uint64_t generation = 0;

    // Take chunks of `st` until none is left.
    void work(Stage& st, SurfaceSampler& sampler) {
        const std::size_t chunk = std::max<std::size_t>(1, std::min<std::size_t>(256, st.n / 64));
        for (;;) {
            const std::size_t i0 = st.next.fetch_add(chunk);
            if (i0 >= st.n) return;
            const std::size_t i1 = std::min(st.n, i0 + chunk);
            std::exception_ptr err;
            for (std::size_t i = i0; i < i1; ++i) {
                try {
                    st.fn(i, sampler);
                } catch (...) {
                    if (!err) err = std::current_exception();
                }
            }
            std::lock_guard<std::mutex> lock(m);
            if (err && !st.error) st.error = err;
            st.done += i1 - i0;
            if (st.done == st.n) cv.notify_all();
        }
    }
};

struct CloudCache::Index {
    std::vector<std::pair<const void*, Entry*>> sorted;
    Entry* find(const void* key) const {
        auto it = std::lower_bound(sorted.begin(), sorted.end(), key,
                                   [](const std::pair<const void*, Entry*>& a, const void* k) { return std::less<const void*>()(a.first, k); });
        return it != sorted.end() && it->first == key ? it->second : nullptr;
    }
};

CloudCache::CloudCache() = default;
CloudCache::~CloudCache() = default;

const PointCloud& CloudCache::get(const void* key, SurfaceSampler& sampler, const Build& build) const {
    if (const Index* ix = index_.load(std::memory_order_acquire))
        if (Entry* e = ix->find(key))
            if (const PointCloud* c = e->ready.load(std::memory_order_acquire)) return *c;

    Entry* e = nullptr;
    bool leader = false;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        const Index* ix = index_.load(std::memory_order_relaxed);
        e = ix ? ix->find(key) : nullptr;
        if (!e) {
            entries_.push_back(std::make_unique<Entry>());
            e = entries_.back().get();
            e->key = key;
            auto next = std::make_unique<Index>();
            if (ix) next->sorted = ix->sorted;
            next->sorted.emplace_back(key, e);
            std::sort(next->sorted.begin(), next->sorted.end(),
                      [](const std::pair<const void*, Entry*>& a, const std::pair<const void*, Entry*>& b) {
                          return std::less<const void*>()(a.first, b.first);
                      });
            index_.store(next.get(), std::memory_order_release);
            indexes_.push_back(std::move(next));
        }
    }
    {
        std::lock_guard<std::mutex> lock(e->m);
        if (!e->started) {
            e->started = true;
            leader = true;
        }
    }
    if (leader) {
        std::shared_ptr<const PointCloud> cloud;
        std::exception_ptr error;
        // Each parallel stage is published to the threads waiting for this cloud, worked on
        // here too, and waited for.
        const ParallelFor parallel = [e, &sampler](std::size_t n, const Task& task) {
            if (n == 0) return;
            auto st = std::make_shared<Stage>(n, task);
            {
                std::lock_guard<std::mutex> lock(e->m);
                e->stage = st;
                ++e->generation;
            }
            e->cv.notify_all();
            e->work(*st, sampler);
            std::unique_lock<std::mutex> lock(e->m);
            e->cv.wait(lock, [&] { return st->done == st->n; });
            e->stage.reset();
            if (st->error) std::rethrow_exception(st->error);
        };
        try {
            cloud = build(parallel, sampler);
        } catch (...) {
            error = std::current_exception();
        }
        {
            std::lock_guard<std::mutex> lock(e->m);
            e->cloud = cloud;
            e->error = error;
            e->finished = true;
            if (cloud) e->ready.store(cloud.get(), std::memory_order_release);
        }
        e->cv.notify_all();
        if (error) std::rethrow_exception(error);
        return *cloud;
    }
    // A helper: work on whatever stage the leader publishes until the cloud is done.
    std::unique_lock<std::mutex> lock(e->m);
    std::uint64_t seen = 0;
    while (!e->finished) {
        if (e->stage && e->generation != seen) {
            seen = e->generation;
            std::shared_ptr<Stage> st = e->stage;
            lock.unlock();
            e->work(*st, sampler);
            lock.lock();
            continue;
        }
        e->cv.wait(lock);
    }
    if (e->error) std::rethrow_exception(e->error);
    return *e->cloud;
}

}  // namespace shading
