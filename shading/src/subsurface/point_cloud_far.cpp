// The far field of a lookup: the octree's sum of Rd(r) A E_t over the samples, aggregated
// where a node is small as seen from x (point_cloud.h far_exitance, far_exitance_sided), and
// the exact sums the tests hold it against.
#include "shading/subsurface/point_cloud.h"

#include <algorithm>
#include <cmath>

namespace shading {

namespace {

// The profile averaged over an aggregate's points, to second order: f(|x - p|) ~ f(d) +
// (1/2) tr(H Sigma), H the Hessian in p: f'' u u^T + (f'/d)(I - u u^T), u = (c - x)/d (f', f''
// tabulated with f), Sigma the points' covariance `cov` (xx yy zz xy xz yz); v = c - x, dc2 =
// |v|^2. Times the aggregate's flux, never below 0 (the expansion can undershoot where Rd ~ 0),
// and the weight at the centre's distance (optional).
Rgb aggregate_exitance(const RdProfile& rd, const double* C, const Rgb& flux, const Vec3& v, double dc2,
                       const RadialWeight* weight) {
    const double dc = std::sqrt(dc2), inv = 1.0 / dc;
    const Vec3 u = v * inv;
    const double uCu = u.x * (C[0] * u.x + C[3] * u.y + C[4] * u.z) +
                       u.y * (C[3] * u.x + C[1] * u.y + C[5] * u.z) +
                       u.z * (C[4] * u.x + C[5] * u.y + C[2] * u.z);
    const double a = 0.5 * uCu, b = 0.5 * (C[0] + C[1] + C[2] - uCu) * inv;
    Rgb f0, f1, f2;
    rd.eval(dc, &f0, &f1, &f2);
    Rgb out;
    out.r = std::max(0.0, f0.r + a * f2.r + b * f1.r) * flux.r;
    out.g = std::max(0.0, f0.g + a * f2.g + b * f1.g) * flux.g;
    out.b = std::max(0.0, f0.b + a * f2.b + b * f1.b) * flux.b;
    return weight ? out * weight->at(dc) : out;
}

}  // namespace

Rgb PointCloud::far_exitance(const RdProfile& rd, const Vec3& x, double r0, double h, double max_angle,
                             double cutoff, std::size_t* visited, const RadialWeight* weight) const {
    return far_sum<false>(rd, nullptr, x, Vec3(), 0.0, r0, h, max_angle, cutoff * cutoff, Rgb(0.0), visited, nullptr,
                          weight);
}

Rgb PointCloud::far_exitance_sided(const RdProfile& same, const RdProfile& transmit, const Vec3& x, const Vec3& nx,
                                   double d, double r0, double h, double max_angle, const Rgb& near_opposite,
                                   std::size_t* visited, Rgb* opposite, const RadialWeight* weight,
                                   const SecondProfiles* second) const {
    const double cut = second ? std::max(same.r_max(), second->same->r_max()) : same.r_max();
    return far_sum<true>(same, &transmit, x, nx, d, r0, h, max_angle, sqr(cut), near_opposite, visited, opposite,
                         weight, second);
}

Rgb PointCloud::far_exitance_exact(const RdProfile& rd, const Vec3& x, double r0, double h,
                                   const RadialWeight* weight) const {
    return exact_sum<false>(rd, nullptr, x, Vec3(), 0.0, r0, h, Rgb(0.0), weight);
}

Rgb PointCloud::far_exitance_sided_exact(const RdProfile& same, const RdProfile& transmit, const Vec3& x,
                                         const Vec3& nx, double d, double r0, double h, const Rgb& near_opposite) const {
    return exact_sum<true>(same, &transmit, x, nx, d, r0, h, near_opposite, nullptr);
}

namespace {

// The window's near part over a plane: the integral of (1 - w) over the disc about x (w:
// far_window, 0 inside r0 - h, a quintic ramp to 1 at r0 + h): pi a^2 + 2 pi h a + (8/7) pi h^2,
// a = r0 - h. The opposite face's near field lights the part of T inside the window by its
// points' mean irradiance there, taken over this area where the points cover less of it (the
// window reaching past a sheet's edge, or over its shadow: unlit nodes are not visited): over
// the points' own area alone, a back-lit sheet read its full light up to its edge, where half
// the window is no sheet (a comb of steps 1-2 spacings inside the edge, +25 % at it).
double near_disc_area(double r0, double h) {
    const double a = std::max(0.0, r0 - h);
    return kPi * (a * a + 2.0 * h * a + (8.0 / 7.0) * h * h);
}

}  // namespace

template <bool kSided>
Rgb PointCloud::far_sum(const RdProfile& same, const RdProfile* transmit, const Vec3& x, const Vec3& nx, double d,
                        double r0, double h, double max_angle, double cut_same2, const Rgb& near_opposite,
                        std::size_t* visited, Rgb* opposite, const RadialWeight* weight,
                        const SecondProfiles* second) const {
    Rgb sum, opp_sum;  // the opposite face's part of sum (added to both: sum's order as before)
    Rgb sum2, opp_sum2;  // the same for `second` (kSided only)
    if (opposite) *opposite = Rgb(0.0);
    if (kSided && second) *second->result = *second->opposite = Rgb(0.0);
    if (nodes_.empty()) return sum;
    const double inner2 = sqr(std::max(0.0, r0 - h)), outer = r0 + h, outer2 = outer * outer;
    const double d2 = d * d;
    const double cut_t = !kSided ? 0.0 : second ? std::max(transmit->r_max(), second->transmit->r_max()) : transmit->r_max();
    // rho >= sqrt(s^2 - d^2): nothing of T beyond s^2 = r_max^2 + d^2
    const double cut_opp2 = cut_t * cut_t + d2;
    const double cut2 = kSided ? std::max(cut_same2, cut_opp2) : cut_same2;
    const double angle2 = max_angle * max_angle;
    // widened angles (RdProfile::angle_gain2) stay below 1: the expansion's limit
    const double gain_cap = std::max(1.0, 1.0 / angle2);
    constexpr double kHalfPi = 0.5 * kPi;
    // The lateral distance of p from x for the transmission profile: rho^2 = s^2 - min(v.nx, d)^2
    // (v = x - p): a flat slab's sqrt(s^2 - d^2) on its opposite face, the distance across
    // x's normal line where the far side is closer than d (a curved object), and never below
    // the lateral distance, which moves by at most |p - q| between points p, q.
    auto rho_of = [&](const Vec3& p) {
        const Vec3 v = x - p;
        const double vn = std::min(std::fabs(dot(v, nx)), d);
        return std::sqrt(std::max(0.0, dot(v, v) - vn * vn));
    };
    // The opposite face's near field: inside the window (in rho) its points only give their
    // irradiance to a (1 - w)-weighted mean, which lights the part of T inside the window
    // (near_opposite, integrated, not sampled: T's peak is as narrow as the slab and would
    // fall between samples).
    double near_area = 0;
    Rgb near_flux;
    std::size_t opened = 0;
    // Stack entries: node, side (0: not known yet, 1: every normal on nx's side, 2: every
    // normal on the other side; a side, once known, holds for the subtree). Without sides
    // every node is on x's side.
    int stack[8 * kMaxDepth + 16];
    std::uint8_t sides[8 * kMaxDepth + 16];
    int top = 0;
    stack[top] = 0;
    sides[top++] = kSided ? 0 : 1;
    auto add_point = [&](int i, bool opp) {
        const Leaf& s = leaves_[i];
        const Vec3 v = x - s.p;
        const double r2 = dot(v, v);
        if (opp) {
            if (r2 > cut_opp2) return;
            const double rho = rho_of(s.p);
            double w = 1.0;
            if (rho < outer) {
                w = rho * rho <= inner2 ? 0.0 : window(rho, r0, h);
                near_area += (1.0 - w) * points_[i].area;
                near_flux += s.flux * (1.0 - w);
            }
            if (w > 0) {
                const Rgb t = transmit->rd(rho) * s.flux * w;
                sum += t;
                opp_sum += t;
                if (kSided && second) {
                    const Rgb t2 = second->transmit->rd(rho) * s.flux * w;
                    sum2 += t2;
                    opp_sum2 += t2;
                }
            }
            return;
        }
        // w = 0 inside the ramp's start: no square root, no profile
        if (r2 <= inner2 || r2 > cut_same2) return;
        const double r = std::sqrt(r2);
        const double w = r2 >= outer2 ? 1.0 : window(r, r0, h);
        const Rgb e = same.rd(r) * s.flux * w;
        if (!weight) {
            sum += e;
            if (kSided && second) sum2 += second->same->rd(r) * s.flux * w;
            return;
        }
        const Rgb wr = weight->at(r);
        sum += e * wr;
        if (kSided && second) sum2 += second->same->rd(r) * s.flux * w * wr;
    };
    while (top > 0) {
        --top;
        const int k = stack[top];
        int side = kSided ? sides[top] : 1;
        const Node& nd = nodes_[k];
        ++opened;
        // Unlit nodes (shadowed, facing away from every light) bring nothing.
        if (!nd.lit) continue;
        const double dbox2 = box_distance2(x, nd.lo, nd.hi);
        if (dbox2 > cut2) continue;
        // The side an aggregate of this node takes: `side` where known; else, for a node of
        // one sheet (its normals within 90 degrees of its axis: a curved surface crossing the
        // plane of nx, e.g. the rim of a sphere seen from x), its axis's side (its points on
        // the other side are few, at the seam of the two profiles); a node whose normals
        // spread wider (both faces of a sheet) has none and is opened.
        int agg_side = side;
        if (kSided && side == 0) {
            // The cone's axis at angle phi from nx, half-angle c: every normal has dot > 0 with
            // nx when phi + c < pi/2, dot < 0 when phi - c > pi/2.
            const Cone& cc = cones_[k];
            const double phi = std::acos(std::max(-1.0, std::min(1.0, cc.axis_cos(nx))));
            if (phi + cc.angle < kHalfPi) side = 1;
            else if (phi - cc.angle > kHalfPi) side = 2;
            agg_side = side != 0 ? side : (cc.angle < kHalfPi ? (phi < kHalfPi ? 1 : 2) : 0);
        }
        if (kSided && side == 1 && dbox2 > cut_same2) continue;
        if (kSided && side == 2 && dbox2 > cut_opp2) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const bool opp = kSided && (side == 2 || (side == 0 && !(dot(points_[i].n, nx) > 0)));
                add_point(i, opp);
            }
            continue;
        }
        if (agg_side == 1 && dbox2 > outer2) {
            // Aggregate only nodes wholly beyond the window's ramp (w = 1 for all their points):
            // Rd at the centre plus (1/2) tr(H Sigma).
            const Agg& g = aggs_[k];
            const Vec3 v = g.centre - x;
            const double dc2 = dot(v, v);
            double gain = same.angle_gain2(dc2);
            if (kSided && second) gain = std::min(gain, second->same->angle_gain2(dc2));
            if (double(nd.diag2) < angle2 * std::min(gain, gain_cap) * dc2) {
                const Rgb e = aggregate_exitance(same, g.cov, g.flux, v, dc2, weight);
                sum.r += e.r;
                sum.g += e.g;
                sum.b += e.b;
                if (kSided && second) sum2 += aggregate_exitance(*second->same, g.cov, g.flux, v, dc2, weight);
                continue;
            }
        } else if (kSided && agg_side == 2) {
            // T at the centre's rho plus the second-order term of its expansion in the plane
            // across nx (exact geometry for a flat slab, where rho is the in-plane distance):
            // (1/2) tr(H Sigma_p), H = T'' u u^T + (T'/rho)(I - u u^T) in that plane, Sigma_p
            // the covariance projected onto it, u the in-plane direction to the centre. For a
            // node wholly beyond the window in rho (rho of any of its points >= the centre's -
            // the diagonal) and small as seen from x.
            const Agg& g = aggs_[k];
            const Vec3 v = g.centre - x;
            const double dc2 = dot(v, v), diag = std::sqrt(double(nd.diag2));
            const double rho = rho_of(g.centre);
            if (rho - diag > outer && double(nd.diag2) < angle2 * dc2) {
                const Vec3 lat = v - nx * dot(v, nx);
                const double ll = length(lat);
                const Vec3 u = ll > 0 ? lat * (1.0 / ll) : Vec3(0, 0, 0);
                const double* C = g.cov;
                auto quad = [C](const Vec3& a) {
                    return a.x * (C[0] * a.x + C[3] * a.y + C[4] * a.z) + a.y * (C[3] * a.x + C[1] * a.y + C[5] * a.z) +
                           a.z * (C[4] * a.x + C[5] * a.y + C[2] * a.z);
                };
                const double uCu = quad(u), nCn = quad(nx);
                const double a = 0.5 * uCu, b = 0.5 * std::max(0.0, C[0] + C[1] + C[2] - nCn - uCu) / rho;
                // T at rho plus the second-order term, times the node's flux, never below 0
                auto expanded = [&](const RdProfile& tp) {
                    Rgb f0, f1, f2;
                    tp.eval(rho, &f0, &f1, &f2);
                    return Rgb(std::max(0.0, f0.r + a * f2.r + b * f1.r) * g.flux.r,
                               std::max(0.0, f0.g + a * f2.g + b * f1.g) * g.flux.g,
                               std::max(0.0, f0.b + a * f2.b + b * f1.b) * g.flux.b);
                };
                const Rgb t = expanded(*transmit);
                sum.r += t.r;
                sum.g += t.g;
                sum.b += t.b;
                opp_sum += t;
                if (kSided && second) {
                    const Rgb t2 = expanded(*second->transmit);
                    sum2 += t2;
                    opp_sum2 += t2;
                }
                continue;
            }
        }
        for (int c = 0; c < nd.children; ++c) {
            stack[top] = nd.child + c;
            if (kSided) sides[top] = std::uint8_t(side);
            ++top;
        }
    }
    if (visited) *visited += opened;
    if (kSided && near_area > 0) {
        near_area = std::max(near_area, near_disc_area(r0, h));
        const Rgb t = near_opposite * near_flux * (1.0 / near_area);
        sum += t;
        opp_sum += t;
        if (second) {
            const Rgb t2 = second->near_opposite * near_flux * (1.0 / near_area);
            sum2 += t2;
            opp_sum2 += t2;
        }
    }
    if (opposite) *opposite = opp_sum;
    if (kSided && second) {
        *second->result = sum2;
        *second->opposite = opp_sum2;
    }
    return sum;
}

