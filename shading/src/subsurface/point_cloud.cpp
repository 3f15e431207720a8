// The point cloud's octree: building it (bounds, octants, second-order aggregates, lookup
// levels) and finding the nearest point; see point_cloud.h. The far-field sums over it:
// point_cloud_far.cpp.
#include "shading/subsurface/point_cloud.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace shading {

namespace {

constexpr int kLeafSize = 8;

// Float bounds rounded outwards: distances to them never exceed distances to the true bounds.
float round_down(double v) {
    const float f = float(v);
    return double(f) > v ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
}
float round_up(double v) {
    const float f = float(v);
    return double(f) < v ? std::nextafter(f, std::numeric_limits<float>::infinity()) : f;
}

}  // namespace

PointCloud::PointCloud(std::vector<SurfacePoint> points, double spacing, const Rgb& near)
    : spacing_(spacing), points_(std::move(points)) {
    for (SurfacePoint& p : points_) {
        p.spacing = spacing;
        thinnest_ = std::min(thinnest_, p.thickness);
    }
    levels_.push_back({spacing, near});
    if (!points_.empty()) build_tree(nullptr);
    finish(nullptr);
}

PointCloud::PointCloud(std::vector<SurfacePoint> points, const NearFn& near, const ParallelFor* parallel)
    : points_(std::move(points)) {
    double coarsest = 0, finest = kInf;
    for (const SurfacePoint& p : points_) {
        if (!(p.spacing > 0) || !std::isfinite(p.spacing)) throw std::invalid_argument("PointCloud: every point needs a spacing > 0");
        coarsest = std::max(coarsest, p.spacing);
        finest = std::min(finest, p.spacing);
        thinnest_ = std::min(thinnest_, p.thickness);
    }
    spacing_ = coarsest > 0 ? coarsest : 1.0;
    if (!points_.empty()) build_tree(parallel);
    if (points_.empty() || finest == coarsest) {
        levels_.push_back({spacing_, near(spacing_)});
        finish(parallel);
        return;
    }
    // Each point's lookup spacing: the fixed point of H <- max spacing of the lit samples within
    // 3H (from its own spacing up, or its leaf's finest where none of it is lit): the window's
    // ramp [H, 3H] around a lookup there then holds no lit sample coarser than H (an unlit one
    // brings no light to it). Found once per leaf for the leaf's box (so a point may take the coarser value of
    // a neighbour up to a leaf away). Levels are the distinct values, coarsest first.
    // Each query starts at the smallest node whose octree cell holds the leaf's box widened
    // by 3H: every point that close lies under it (cells, unlike the nodes' tight bounds,
    // partition space).
    std::vector<int> parent(nodes_.size(), -1);
    std::vector<std::array<double, 6>> cell(nodes_.size());
    cell[0] = {-kInf, -kInf, -kInf, kInf, kInf, kInf};
    for (std::size_t k = 0; k < nodes_.size(); ++k) {
        const Node& nd = nodes_[k];
        for (int c = nd.child; c >= 0 && c < nd.child + nd.children; ++c) {
            parent[c] = int(k);
            std::array<double, 6> b = cell[k];
            const Vec3& sp = aux_[k].split;
            const double split[3] = {sp.x, sp.y, sp.z};
            for (int a = 0; a < 3; ++a) {
                if (nodes_[c].octant & (1 << a)) b[a] = split[a];
                else b[3 + a] = split[a];
            }
            cell[c] = b;
        }
    }
    std::vector<int> leaves;
    for (std::size_t k = 0; k < nodes_.size(); ++k)
        if (nodes_[k].child < 0) leaves.push_back(int(k));
    std::vector<double> leaf_h(leaves.size());
    auto settle = [&](std::size_t c, SurfaceSampler*) {
        for (std::size_t l = 64 * c; l < std::min(leaves.size(), 64 * (c + 1)); ++l) {
            const int leaf = leaves[l];
            const Node& nd = nodes_[leaf];
            // (from its lit points' spacing; a leaf with none lit from its finest: unlit points
            // bring no light to any window, so their spacing does not bound it)
            double H = 0, own_finest = kInf;
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                own_finest = std::min(own_finest, points_[i].spacing);
                if (points_[i].irradiance.max_component() > 0) H = std::max(H, points_[i].spacing);
            }
            if (!(H > 0)) H = own_finest;
            while (H < coarsest) {
                const double r = 3.0 * H;
                int start = leaf;
                auto holds = [&](int k) {
                    const std::array<double, 6>& b = cell[k];
                    for (int a = 0; a < 3; ++a)
                        if (!(b[a] <= nd.lo[a] - r && nd.hi[a] + r < b[3 + a])) return false;
                    return true;
                };
                while (parent[start] >= 0 && !holds(start)) start = parent[start];
                const double m = max_spacing_within(start, nd.lo, nd.hi, r, H);
                if (!(m > H)) break;
                H = m;
            }
            leaf_h[l] = H;
        }
    };
    const std::size_t chunks = (leaves.size() + 63) / 64;
    if (parallel) (*parallel)(chunks, [&](std::size_t c, SurfaceSampler& s) { settle(c, &s); });
    else for (std::size_t c = 0; c < chunks; ++c) settle(c, nullptr);
    std::vector<double> distinct;
    std::vector<double> lookup(points_.size());
    for (std::size_t l = 0; l < leaves.size(); ++l) {
        const Node& nd = nodes_[leaves[l]];
        const double H = leaf_h[l];
        for (int i = nd.first; i < nd.first + nd.count; ++i) lookup[i] = H;
        if (std::find(distinct.begin(), distinct.end(), H) == distinct.end()) distinct.push_back(H);
    }
    std::sort(distinct.begin(), distinct.end(), std::greater<double>());
    if (distinct.size() > 127) throw std::invalid_argument("PointCloud: more than 127 distinct spacings");
    for (double h : distinct) levels_.push_back({h, near(h)});
    level_of_.resize(points_.size());
    for (std::size_t i = 0; i < points_.size(); ++i)
        level_of_[i] = std::uint8_t(std::find(distinct.begin(), distinct.end(), lookup[i]) - distinct.begin());
    finish(parallel);
}

