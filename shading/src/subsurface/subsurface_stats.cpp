// The subsurface statistics: process-wide counters, the per-object warnings and their texts;
// see subsurface_stats.h.
#include "shading/subsurface/subsurface_stats.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <mutex>

#include "shading/core/format.h"

namespace shading {

namespace {

// Build counters change once per object; lookup counters once per shaded point, so each
// thread counts its lookups in a block of its own (no shared cache line, no atomic
// read-modify-write on the hot path) and subsurface_stats() adds the blocks up.
std::atomic<std::size_t> g_clouds{0}, g_points{0}, g_refined{0}, g_edge_means{0};
std::atomic<std::int64_t> g_build_ns{0};
std::atomic<std::size_t> g_unbounded{0}, g_thin{0}, g_slab_objects{0};
std::atomic<int> g_max_levels{0};

struct alignas(64) LookupCounter {
    std::atomic<std::uint64_t> lookups{0}, visited{0}, slab{0};
};

struct Notes {
    std::mutex mutex;
    std::vector<std::unique_ptr<LookupCounter>> counters;
    std::vector<std::string> notes;
    double finest = 0;
    double thinnest = 0, thinnest_mfp = 0;  // over the objects with slab lookups (0: none)
    // count_unresolved (rare: under the lock): count, largest spacing, least point (x, y, z)
    std::size_t unresolved = 0;
    double unresolved_h = 0;
    Vec3 unresolved_at;
};
Notes& notes() {
    static Notes n;
    return n;
}

LookupCounter& thread_counter() {
    thread_local LookupCounter* mine = nullptr;
    if (!mine) {
        Notes& n = notes();
        std::lock_guard<std::mutex> lock(n.mutex);
        n.counters.push_back(std::make_unique<LookupCounter>());
        mine = n.counters.back().get();
    }
    return *mine;
}

// Only this thread writes its counter: a relaxed load and store, no locked instruction.
void bump(std::atomic<std::uint64_t>& c, std::uint64_t by) {
    c.store(c.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
}

}  // namespace

SubsurfaceStats subsurface_stats() {
    SubsurfaceStats s;
    s.clouds = g_clouds.load();
    s.points = g_points.load();
    s.refined_points = g_refined.load();
    s.edge_means = g_edge_means.load();
    s.max_levels = g_max_levels.load();
    s.build_seconds = double(g_build_ns.load()) * 1e-9;
    s.unbounded = g_unbounded.load();
    s.thin = g_thin.load();
    Notes& n = notes();
    std::lock_guard<std::mutex> lock(n.mutex);
    for (const auto& c : n.counters) {
        s.lookups += c->lookups.load(std::memory_order_relaxed);
        s.nodes_visited += c->visited.load(std::memory_order_relaxed);
        s.slab_lookups += c->slab.load(std::memory_order_relaxed);
    }
    s.unresolved_lookups = n.unresolved;
    s.unresolved_spacing = n.unresolved_h;
    s.unresolved_at = n.unresolved_at;
    s.slab_objects = g_slab_objects.load();
    s.thinnest = n.thinnest;
    s.thinnest_mfp = n.thinnest_mfp;
    s.notes = n.notes;
    std::sort(s.notes.begin(), s.notes.end());
    s.finest_spacing = n.finest;
    return s;
}

void record_cloud(const CloudRecord& r) {
    g_clouds += 1;
    g_points += r.points;
    g_refined += r.refined;
    g_edge_means += r.edge_means;
    if (r.unbounded) ++g_unbounded;
    if (r.slab_object) ++g_slab_objects;
    else if (r.thin) ++g_thin;
    int seen = g_max_levels.load();
    while (r.levels > seen && !g_max_levels.compare_exchange_weak(seen, r.levels)) {
    }
    {
        Notes& n = notes();
        std::lock_guard<std::mutex> lock(n.mutex);
        if (!r.note.empty()) n.notes.push_back(r.note);
        if (!r.finish_note.empty() && std::find(n.notes.begin(), n.notes.end(), r.finish_note) == n.notes.end())
            n.notes.push_back(r.finish_note);
        if (r.levels > 0 && (n.finest == 0 || r.finest_spacing < n.finest)) n.finest = r.finest_spacing;
        if (r.slab_object && (n.thinnest == 0 || r.thinnest < n.thinnest)) {
            n.thinnest = r.thinnest;
            n.thinnest_mfp = r.thinnest_mfp;
        }
    }
    g_build_ns += r.build_ns;
}

void count_lookup(std::size_t visited, bool slab) {
    LookupCounter& c = thread_counter();
    bump(c.lookups, 1);
    bump(c.visited, visited);
    if (slab) bump(c.slab, 1);
}

void count_unresolved(double h, const Vec3& x) {
    Notes& n = notes();
    std::lock_guard<std::mutex> lock(n.mutex);
    // the least point, so that the warning names the same one whatever the threads' order
    const bool less = x.x < n.unresolved_at.x ||
                      (x.x == n.unresolved_at.x && (x.y < n.unresolved_at.y || (x.y == n.unresolved_at.y && x.z < n.unresolved_at.z)));
    if (n.unresolved == 0 || less) n.unresolved_at = x;
    n.unresolved_h = std::max(n.unresolved_h, h);
    ++n.unresolved;
}

std::string small_object_note(const std::string& object, const Vec3& centre, double extent, double L,
                              double mm_per_unit, bool slab_object, double thinnest) {
    auto fmt3 = [](double v) { return detail::fmt(v, 3); };
    // (POV wraps statistics at 80 columns: the lines are broken here, indented)
    return "Dipole warning: " + object + " at <" + fmt3(centre.x) + ", " + fmt3(centre.y) + ", " + fmt3(centre.z) +
           "> (extent " + fmt3(extent) + " units)\n  is smaller than 3 diffusion lengths (" +
           (std::isfinite(L) ? "1/sigma_tr = " + fmt3(L * mm_per_unit) + " mm = " + fmt3(L) + " units\n  at mm_per_unit " +
                                   fmt3(mm_per_unit)
                             : "no absorption: unbounded") +
           (slab_object ? "): light through it follows slab profiles\n  (thinnest " + fmt3(thinnest) + " units)"
                        : "): light that would glow through it is lost");
}

}  // namespace shading
