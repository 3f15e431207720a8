// What the subsurface finishes did, for POV's statistics: counters over the whole process (all
// subsurface finishes) and the warnings about single objects.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "shading/core/vec.h"

namespace shading {

struct SubsurfaceStats {
    std::size_t clouds = 0, points = 0, lookups = 0, nodes_visited = 0;
    double build_seconds = 0;
    std::size_t refined_points = 0;
    std::size_t edge_means = 0;  // samples at an edge of the light that took their cell's mean E_t
    int max_levels = 0;
    double finest_spacing = 0;  // smallest spacing reached in any cloud (scene units), 0: none
    std::size_t unbounded = 0;  // objects that could not be sampled (no finite bounding box)
    std::size_t thin = 0;       // thin geometry off: objects thinner than the mean free path in > 10 % of places
    // Thin geometry on: objects thinner than their finish's slab threshold somewhere, the
    // thinnest sample found (scene units and transport mean free paths), lookups that used
    // slab profiles.
    std::size_t slab_objects = 0, slab_lookups = 0;
    // Lookups at a lit point with no lit sample within 8 spacings of it (a lit area smaller than
    // the sample spacing: Subsurface::radiance), the largest such spacing (scene units) and the
    // least such point (by x, then y, then z: the same for any thread count).
    std::size_t unresolved_lookups = 0;
    double unresolved_spacing = 0;
    Vec3 unresolved_at;
    double thinnest = 0, thinnest_mfp = 0;  // 0: none
    std::vector<std::string> notes;  // per-object warnings (small objects), sorted
};
SubsurfaceStats subsurface_stats();

// ---------------------------------------------------------------------------------------------
// Recording (Subsurface).

// What building one object's cloud adds.
struct CloudRecord {
    std::size_t points = 0, refined = 0, edge_means = 0;
    int levels = 0;               // refinement levels used
    double finest_spacing = 0;    // the cloud's finest spacing (counted where levels > 0)
    bool unbounded = false;       // no finite bounding box
    bool thin = false;            // thin geometry off, and thinner than the mean free path in places
    bool slab_object = false;     // thinner than its finish's slab threshold somewhere
    double thinnest = 0, thinnest_mfp = 0;  // of a slab object: its thinnest sample (scene units, mfp')
    std::string note;             // a warning about this object ("" if none)
    std::string finish_note;      // a warning about its finish, said once ("" if none)
    std::int64_t build_ns = 0;
};
void record_cloud(const CloudRecord& r);
// One lookup (Subsurface::radiance): octree nodes opened, and whether it used slab profiles.
// Counted per thread, without a lock or a shared cache line.
void count_lookup(std::size_t visited, bool slab);
// A lookup at a lit point x of spacing h that the cloud saw no light near (SubsurfaceStats;
// under a lock: such lookups are few, or the warning is due anyway).
void count_unresolved(double h, const Vec3& x);

// The warning about an object smaller than 3 diffusion lengths L (scene units; infinite without
// absorption): `object` as the renderer describes it, its bounding box's centre and largest
// side; a slab object names its thinnest sample.
std::string small_object_note(const std::string& object, const Vec3& centre, double extent, double L,
                              double mm_per_unit, bool slab_object, double thinnest);

}  // namespace shading