struct PointCloud::Tree {
    std::vector<Node> nodes;
    std::vector<Agg> aggs;
    std::vector<Aux> aux;
    std::vector<Merge> merge;
    std::vector<Cone> cones;
    int grow(int n) {
        const int at = int(nodes.size());
        nodes.resize(at + n);
        aggs.resize(at + n);
        aux.resize(at + n);
        merge.resize(at + n);
        cones.resize(at + n);
        return at;
    }
};

// The root splits here; its (at most 8) subtrees build in parallel, each into a tree of its
// own, and are spliced in behind the root and its children in octant order: the same tree for
// any number of threads.
void PointCloud::build_tree(const ParallelFor* parallel) {
    Tree t;
    t.grow(1);
    const int n_points = int(points_.size());
    int ranges[8][3];
    const int n = split(t, 0, 0, n_points, 0, ranges);
    if (n > 1) {
        std::vector<Tree> sub(n);
        auto one = [&](std::size_t k) {
            sub[k].grow(1);
            build(sub[k], 0, ranges[k][0], ranges[k][1], 1);
        };
        if (parallel) (*parallel)(std::size_t(n), [&](std::size_t k, SurfaceSampler&) { one(k); });
        else for (int k = 0; k < n; ++k) one(std::size_t(k));
        std::size_t total = 1 + n;
        for (const Tree& s : sub) total += s.nodes.size() - 1;
        t.nodes.reserve(total);
        t.aggs.reserve(total);
        t.aux.reserve(total);
        t.merge.reserve(total);
        t.cones.reserve(total);
        t.grow(n);
        t.nodes[0].child = 1;
        t.nodes[0].children = std::int16_t(n);
        int base = 1 + n;  // where subtree k's node 1 goes
        for (int k = 0; k < n; ++k) {
            const Tree& s = sub[k];
            const int shift = base - 1;  // local j >= 1 -> base + j - 1
            auto place = [&](int to, int from) {
                t.nodes[to] = s.nodes[from];
                if (t.nodes[to].child >= 0) t.nodes[to].child += shift;
                t.aggs[to] = s.aggs[from];
                t.aux[to] = s.aux[from];
                t.merge[to] = s.merge[from];
                t.cones[to] = s.cones[from];
            };
            place(1 + k, 0);
            t.nodes[1 + k].octant = std::uint8_t(ranges[k][2]);
            const int at = t.grow(int(s.nodes.size()) - 1);
            for (int j = 1; j < int(s.nodes.size()); ++j) place(at + j - 1, j);
            base += int(s.nodes.size()) - 1;
        }
    }
    aggregate(t, 0, 0, n_points, n);
    nodes_ = std::move(t.nodes);
    aggs_ = std::move(t.aggs);
    aux_ = std::move(t.aux);
    cones_ = std::move(t.cones);
}