template <bool kSided>
Rgb PointCloud::exact_sum(const RdProfile& same, const RdProfile* transmit, const Vec3& x, const Vec3& nx, double d,
                          double r0, double h, const Rgb& near_opposite, const RadialWeight* weight) const {
    Rgb sum, near_flux;
    double near_area = 0;
    for (const SurfacePoint& s : points_) {
        const Vec3 v = x - s.p;
        const double r = length(v);
        if (!kSided || dot(s.n, nx) > 0) {
            const double w = window(r, r0, h);
            if (w > 0) sum += same.exact(r) * s.irradiance * (s.area * w) * (weight ? weight->at(r) : Rgb(1.0));
        } else {
            const double vn = std::min(std::fabs(dot(v, nx)), d);
            const double rho = std::sqrt(std::max(0.0, r * r - vn * vn));
            const double w = window(rho, r0, h);
            sum += transmit->exact(rho) * s.irradiance * (s.area * w);
            near_area += (1.0 - w) * s.area;
            near_flux += s.irradiance * ((1.0 - w) * s.area);
        }
    }
    if (near_area > 0) sum += near_opposite * near_flux * (1.0 / std::max(near_area, near_disc_area(r0, h)));
    return sum;
}

}  // namespace shading

namespace shading {

// ---------------------------------------------------------------- direction-aware profiles

Rgb PointCloud::far_exitance_shifted(const RdProfile& rd, const Vec3& x, const Vec3& nx, double r0, double h,
                                     double max_angle, double cutoff, Rgb* near_irradiance, std::size_t* visited,
                                     const RadialWeight* weight) const {
    return shifted_sum<false>(rd, x, nx, r0, h, max_angle, cutoff * cutoff, near_irradiance, visited, weight);
}

Rgb PointCloud::far_exitance_shifted_exact(const RdProfile& rd, const Vec3& x, const Vec3& nx, double r0, double h,
                                           Rgb* near_irradiance, const RadialWeight* weight) const {
    return shifted_sum<true>(rd, x, nx, r0, h, 0.0, kInf, near_irradiance, nullptr, weight);
}

template <bool kExact>
Rgb PointCloud::shifted_sum(const RdProfile& rd, const Vec3& x, const Vec3& nx, double r0, double h, double max_angle,
                            double cut2, Rgb* near_irradiance, std::size_t* visited, const RadialWeight* weight) const {
    constexpr int K = kSmearNodes;
    Rgb sum;
    // The near field: the (1 - w)-weighted flux of the images inside the window, per channel and
    // image, over the larger of two (1 - w)-weighted areas: the points' own there (the surface
    // about x: where few images land, as just upstream of a shadow edge, their flux density is
    // low) and the images' (a mean of E_t: where the partition of unity gives the points about
    // x little area and some image much, the density would overshoot).
    double nflux[3][K] = {}, iarea[3][K] = {}, narea = 0;
    const double inner2 = sqr(std::max(0.0, r0 - h)), outer = r0 + h, outer2 = outer * outer;
    const double angle2 = max_angle * max_angle;
    const double gain_cap = std::max(1.0, 1.0 / std::max(angle2, 1e-300));
    const double cut = std::sqrt(cut2);
    std::size_t opened = 0;
    // Whether the first two images of every lit point of node k lie beyond the window's ramp,
    // as the distance across x's tangent plane with the point's own height (add_point's r):
    // by the box, moved by each image's mean offset t_k mean_c, less the points' deviation from
    // it (t_k dev_c), the box's extent along nx taken out; or, where that says less, by the
    // box less t_k times the largest shift.
    // bd: the distance from x to the box.
    auto images_beyond = [&](int k, const Node& nd, const NodeShift& ns, double bd) {
        if (bd - kSmearT[1] * ns.spread > outer) return true;
        // the range of (x - p).nx over the box
        double lo_n = dot(x, nx), hi_n = lo_n;
        const double nn[3] = {nx.x, nx.y, nx.z};
        for (int a = 0; a < 3; ++a) {
            const double e0 = -nn[a] * double(nd.lo[a]), e1 = -nn[a] * double(nd.hi[a]);
            lo_n += std::min(e0, e1);
            hi_n += std::max(e0, e1);
        }
        const double own2 = lo_n > 0 ? lo_n * lo_n : (hi_n < 0 ? hi_n * hi_n : 0.0);  // the least v0n^2
        for (int c = 0; c < 3; ++c) {
            if (!(aggs_[k].flux[c] > 0)) continue;
            for (int j = 0; j < 2; ++j) {
                const double t = kSmearT[j];
                const Vec3 m = ns.mean[c] * t;
                const double mn = dot(m, nx);
                const double hmax = std::max(std::fabs(lo_n - mn), std::fabs(hi_n - mn));
                const double across = std::sqrt(std::max(0.0, box_distance2(x - m, nd.lo, nd.hi) - hmax * hmax));
                const double r_new = std::sqrt(sqr(std::max(0.0, across - t * ns.dev[c])) + own2);
                if (!(std::max(r_new, bd - t * ns.spread) > outer)) return false;
            }
        }
        return true;
    };
    auto add_point = [&](int i) {
        const Leaf& s = leaves_[i];
        const LeafShift& ls = leaf_shift_[i];
        double own = 0;  // (1 - w) A at the point itself
        const Vec3 v0 = x - s.p;
        const double v0n = dot(v0, nx), v0n2 = v0n * v0n;
        {
            const double r2 = dot(v0, v0);
            if (r2 < outer2) own = (1.0 - (r2 <= inner2 ? 0.0 : window(std::sqrt(r2), r0, h))) * points_[i].area;
            narea += own;
        }
        for (int c = 0; c < 3; ++c) {
            const double f = s.flux[c];
            if (!(f > 0)) {  // unlit in c: no shift, every image at the point
                if (own > 0)
                    for (int k = 0; k < K; ++k) iarea[c][k] += own;
                continue;
            }
            const Vec3& sc = ls.s[c];
            if (!kExact) {
                // Far from x (beyond six shifts and the window's ramp): the images' spread to
                // second order about the mean image, R(d) + (1/2) tr(H S), S = v s s^T (their
                // variance v |s|^2 along s, v = kSmearVariance): one profile lookup, not K.
                const Vec3 v = v0 - sc;
                const double vn = dot(v, nx);
                const double d2 = std::max(0.0, dot(v, v) - vn * vn + v0n2), s2 = dot(sc, sc);
                if (d2 > 36.0 * s2 && d2 > sqr(outer + 2.0 * std::sqrt(s2))) {
                    if (d2 > cut2) continue;
                    const double d = std::sqrt(d2), inv = 1.0 / d;
                    const double us = dot(v, sc) * inv;
                    double f0, f1, f2;
                    rd.eval_channel(c, d, &f0, &f1, &f2);
                    const double spread = kSmearVariance * (f2 * us * us + f1 * inv * (s2 - us * us));
                    sum[c] += std::max(0.0, f0 + 0.5 * spread) * f * (weight ? weight->at(c, d) : 1.0);
                    continue;
                }
            }
            for (int k = 0; k < K; ++k) {
                // the distance across x's tangent plane, with the point's own height above it: a
                // shift along a curved surface does not lift the image off it
                const Vec3 v = v0 - sc * kSmearT[k];
                const double vn = dot(v, nx);
                const double r2 = std::max(0.0, dot(v, v) - vn * vn + v0n2);
                if (r2 > cut2) continue;
                double w = 1.0;
                if (r2 < outer2) {
                    w = r2 <= inner2 ? 0.0 : window(std::sqrt(r2), r0, h);
                    nflux[c][k] += (1.0 - w) * f;
                    iarea[c][k] += (1.0 - w) * points_[i].area;
                }
                if (w > 0) {
                    const double r = std::sqrt(r2);
                    sum[c] += kSmearW[k] * w * f * (kExact ? rd.exact(r)[c] : rd.rd_channel(c, r)) *
                              (weight ? weight->at(c, r) : 1.0);
                }
            }
        }
    };
    if (kExact) {
        for (int i = 0; i < int(points_.size()); ++i) add_point(i);
    } else if (!nodes_.empty()) {
        int stack[8 * kMaxDepth + 16];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const int k = stack[--top];
            const Node& nd = nodes_[k];
            ++opened;
            if (!nd.lit) continue;
            const NodeShift& ns = node_shift_[k];
            // every image of the node's points lies within `reach` of its box
            const double bd = std::sqrt(box_distance2(x, nd.lo, nd.hi));
            if (bd - ns.reach > cut) continue;
            if (nd.child < 0) {
                for (int i = nd.first; i < nd.first + nd.count; ++i) add_point(i);
                continue;
            }
            // Aggregated: nodes whose first two images lie beyond the window's ramp (the third,
            // a hundredth of the light, may reach into it: its near part then counts as far) and
            // that are small as seen from x.
            if (bd > outer && images_beyond(k, nd, ns, bd)) {
                const Agg& g = aggs_[k];
                const double hn = dot(g.centre - x, nx);
                // the distance across x's tangent plane to the centre moved by o, its direction
                auto across = [&](const Vec3& o, Vec3* u) {
                    const Vec3 v = g.centre + o - x;
                    const double vn = dot(v, nx);
                    const double d = std::sqrt(std::max(1e-300, dot(v, v) - vn * vn + hn * hn));
                    *u = v * (1.0 / d);
                    return d;
                };
                // Small as seen from x at each image's distance, not the first's alone: where a
                // third image (6.3 shifts on) lands within a node's size of x, the expansion
                // about it diverges (the study's CSG difference in Skin1: one pixel 12x too
                // bright, a term of 2.6e4 x R at the image's distance 0.002).
                double dmin2 = kInf;
                for (int c = 0; c < 3; ++c)
                    for (int j = 0; j < K; ++j) {
                        Vec3 u;
                        dmin2 = std::min(dmin2, sqr(across(ns.mean[c] * kSmearT[j], &u)));
                    }
                if (double(nd.diag2) < angle2 * std::min(rd.angle_gain2(dmin2), gain_cap) * dmin2) {
                    const double* C = g.cov;
                    // R at distance d (direction u) to second order in the covariance C + extra s s^T
                    auto taylor = [&](int c, double d, const Vec3& u, const Vec3& sx) {
                        const double uCu = u.x * (C[0] * u.x + C[3] * u.y + C[4] * u.z) +
                                           u.y * (C[3] * u.x + C[1] * u.y + C[5] * u.z) +
                                           u.z * (C[4] * u.x + C[5] * u.y + C[2] * u.z);
                        const double us = dot(u, sx);
                        const double uCs = uCu + us * us, tr = C[0] + C[1] + C[2] + dot(sx, sx);
                        double f0, f1, f2;
                        rd.eval_channel(c, d, &f0, &f1, &f2);
                        return std::max(0.0, f0 + 0.5 * uCs * f2 + 0.5 * (tr - uCs) / d * f1);
                    };
                    for (int c = 0; c < 3; ++c) {
                        if (!(g.flux[c] > 0)) continue;
                        const Vec3& sc = ns.mean[c];
                        Vec3 u;
                        const double dm = across(sc, &u);
                        double r;
                        if (dm * dm > 36.0 * dot(sc, sc)) {
                            // far beyond the spread: the mean image, the images' variance
                            // kSmearVariance |s|^2 along s added to the covariance
                            r = taylor(c, dm, u, sc * std::sqrt(kSmearVariance)) * (weight ? weight->at(c, dm) : 1.0);
                        } else {
                            r = 0;
                            for (int j = 0; j < K; ++j) {
                                const double dj = across(sc * kSmearT[j], &u);
                                r += kSmearW[j] * taylor(c, dj, u, Vec3(0, 0, 0)) * (weight ? weight->at(c, dj) : 1.0);
                            }
                        }
                        sum[c] += r * g.flux[c];
                    }
                    continue;
                }
            }
            for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
        }
    }
    if (visited) *visited += opened;
    if (near_irradiance)
        for (int c = 0; c < 3; ++c) {
            double e = 0;
            for (int k = 0; k < K; ++k) {
                const double a = std::max(narea, iarea[c][k]);
                if (a > 0) e += kSmearW[k] * nflux[c][k] / a;
            }
            (*near_irradiance)[c] = e;
        }
    return sum;
}

