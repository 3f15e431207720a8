// A flat triangle with vertex normals (POV's smooth_triangle, a smooth mesh's triangles) stands
// for a curved surface: its shading normal is interpolated, its geometry is not. Light tested
// from the flat facet near the terminator is shadowed by the neighbouring facets, in jags the
// size of a facet (a plain `diffuse 1` render shows them). smooth_facet_point moves a point of
// the facet onto (or just above) the curved surface the normals describe, from where such a
// test sees what the smooth surface would. The construction is Hanika's (2021, "Hacking the
// shadow terminator", Ray Tracing Gems II, chapter 4).
#pragma once

#include <cmath>

#include "shading/core/vec.h"

namespace shading {

// p, on the facet with vertices v[0..2] and vertex normals n[0..2], moved out of the underside of
// each vertex's tangent plane (the plane through v[i] normal to n[i]) by p's barycentric
// weight of that vertex: p + sum_i b_i max(0, -(p - v_i) . n_i) n_i. The normals are taken on
// the side of `outward` (the surface's outward normal at p) and need not be unit. Where p lies
// on or above every tangent plane (a flat facet, or one on a concave part) it does not move; a
// vertex does not move. On a facet of a sphere with its exact normals every point lands on the
// sphere or outside it by up to the facet's depth inside it (SmoothFacet tests). A degenerate
// facet, a zero normal or any non-finite input returns p.
inline Vec3 smooth_facet_point(const Vec3& p, const Vec3 v[3], const Vec3 n[3], const Vec3& outward) {
    const Vec3 e1 = v[1] - v[0], e2 = v[2] - v[0], f = p - v[0];
    const double d00 = dot(e1, e1), d01 = dot(e1, e2), d11 = dot(e2, e2), d20 = dot(f, e1), d21 = dot(f, e2);
    const double den = d00 * d11 - d01 * d01;
    if (!(den > 1e-300) || !std::isfinite(den)) return p;
    double b[3];
    b[1] = (d11 * d20 - d01 * d21) / den;
    b[2] = (d00 * d21 - d01 * d20) / den;
    b[0] = 1.0 - b[1] - b[2];
    // p is on the facet up to rounding: weights clamped to [0, 1] and renormalised
    double sum = 0;
    for (double& w : b) sum += (w = std::min(1.0, std::max(0.0, w)));
    if (!(sum > 0) || !std::isfinite(sum)) return p;
    Vec3 lifted = p;
    for (int i = 0; i < 3; ++i) {
        const double len = length(n[i]);
        if (!(len > 0) || !std::isfinite(len)) return p;
        Vec3 u = n[i] * (1.0 / len);
        if (dot(u, outward) < 0) u = -u;
        const double below = -dot(p - v[i], u);
        if (below > 0) lifted = lifted + u * (b[i] / sum * below);
    }
    return lifted;
}

}  // namespace shading