// Bounds top-down (the split needs them), aggregates bottom-up: a leaf's from its points, a
// parent's by merging its children's (weights, means and covariances, the parallel-axis rule),
// so each point is read O(1) times for the aggregates whatever the depth.
void PointCloud::build(Tree& t, int index, int first, int count, int depth) {
    int ranges[8][3];
    const int n = split(t, index, first, count, depth, ranges);
    if (n > 1) {
        const int child = t.grow(n);
        t.nodes[index].child = child;
        t.nodes[index].children = std::int16_t(n);
        for (int k = 0; k < n; ++k) {
            t.nodes[child + k].octant = std::uint8_t(ranges[k][2]);
            build(t, child + k, ranges[k][0], ranges[k][1], depth + 1);
        }
    }
    aggregate(t, index, first, count, n);
}

// The node's bounds, and its points partitioned in place into the non-empty octants about the
// centre of the bounds: ranges (first, count, octant), how many (<= 1: a leaf).
int PointCloud::split(Tree& t, int index, int first, int count, int depth, int ranges[8][3]) {
    Vec3 lo = points_[first].p, hi = lo;
    for (int i = first + 1; i < first + count; ++i) {
        const Vec3& p = points_[i].p;
        lo = Vec3(std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z));
        hi = Vec3(std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z));
    }
    Node& nd = t.nodes[index];
    nd.lo[0] = round_down(lo.x), nd.lo[1] = round_down(lo.y), nd.lo[2] = round_down(lo.z);
    nd.hi[0] = round_up(hi.x), nd.hi[1] = round_up(hi.y), nd.hi[2] = round_up(hi.z);
    const Vec3 span = hi - lo;
    nd.diag2 = round_up(dot(span, span));
    nd.first = first;
    nd.count = count;
    t.aux[index].split = (lo + hi) * 0.5;
    t.aggs[index].centre = lo;  // (the unlit, arealess fallback; aggregate() sets the real one)
    int n = 0;
    if (count <= kLeafSize || depth >= kMaxDepth || !(dot(span, span) > 0)) return 0;
    const Vec3 c = t.aux[index].split;
    auto begin = points_.begin() + first, end = begin + count;
    auto mz = std::partition(begin, end, [&](const SurfacePoint& s) { return s.p.z < c.z; });
    auto my0 = std::partition(begin, mz, [&](const SurfacePoint& s) { return s.p.y < c.y; });
    auto my1 = std::partition(mz, end, [&](const SurfacePoint& s) { return s.p.y < c.y; });
    auto split_x = [&](std::vector<SurfacePoint>::iterator a, std::vector<SurfacePoint>::iterator b) {
        return std::partition(a, b, [&](const SurfacePoint& s) { return s.p.x < c.x; });
    };
    auto mx0 = split_x(begin, my0), mx1 = split_x(my0, mz), mx2 = split_x(mz, my1), mx3 = split_x(my1, end);
    // Range k holds octant k: bit 0 set for x >= c.x, bit 1 for y, bit 2 for z.
    const std::vector<SurfacePoint>::iterator bounds[9] = {begin, mx0, my0, mx1, mz, mx2, my1, mx3, end};
    for (int k = 0; k < 8; ++k) {
        int a = int(bounds[k] - points_.begin()), b = int(bounds[k + 1] - points_.begin());
        if (b > a) {
            ranges[n][0] = a;
            ranges[n][1] = b - a;
            ranges[n][2] = k;
            ++n;
        }
    }
    return n;
}