template <class Visit>
void PointCloud::for_each_in_window(const Vec3& y, double h, Visit&& visit) const {
    if (nodes_.empty()) return;
    const double r0 = 2.0 * h, inner2 = sqr(r0 - h), outer = r0 + h, outer2 = outer * outer;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& nd = nodes_[stack[--top]];
        if (box_distance2(y, nd.lo, nd.hi) >= outer2) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Vec3 v = y - leaves_[i].p;
                const double r2 = dot(v, v);
                if (r2 >= outer2) continue;
                visit(i, v, r2, 1.0 - (r2 <= inner2 ? 0.0 : window(std::sqrt(r2), r0, h)));
            }
            continue;
        }
        for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
    }
}

Rgb PointCloud::irradiance_about(const Vec3& y, double h) const {
    Rgb flux;
    double area = 0;
    for_each_in_window(y, h, [&](int i, const Vec3&, double, double w) {
        flux += leaves_[i].flux * w;
        area += points_[i].area * w;
    });
    if (area > 0) return flux * (1.0 / area);
    // Off the surface (single_scatter_upstream's line along x's tangent plane leaves a curved
    // face: at the finest spacings its far nodes saw no point and read 0, which darkened single
    // scattering by several per cent on a small Ketchup mesh): the nearest point's light.
    const int i = nearest(y);
    return i < 0 ? Rgb(0.0) : points_[std::size_t(i)].irradiance;
}

