// Crossings of a line kept by their depth: what a sampler's segment_hits returns when the
// renderer can only give the whole line (SurfaceSampler, DipoleObject: the two layers' twins).
#pragma once

#include <cstddef>
#include <vector>

namespace shading {

// Removes, from (*hits)[first] on, every crossing whose depth `t` is outside [t0, t1] (NaN
// included); the rest keep their order.
template <class Hit>
void keep_depths_within(std::vector<Hit>* hits, std::size_t first, double t0, double t1) {
    std::size_t kept = first;
    for (std::size_t k = first; k < hits->size(); ++k)
        if ((*hits)[k].t >= t0 && (*hits)[k].t <= t1) (*hits)[kept++] = (*hits)[k];
    hits->resize(kept);
}

}  // namespace shading