// A node's aggregate: from its points (a leaf, n <= 1) or by merging its n children's.
void PointCloud::aggregate(Tree& t, int index, int first, int count, int n) {
    // Weights: w = flux summed over channels (the centre and covariance), a = area (the centre
    // of an unlit node).
    double wsum = 0, area = 0;
    Vec3 wmean, amean;
    double cov[6] = {0, 0, 0, 0, 0, 0};
    Rgb flux;
    double max_spacing = 0;
    Vec3 nsum;
    auto add = [&](double w, double a, const Vec3& cw, const Vec3& ca, const double* S, const Rgb& f, double sp) {
        // merge (w, cw, S) into the running (wsum, wmean, cov): parallel-axis rule
        if (w > 0) {
            const double W = wsum + w;
            const Vec3 d = cw - wmean;
            const double tw = wsum * w / W;  // weight of the between-means term
            for (int k = 0; k < 6; ++k) cov[k] = (wsum * cov[k] + w * S[k]) / W;
            cov[0] += tw * d.x * d.x / W, cov[1] += tw * d.y * d.y / W, cov[2] += tw * d.z * d.z / W;
            cov[3] += tw * d.x * d.y / W, cov[4] += tw * d.x * d.z / W, cov[5] += tw * d.y * d.z / W;
            wmean = wmean + d * (w / W);
            wsum = W;
        }
        if (a > 0) {
            const double A = area + a;
            amean = amean + (ca - amean) * (a / A);
            area = A;
        }
        flux += f;
        max_spacing = std::max(max_spacing, sp);
    };
    // The normal cone (thin geometry): axis along the area-weighted normal sum, half-angle the
    // widest normal (a leaf) or child cone (a parent) from it, rounded up; pi when the normals
    // cancel.
    double cone = 0;
    auto angle_to = [](const Vec3& axis, const Vec3& v) { return std::acos(std::max(-1.0, std::min(1.0, dot(axis, v)))); };
    if (n <= 1) {
        static const double zero[6] = {0, 0, 0, 0, 0, 0};
        for (int i = first; i < first + count; ++i) {
            const SurfacePoint& s = points_[i];
            const Rgb f = s.irradiance * s.area;
            add(f.r + f.g + f.b, s.area, s.p, s.p, zero, f, s.spacing);
            nsum = nsum + s.n * std::max(s.area, 1e-300);
        }
        const double len = length(nsum);
        const Vec3 axis = len > 0 ? nsum * (1.0 / len) : Vec3(0, 0, 1);
        if (!(len > 0)) cone = kPi;
        for (int i = first; i < first + count && cone < kPi; ++i) cone = std::max(cone, angle_to(axis, points_[i].n));
    } else {
        const int child = t.nodes[index].child;
        for (int k = 0; k < n; ++k) {
            const Agg& c = t.aggs[child + k];
            const Merge& m = t.merge[child + k];
            add(m.wsum, m.area, c.centre, m.area_centre, c.cov, c.flux, t.aux[child + k].max_spacing);
            nsum = nsum + m.nsum;
        }
        const double len = length(nsum);
        const Vec3 axis = len > 0 ? nsum * (1.0 / len) : Vec3(0, 0, 1);
        if (!(len > 0)) cone = kPi;
        for (int k = 0; k < n && cone < kPi; ++k) {
            const Cone& cc = t.cones[child + k];
            cone = std::max(cone, angle_to(axis, Vec3(cc.axis[0], cc.axis[1], cc.axis[2])) + double(cc.angle));
        }
    }
    {
        const double len = length(nsum);
        const Vec3 axis = len > 0 ? nsum * (1.0 / len) : Vec3(0, 0, 1);
        Cone& cc = t.cones[index];
        cc.axis[0] = float(axis.x), cc.axis[1] = float(axis.y), cc.axis[2] = float(axis.z);
        // float axis and angle: 1e-5 rad covers their rounding
        cc.angle = float(std::min(kPi, cone + 1e-5));
    }
    Agg& g = t.aggs[index];
    t.merge[index] = {wsum, area, amean, nsum};
    // The flux-weighted centre is where an aggregate's light comes from; an unlit node has
    // no flux to place, its area-weighted centre is used.
    if (wsum > 0) g.centre = wmean;
    else if (area > 0) g.centre = amean;
    for (int k = 0; k < 6; ++k) g.cov[k] = wsum > 0 ? cov[k] : 0.0;
    g.flux = flux;
    t.aux[index].max_spacing = max_spacing;
    t.nodes[index].lit = flux.max_component() > 0;
}