template <class Whole, class Point>
void PointCloud::window_sum(const Vec3& x, const Vec3& nx, double h, double small, double min_cos, Whole&& whole,
                            Point&& point) const {
    if (nodes_.empty()) return;
    const double r0 = 2.0 * h, inner2 = sqr(r0 - h), outer2 = sqr(r0 + h), small2 = sqr(small * h);
    auto weight = [&](double r2) { return r2 <= inner2 ? 1.0 : (r2 >= outer2 ? 0.0 : 1.0 - window(std::sqrt(r2), r0, h)); };
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const int k = stack[--top];
        const Node& nd = nodes_[k];
        if (box_distance2(x, nd.lo, nd.hi) >= outer2) continue;
        if (double(nd.diag2) <= small2 && nd.count > 1) {
            // every normal within acos(min_cos) of nx: phi + a below it, phi the angle from the
            // cone's axis to nx, a the cone's half-angle
            const Cone& cone = cones_[k];
            const double ca = std::min(1.0, cone.axis_cos(nx));
            const double cc = curve_[k].cone_cos, sa = std::sqrt(std::max(0.0, 1.0 - ca * ca));
            const double sc = std::sqrt(std::max(0.0, 1.0 - cc * cc));
            if (ca > 0 && cc > 0 && ca * cc - sa * sc > min_cos) {
                const Vec3 cx = curve_[k].centre - x;
                whole(k, cx, weight(dot(cx, cx)));
                continue;
            }
        }
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Vec3 v = x - leaves_[i].p;
                const double r2 = dot(v, v);
                if (r2 < outer2) point(i, v, r2, weight(r2));
            }
            continue;
        }
        for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
    }
}