void PointCloud::finish(const ParallelFor* parallel) {
    leaves_.resize(points_.size());
    for (std::size_t i = 0; i < points_.size(); ++i) {
        leaves_[i] = {points_[i].p, points_[i].irradiance * points_[i].area};
        max_irradiance_ = std::max(max_irradiance_, points_[i].irradiance.max_component());
    }
    build_curve_sums();  // (its cones' cosines serve build_shifts too)
    build_shifts(parallel);
    build_div_sums();
    // Children come after their parent: one backward pass settles which nodes share one level.
    for (std::size_t k = nodes_.size(); k-- > 0;) {
        Node& nd = nodes_[k];
        if (level_of_.empty()) {
            nd.uniform = 0;
            continue;
        }
        int level = -2;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count && level != -1; ++i)
                level = level == -2 || level == level_of_[i] ? level_of_[i] : -1;
        } else {
            for (int c = nd.child; c < nd.child + nd.children && level != -1; ++c)
                level = nodes_[c].uniform < 0 ? -1 : (level == -2 || level == nodes_[c].uniform ? nodes_[c].uniform : -1);
        }
        nd.uniform = std::int8_t(level < 0 ? -1 : level);
    }
}

void PointCloud::build_curve_sums() {
    curve_.assign(nodes_.size(), CurveSums{});
    // Children come after their parent: one backward pass, each node's sums about its own
    // centroid from its points' or its children's (the parallel-axis rule).
    for (std::size_t k = nodes_.size(); k-- > 0;) {
        const Node& nd = nodes_[k];
        CurveSums& cs = curve_[k];
        double area = 0;
        Vec3 ap;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                area += points_[i].area;
                ap = ap + points_[i].p * points_[i].area;
            }
        } else {
            for (int j = nd.child; j < nd.child + nd.children; ++j) {
                area += curve_[j].area;
                ap = ap + curve_[j].centre * curve_[j].area;
            }
        }
        cs.cone_cos = std::cos(double(cones_[k].angle));
        cs.area = area;
        cs.centre = area > 0 ? ap * (1.0 / area) : Vec3(double(nd.lo[0]), double(nd.lo[1]), double(nd.lo[2]));
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const SurfacePoint& q = points_[i];
                const Vec3 d = q.p - cs.centre;
                cs.nsum = cs.nsum + q.n * q.area;
                cs.q += q.area * dot(q.n, d);
                cs.var += q.area * dot(d, d);
            }
        } else {
            for (int j = nd.child; j < nd.child + nd.children; ++j) {
                const CurveSums& c = curve_[j];
                const Vec3 d = c.centre - cs.centre;
                cs.nsum = cs.nsum + c.nsum;
                cs.q += c.q + dot(c.nsum, d);
                cs.var += c.var + c.area * dot(d, d);
            }
        }
    }
}

void PointCloud::build_div_sums() {
    div_.clear();
    if (leaf_shift_.empty()) return;
    div_.assign(nodes_.size(), std::array<DivSums, 3>{});
    // Children come after their parent: one backward pass, about each node's own centre.
    for (std::size_t k = nodes_.size(); k-- > 0;) {
        const Node& nd = nodes_[k];
        const Vec3 c = curve_[k].centre;
        for (int ch = 0; ch < 3; ++ch) {
            DivSums& D = div_[k][ch];
            // a point or child's sums, moved from its own centre o (a point: its position, with
            // no spread of its own) to c
            auto add = [&](const DivSums& from, const Vec3& o) {
                const double d[3] = {o.x - c.x, o.y - c.y, o.z - c.z};
                D.add_moved(from, d, 1.0);
            };
            if (nd.child < 0) {
                for (int i = nd.first; i < nd.first + nd.count; ++i) {
                    // the points shift_divergence_about takes: lit in the channel, with a shift
                    const Vec3& sv = points_[i].shift[ch];
                    if (!(leaves_[i].flux[ch] > 0) || dot(sv, sv) == 0) continue;
                    DivSums one;
                    one.a = points_[i].area;
                    one.s[0] = one.a * sv.x, one.s[1] = one.a * sv.y, one.s[2] = one.a * sv.z;
                    one.count = 1;
                    add(one, points_[i].p);
                }
            } else {
                for (int j = nd.child; j < nd.child + nd.children; ++j) {
                    const DivSums& C = div_[j][ch];
                    if (C.count == 0) continue;
                    add(C, curve_[j].centre);
                }
            }
        }
    }
}

const double PointCloud::kSmearT[PointCloud::kSmearNodes] = {
    kSmearLead + (1.0 - kSmearLead) * 0.41577455678347908, kSmearLead + (1.0 - kSmearLead) * 2.2942803602790417,
    kSmearLead + (1.0 - kSmearLead) * 6.2899450829374792};
const double PointCloud::kSmearW[PointCloud::kSmearNodes] = {0.71109300992917302, 0.27851773356924085,
                                                            0.010389256501586136};

void PointCloud::build_shifts(const ParallelFor* parallel) {
    bool any = false;
    for (const SurfacePoint& p : points_)
        for (int c = 0; c < 3 && !any; ++c)
            if (dot(p.shift[c], p.shift[c]) > 0) any = true;
    leaf_shift_.clear();
    node_shift_.clear();
    if (!any || nodes_.empty()) return;
    leaf_shift_.resize(points_.size());
    // Where the surface bends within the reach of a point's images (a crease, a small bump) the
    // half-space's shift means nothing: it fades with the largest angle between the point's
    // normal and those within 2.3 shifts (the second image), as 1 - (angle / 60 deg)^2, down
    // to none from 60 degrees (a sphere ten shifts in radius keeps 96 %): faded_shift.
    // The search for that angle skips a node whose normal cone (cones_) cannot hold a normal
    // farther from the point's than the farthest found so far, and stops once the fade is 0:
    // the same fade as visiting every point within reach, at a fraction of the cost (the study
    // blob in Skin1: 5.7x fewer instructions).
    constexpr double kFadeAngle = kPi / 3;
    const double cos_fade_angle = std::cos(kFadeAngle);
    std::vector<double> cone_sin(nodes_.size());  // of each cone's angle (its cosine: curve_)
    for (std::size_t k = 0; k < nodes_.size(); ++k) cone_sin[k] = std::sin(double(cones_[k].angle));
    auto fade_one = [&](std::size_t i) {
        const SurfacePoint& pt = points_[i];
        double smax = 0;
        for (int c = 0; c < 3; ++c) smax = std::max(smax, length(pt.shift[c]));
        double fade = 0;
        if (smax > 0) {
            const double reach = kSmearT[1] * smax, reach2 = reach * reach;
            double min_cos = 1;
            // The least cosine any normal of node k can have with pt.n: cos(a + angle), a the
            // angle from the cone's axis to pt.n (-1 once a + angle reaches pi).
            auto least = [&](int k) {
                const Cone& cone = cones_[k];
                const double ca = std::clamp(cone.axis_cos(pt.n), -1.0, 1.0);
                const double cc = curve_[k].cone_cos;
                return ca <= -cc ? -1.0 : ca * cc - std::sqrt(1.0 - ca * ca) * cone_sin[k];
            };
            // Depth first, the child that may hold the farthest normal first (it lowers
            // min_cos soonest, and then prunes its siblings).
            struct Entry {
                int k;
                double least;
            };
            Entry stack[8 * kMaxDepth + 16];
            int top = 0;
            stack[top++] = {0, least(0)};
            while (top > 0 && min_cos > cos_fade_angle) {
                const Entry e = stack[--top];
                if (e.least >= min_cos) continue;
                const Node& nd = nodes_[e.k];
                if (nd.child < 0) {
                    for (int q = nd.first; q < nd.first + nd.count; ++q) {
                        const Vec3 v = points_[q].p - pt.p;
                        if (dot(v, v) <= reach2) min_cos = std::min(min_cos, dot(points_[q].n, pt.n));
                    }
                    continue;
                }
                const int base = top;
                for (int c = nd.child; c < nd.child + nd.children; ++c) {
                    if (box_distance2(pt.p, nodes_[c].lo, nodes_[c].hi) > reach2) continue;
                    const double l = least(c);
                    if (l >= min_cos) continue;
                    int j = top++;  // insertion: the least bound ends on top
                    while (j > base && stack[j - 1].least < l) {
                        stack[j] = stack[j - 1];
                        --j;
                    }
                    stack[j] = {c, l};
                }
            }
            const double a = std::acos(std::clamp(min_cos, -1.0, 1.0)) / kFadeAngle;
            fade = min_cos > cos_fade_angle ? std::max(0.0, 1.0 - a * a) : 0.0;
        }
        for (int c = 0; c < 3; ++c) leaf_shift_[i].s[c] = pt.shift[c] * fade;
    };
    const std::size_t chunks = (points_.size() + 255) / 256;
    auto chunk = [&](std::size_t c) {
        for (std::size_t i = 256 * c; i < std::min(points_.size(), 256 * (c + 1)); ++i) fade_one(i);
    };
    if (parallel) (*parallel)(chunks, [&](std::size_t c, SurfaceSampler&) { chunk(c); });
    else for (std::size_t c = 0; c < chunks; ++c) chunk(c);
    // Children come after their parent: one backward pass sums them up.
    node_shift_.resize(nodes_.size());
    std::vector<Rgb> flux(nodes_.size());
    const double tmax = kSmearT[kSmearNodes - 1];
    for (std::size_t k = nodes_.size(); k-- > 0;) {
        const Node& nd = nodes_[k];
        NodeShift& ns = node_shift_[k];
        Vec3 acc[3];
        Rgb f;
        double spread = 0;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Rgb fi = leaves_[i].flux;
                for (int c = 0; c < 3; ++c) {
                    acc[c] = acc[c] + leaf_shift_[i].s[c] * fi[c];
                    spread = std::max(spread, length(leaf_shift_[i].s[c]));
                }
                f += fi;
            }
        } else {
            for (int j = nd.child; j < nd.child + nd.children; ++j) {
                const Rgb fj = flux[j];
                for (int c = 0; c < 3; ++c) acc[c] = acc[c] + node_shift_[j].mean[c] * fj[c];
                spread = std::max(spread, node_shift_[j].spread);
                f += fj;
            }
        }
        for (int c = 0; c < 3; ++c) ns.mean[c] = f[c] > 0 ? acc[c] * (1.0 / f[c]) : Vec3(0, 0, 0);
        // how far the shifts of the channel's lit points lie from its mean (a bound, by the
        // children's own: where its images can land, shifted_sum)
        for (int c = 0; c < 3; ++c) {
            double dev = 0;
            if (nd.child < 0) {
                for (int i = nd.first; i < nd.first + nd.count; ++i)
                    if (leaves_[i].flux[c] > 0) dev = std::max(dev, length(leaf_shift_[i].s[c] - ns.mean[c]));
            } else {
                for (int j = nd.child; j < nd.child + nd.children; ++j)
                    if (flux[j][c] > 0)
                        dev = std::max(dev, length(node_shift_[j].mean[c] - ns.mean[c]) + node_shift_[j].dev[c]);
            }
            ns.dev[c] = std::min(dev, 2.0 * spread);
        }
        ns.spread = spread;
        ns.reach = tmax * spread;
        flux[k] = f;
    }
}