bool PointCloud::flat_within(const Vec3& x, const Vec3& nx, double radius, double cos_min) const {
    if (nodes_.empty()) return true;
    const double r2 = radius * radius;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const int k = stack[--top];
        const Node& nd = nodes_[k];
        if (box_distance2(x, nd.lo, nd.hi) > r2) continue;
        // the least cosine any normal of the node can have with nx: cos(a + angle), a the angle
        // from the cone's axis to nx
        const Cone& cone = cones_[k];
        const double ca = std::clamp(cone.axis_cos(nx), -1.0, 1.0);
        const double a = std::acos(ca) + double(cone.angle);
        if (a < kPi && std::cos(a) >= cos_min) continue;  // every normal in it is close enough
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Vec3 v = points_[i].p - x;
                if (dot(v, v) <= r2 && dot(points_[i].n, nx) < cos_min) return false;
            }
            continue;
        }
        for (int c = nd.child; c < nd.child + nd.children; ++c) stack[top++] = c;
    }
    return true;
}

double PointCloud::mean_curvature_about(const Vec3& x, const Vec3& nx, double h) const {
    // Each point for its own area (a quadrature over the surface, whatever the sampling's
    // density); least squares of (nx - n_i).v - H r2 with weights A w / r2: its normal equation
    // is sum A w (nx - n_i).v = H sum A w r2, v = x - p_i, w the window's 1 - w(r).
    // A node small against the window's ramp (under half the spacing across; the ramp is two
    // spacings wide, and the centre's weight errs to second order in the node's size) whose
    // normals all face nx's side is taken whole from its sums about its centroid c (curve_),
    // at the weight of c: sum A (nx - n_i).v = nx.(A (x - c)) - n.(x - c) + q and sum A r2 =
    // A |x - c|^2 + v. A refined cloud (a shadow edge 5 levels deep) holds 1024 samples per
    // window cell; the sum visits a few hundred nodes instead. On a sphere every term is H r2
    // either way: H = 1/R exactly.
    double num = 0, den = 0;
    window_sum(
        x, nx, h, 0.5, 0.0,
        [&](int k, const Vec3& cx, double w) {
            const CurveSums& cs = curve_[k];
            // v = x - c = -cx
            num -= w * (cs.area * dot(nx, cx) - dot(cs.nsum, cx) - cs.q);
            den += w * (cs.area * dot(cx, cx) + cs.var);
        },
        [&](int i, const Vec3& v, double r2, double w) {
            const SurfacePoint& q = points_[i];
            if (!(r2 > 0) || !(dot(q.n, nx) > 0)) return;
            num += q.area * w * dot(nx - q.n, v);
            den += q.area * w * r2;
        });
    return den > 0 ? num / den : 0.0;
}

namespace {
constexpr double kDivergenceFaceCos = 0.866;  // cos 30 degrees
}  // namespace

Rgb PointCloud::shift_divergence_about(const Vec3& x, const Vec3& nx, double h) const {
    if (leaf_shift_.empty()) return Rgb(0.0);
    // a tangent basis at x
    const Vec3 e1 = normalize(std::fabs(nx.x) < 0.9 ? cross(nx, Vec3(1, 0, 0)) : cross(nx, Vec3(0, 1, 0)));
    const Vec3 e2 = cross(nx, e1);
    // per channel the weighted sums of 1, d (2), s (2), d d^T (3) and s d^T (4), d = p_i - x and
    // s the shift, both across x's tangent plane
    double sums[3][12] = {};
    int count[3] = {0, 0, 0};
    auto point = [&](int i, const Vec3& v, double w) {
        // the face x lies on: a sheet's other face, or an edge's or a crease's other side
        // (normals more than 30 degrees apart: their shifts lie in other planes), stays out
        if (!(dot(points_[i].n, nx) > kDivergenceFaceCos)) return;
        const double a = points_[i].area * w, u1 = -dot(v, e1), u2 = -dot(v, e2);
        for (int c = 0; c < 3; ++c) {
            // the shift as the light gave it, not faded at creases (build_shifts): the fade's own
            // fall to 0 toward a crease is no divergence of the light's field (it drew +-30 %
            // lines along the CSG difference's inner edges). Unlit points, and the light's edge
            // cells whose centre the light misses (lit by their sub-lines' mean, shift 0), are
            // not part of the field.
            const Vec3& sv = points_[i].shift[c];
            if (!(leaves_[i].flux[c] > 0) || dot(sv, sv) == 0) continue;
            const double t1 = dot(sv, e1), t2 = dot(sv, e2);
            double* S = sums[c];
            S[0] += a, S[1] += a * u1, S[2] += a * u2, S[3] += a * t1, S[4] += a * t2;
            S[5] += a * u1 * u1, S[6] += a * u1 * u2, S[7] += a * u2 * u2;
            S[8] += a * t1 * u1, S[9] += a * t1 * u2, S[10] += a * t2 * u1, S[11] += a * t2 * u2;
            ++count[c];
        }
    };
    // A node under half the spacing across whose normals all lie within 30 degrees of nx is
    // taken whole from its sums (div_) at the weight of its centre, as mean_curvature_about
    // takes its nodes (a shadow edge refined 5 levels: 1024 samples per cell of the base
    // spacing's window).
    DivSums about_x[3];  // the whole nodes' sums, in 3-D about x
    window_sum(
        x, nx, h, 0.5, kDivergenceFaceCos,
        [&](int k, const Vec3& cx, double w) {
            const double d[3] = {cx.x, cx.y, cx.z};  // from x to the node's centre
            for (int ch = 0; ch < 3; ++ch) {
                const DivSums& D = div_[k][ch];
                if (D.count == 0) continue;
                // in 3-D about x (projected across x's plane once, at the end)
                about_x[ch].add_moved(D, d, w);
                count[ch] += D.count;
            }
        },
        [&](int i, const Vec3& v, double, double w) { point(i, v, w); });
    // the whole nodes' sums across x's plane: u = (p - x).e, t = s.e
    const double E[2][3] = {{e1.x, e1.y, e1.z}, {e2.x, e2.y, e2.z}};
    for (int ch = 0; ch < 3; ++ch) {
        const DivSums& T = about_x[ch];
        if (!(T.a > 0)) continue;
        double m[2], sv[2], M[2][2], N[2][2];
        for (int i = 0; i < 2; ++i) {
            const double* e = E[i];
            m[i] = T.m[0] * e[0] + T.m[1] * e[1] + T.m[2] * e[2];
            sv[i] = T.s[0] * e[0] + T.s[1] * e[1] + T.s[2] * e[2];
        }
        const double* P = T.M;
        for (int i = 0; i < 2; ++i)
            for (int j = 0; j < 2; ++j) {
                const double* a = E[i];
                const double* b = E[j];
                M[i][j] = a[0] * (P[0] * b[0] + P[3] * b[1] + P[4] * b[2]) + a[1] * (P[3] * b[0] + P[1] * b[1] + P[5] * b[2]) +
                          a[2] * (P[4] * b[0] + P[5] * b[1] + P[2] * b[2]);
                double r = 0;
                for (int q = 0; q < 3; ++q) r += a[q] * (T.N[3 * q] * b[0] + T.N[3 * q + 1] * b[1] + T.N[3 * q + 2] * b[2]);
                N[i][j] = r;
            }
        double* S = sums[ch];
        S[0] += T.a, S[1] += m[0], S[2] += m[1], S[3] += sv[0], S[4] += sv[1];
        S[5] += M[0][0], S[6] += M[0][1], S[7] += M[1][1];
        S[8] += N[0][0], S[9] += N[0][1], S[10] += N[1][0], S[11] += N[1][1];
    }
    Rgb out;
    for (int c = 0; c < 3; ++c) {
        const double* S = sums[c];
        const double W = S[0];
        if (count[c] < 6 || !(W > 0)) continue;
        // centred: C = sum a (d - dbar)(d - dbar)^T, B = sum a (s - sbar)(d - dbar)^T; J = B C^-1
        const double m1 = S[1] / W, m2 = S[2] / W, n1 = S[3] / W, n2 = S[4] / W;
        const double C11 = S[5] - W * m1 * m1, C12 = S[6] - W * m1 * m2, C22 = S[7] - W * m2 * m2;
        const double B11 = S[8] - W * n1 * m1, B12 = S[9] - W * n1 * m2, B21 = S[10] - W * n2 * m1, B22 = S[11] - W * n2 * m2;
        const double det = C11 * C22 - C12 * C12;
        if (!(det > 1e-6 * (C11 + C22) * (C11 + C22))) continue;  // points along a line: no 2-D fit
        // tr(B C^-1), C^-1 = [C22 -C12; -C12 C11] / det
        out[c] = (B11 * C22 - (B12 + B21) * C12 + B22 * C11) / det;
    }
    return out;
}

}  // namespace shading