int PointCloud::lookup_level_shifted(const Vec3& x) const {
    int level = lookup_level(x);
    if (leaf_shift_.empty() || level_of_.empty()) return level;
    const int i = nearest(x);
    if (i < 0) return level;
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 2; ++k) {
            const Vec3 s = leaf_shift_[i].s[c] * kSmearT[k];
            if (dot(s, s) > 0) level = std::min(level, lookup_level(x - s));
        }
    return level;
}

double PointCloud::max_spacing_within(int start, const float* lo, const float* hi, double radius, double above) const {
    // The largest spacing above `above` among points within `radius` of the box [lo, hi]
    // (nodes are pruned by the box widened by `radius` in each axis, points by distance).
    double best = above;
    if (nodes_.empty()) return best;
    const double r2 = radius * radius;
    const double qlo[3] = {lo[0] - radius, lo[1] - radius, lo[2] - radius};
    const double qhi[3] = {hi[0] + radius, hi[1] + radius, hi[2] + radius};
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = start;
    while (top > 0) {
        const int k = stack[--top];
        const Node& nd = nodes_[k];
        if (!(aux_[k].max_spacing > best) || nd.hi[0] < qlo[0] || nd.lo[0] > qhi[0] || nd.hi[1] < qlo[1] ||
            nd.lo[1] > qhi[1] || nd.hi[2] < qlo[2] || nd.lo[2] > qhi[2])
            continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                if (!(points_[i].spacing > best) || !(points_[i].irradiance.max_component() > 0)) continue;
                const Vec3& p = points_[i].p;
                const double dx = std::max({double(lo[0]) - p.x, 0.0, p.x - double(hi[0])});
                const double dy = std::max({double(lo[1]) - p.y, 0.0, p.y - double(hi[1])});
                const double dz = std::max({double(lo[2]) - p.z, 0.0, p.z - double(hi[2])});
                if (dx * dx + dy * dy + dz * dz < r2) best = points_[i].spacing;
            }
            continue;
        }
        for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
    }
    return best;
}

int PointCloud::nearest(const Vec3& x) const {
    int best = -1;
    if (nodes_.empty()) return best;  // (an unbounded object's or an unlit one's cloud has no points)
    double best_d2 = kInf;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& nd = nodes_[stack[--top]];
        if (!(box_distance2(x, nd.lo, nd.hi) < best_d2)) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Vec3 v = points_[i].p - x;
                const double d2 = dot(v, v);
                if (d2 < best_d2) {
                    best_d2 = d2;
                    best = i;
                }
            }
            continue;
        }
        // Push the children farthest first, so the nearest is opened first and prunes the rest.
        int order[8];
        double dist[8];
        for (int k = 0; k < nd.children; ++k) {
            order[k] = nd.child + k;
            dist[k] = box_distance2(x, nodes_[order[k]].lo, nodes_[order[k]].hi);
        }
        for (int a = 1; a < nd.children; ++a)
            for (int b = a; b > 0 && dist[b] > dist[b - 1]; --b) {
                std::swap(dist[b], dist[b - 1]);
                std::swap(order[b], order[b - 1]);
            }
        for (int k = 0; k < nd.children; ++k) stack[top++] = order[k];
    }
    return best;
}

int PointCloud::lookup_level(const Vec3& x) const {
    if (level_of_.empty() || nodes_.empty()) return 0;
    // Down the octants that hold x until a node whose points share one level; where x's
    // octant is empty or a leaf is mixed, the nearest point decides.
    int k = 0;
    for (;;) {
        const Node& nd = nodes_[k];
        if (nd.uniform >= 0) return nd.uniform;
        if (nd.child < 0) break;
        const Vec3& c = aux_[k].split;
        const int oct = int(x.x >= c.x) | (int(x.y >= c.y) << 1) | (int(x.z >= c.z) << 2);
        int next = -1;
        for (int i = nd.child; i < nd.child + nd.children; ++i)
            if (nodes_[i].octant == oct) next = i;
        if (next < 0) break;
        k = next;
    }
    const int i = nearest(x);
    return i < 0 ? 0 : level_of_[i];
}

template <class Pred>
bool PointCloud::any_lit_within(const Vec3& y, double radius, Pred pred) const {
    if (nodes_.empty()) return false;
    const double r2 = radius * radius;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& nd = nodes_[stack[--top]];
        if (!nd.lit || !(box_distance2(y, nd.lo, nd.hi) <= r2)) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Vec3 v = leaves_[i].p - y;
                if (dot(v, v) <= r2 && pred(i)) return true;
            }
            continue;
        }
        for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
    }
    return false;
}

bool PointCloud::lit_within(const Vec3& x, double radius) const {
    return any_lit_within(x, radius, [&](int i) { return leaves_[i].flux.max_component() > 0; });
}

bool PointCloud::brighter_within(const Vec3& y, double radius, const Vec3& facing, const Rgb& scale,
                                 const Rgb& bound) const {
    return any_lit_within(y, radius, [&](int i) {
        const SurfacePoint& q = points_[i];
        if (!(dot(q.n, facing) > 0)) return false;
        for (int c = 0; c < 3; ++c)
            if (q.irradiance[c] * scale[c] > bound[c]) return true;
        return false;
    });
}

CloudStats PointCloud::stats() const {
    CloudStats s;
    s.points = points_.size();
    s.nodes = nodes_.size();
    s.levels = levels_.size();
    s.finest_spacing = levels_.empty() ? spacing_ : levels_.back().h;
    for (const SurfacePoint& p : points_) s.total_area += p.area;
    return s;
}

}  // namespace shading
