// Hierarchical dipole subsurface scattering over sampled surface points; see subsurface.h.
#include "shading/subsurface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "shading/finish.h"

namespace shading {

namespace {

std::atomic<std::size_t> g_clouds{0}, g_points{0}, g_lookups{0}, g_visited{0};
std::atomic<std::int64_t> g_build_ns{0};
std::atomic<std::size_t> g_unbounded{0}, g_thin{0};

double box_distance(const Vec3& x, const Vec3& lo, const Vec3& hi) {
    double dx = std::max({lo.x - x.x, 0.0, x.x - hi.x});
    double dy = std::max({lo.y - x.y, 0.0, x.y - hi.y});
    double dz = std::max({lo.z - x.z, 0.0, x.z - hi.z});
    return std::sqrt(dx * dx + dy * dy + dz * dz);
}

constexpr int kLeafSize = 8;
constexpr int kMaxDepth = 48;

}  // namespace

SubsurfaceStats subsurface_stats() {
    SubsurfaceStats s;
    s.clouds = g_clouds.load();
    s.points = g_points.load();
    s.lookups = g_lookups.load();
    s.nodes_visited = g_visited.load();
    s.build_seconds = double(g_build_ns.load()) * 1e-9;
    s.unbounded = g_unbounded.load();
    s.thin = g_thin.load();
    return s;
}

void subsurface_note_unbounded() { ++g_unbounded; }
void subsurface_note_thin() { ++g_thin; }

// ---------------------------------------------------------------- RdProfile

namespace {
double smallest_depth(const Dipole& dipole, double r_max) {
    double r_s = r_max;
    for (int c = 0; c < 3; ++c)
        if (!dipole.channel(c).empty) r_s = std::min(r_s, dipole.channel(c).zr);
    return r_s;
}
}  // namespace

RdProfile::RdProfile(const Dipole& dipole, double r_max, int nodes)
    : RdProfile([&dipole](double r) { return dipole.rd(r); }, smallest_depth(dipole, r_max), r_max, nodes) {}

RdProfile::RdProfile(const std::function<Rgb(double)>& rd, double r_s, double r_max, int nodes) : r_max_(r_max) {
    if (!(r_max > 0) || !std::isfinite(r_max) || nodes < 2) throw std::invalid_argument("RdProfile: bad range");
    r_s_ = r_s > 0 && r_s < r_max ? r_s : r_max;
    const double L = std::log1p(r_max / r_s_);
    inv_step_ = nodes / L;
    f_.resize(nodes + 1);
    d1_.resize(nodes + 1);
    d2_.resize(nodes + 1);
    for (int i = 0; i <= nodes; ++i) {
        const double r = r_s_ * std::expm1(L * i / nodes);
        // Derivatives by central differences, step 1e-3 of the local scale r + r_s; below
        // r = e the even extension of Rd (a function of |r|) supplies the point at r - e.
        const double e = 1e-3 * (r + r_s_);
        const Rgb f0 = rd(r), fp = rd(r + e), fm = rd(std::fabs(r - e));
        f_[i] = f0;
        for (int k = 0; k < 3; ++k) {
            d1_[i][k] = (fp[k] - fm[k]) / (2 * e);
            d2_[i][k] = (fp[k] - 2 * f0[k] + fm[k]) / (e * e);
        }
    }
}

Rgb RdProfile::rd(double r) const {
    if (!(r < r_max_)) return Rgb(0.0);
    const double x = index(std::max(0.0, r));
    const std::size_t i = std::min(std::size_t(x), f_.size() - 2);
    const double u = x - double(i);
    return f_[i] * (1.0 - u) + f_[i + 1] * u;
}

void RdProfile::eval(double r, Rgb* f, Rgb* d1, Rgb* d2) const {
    if (!(r < r_max_)) {
        *f = *d1 = *d2 = Rgb(0.0);
        return;
    }
    const double x = index(std::max(0.0, r));
    const std::size_t i = std::min(std::size_t(x), f_.size() - 2);
    const double u = x - double(i), v = 1.0 - u;
    *f = f_[i] * v + f_[i + 1] * u;
    *d1 = d1_[i] * v + d1_[i + 1] * u;
    *d2 = d2_[i] * v + d2_[i + 1] * u;
}

// ---------------------------------------------------------------- PointCloud

PointCloud::PointCloud(std::vector<SurfacePoint> points, double spacing, const Rgb& near)
    : spacing_(spacing), near_(near), points_(std::move(points)) {
    if (!points_.empty()) {
        nodes_.reserve(points_.size() / 2 + 1);
        nodes_.emplace_back();
        build(0, 0, int(points_.size()), 0);
    }
}

void PointCloud::build(int index, int first, int count, int depth) {
    Node nd;
    nd.first = first;
    nd.count = count;
    nd.lo = nd.hi = points_[first].p;
    Vec3 weighted, plain;
    double wsum = 0;
    for (int i = first; i < first + count; ++i) {
        const SurfacePoint& s = points_[i];
        nd.lo = Vec3(std::min(nd.lo.x, s.p.x), std::min(nd.lo.y, s.p.y), std::min(nd.lo.z, s.p.z));
        nd.hi = Vec3(std::max(nd.hi.x, s.p.x), std::max(nd.hi.y, s.p.y), std::max(nd.hi.z, s.p.z));
        Rgb f = s.irradiance * s.area;
        nd.flux += f;
        nd.area += s.area;
        double w = f.r + f.g + f.b;
        weighted = weighted + s.p * w;
        plain = plain + s.p * s.area;
        wsum += w;
    }
    // The flux-weighted centre is where an aggregate's light comes from; an unlit node has
    // no flux to place, its area-weighted centre is used.
    nd.centre = wsum > 0 ? weighted * (1.0 / wsum) : (nd.area > 0 ? plain * (1.0 / nd.area) : nd.lo);
    if (wsum > 0) {
        for (int i = first; i < first + count; ++i) {
            const SurfacePoint& s = points_[i];
            Rgb f = s.irradiance * s.area;
            const double w = (f.r + f.g + f.b) / wsum;
            const Vec3 d = s.p - nd.centre;
            nd.cov[0] += w * d.x * d.x;
            nd.cov[1] += w * d.y * d.y;
            nd.cov[2] += w * d.z * d.z;
            nd.cov[3] += w * d.x * d.y;
            nd.cov[4] += w * d.x * d.z;
            nd.cov[5] += w * d.y * d.z;
        }
    }
    nd.diagonal = length(nd.hi - nd.lo);
    nodes_[index] = nd;
    if (count <= kLeafSize || depth >= kMaxDepth || nd.diagonal == 0.0) return;  // leaf

    // Split into octants about the box centre (in place), keep the non-empty ones.
    const Vec3 c = (nd.lo + nd.hi) * 0.5;
    auto begin = points_.begin() + first, end = begin + count;
    auto mz = std::partition(begin, end, [&](const SurfacePoint& s) { return s.p.z < c.z; });
    auto my0 = std::partition(begin, mz, [&](const SurfacePoint& s) { return s.p.y < c.y; });
    auto my1 = std::partition(mz, end, [&](const SurfacePoint& s) { return s.p.y < c.y; });
    auto split_x = [&](std::vector<SurfacePoint>::iterator a, std::vector<SurfacePoint>::iterator b) {
        return std::partition(a, b, [&](const SurfacePoint& s) { return s.p.x < c.x; });
    };
    auto mx0 = split_x(begin, my0), mx1 = split_x(my0, mz), mx2 = split_x(mz, my1), mx3 = split_x(my1, end);
    const std::vector<SurfacePoint>::iterator bounds[9] = {begin, mx0, my0, mx1, mz, mx2, my1, mx3, end};
    int ranges[8][2], n = 0;
    for (int k = 0; k < 8; ++k) {
        int a = int(bounds[k] - points_.begin()), b = int(bounds[k + 1] - points_.begin());
        if (b > a) {
            ranges[n][0] = a;
            ranges[n][1] = b - a;
            ++n;
        }
    }
    if (n <= 1) return;  // cannot split further (all on one side of every plane): a leaf
    const int child = int(nodes_.size());
    nodes_.resize(nodes_.size() + n);
    nodes_[index].child = child;
    nodes_[index].children = n;
    for (int k = 0; k < n; ++k) build(child + k, ranges[k][0], ranges[k][1], depth + 1);
}

double PointCloud::window(double r, double r0, double h) {
    double t = (r - (r0 - h)) / (2.0 * h);
    if (t <= 0) return 0.0;
    if (t >= 1) return 1.0;
    return t * t * (3.0 - 2.0 * t);
}

Rgb PointCloud::far_exitance(const RdProfile& rd, const Vec3& x, double r0, double h, double max_angle,
                             double cutoff, std::size_t* visited) const {
    Rgb sum;
    if (nodes_.empty()) return sum;
    std::size_t opened = 0;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& nd = nodes_[stack[--top]];
        ++opened;
        // Unlit nodes (shadowed, facing away from every light) bring nothing.
        if (!(nd.flux.max_component() > 0)) continue;
        const double dbox = box_distance(x, nd.lo, nd.hi);
        if (dbox > cutoff) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const SurfacePoint& s = points_[i];
                const double r = length(x - s.p);
                const double w = window(r, r0, h);
                if (w > 0 && r <= cutoff) sum += rd.rd(r) * s.irradiance * (s.area * w);
            }
            continue;
        }
        const double dc = length(x - nd.centre);
        // Aggregate only nodes wholly beyond the window's ramp (w = 1 for all their points).
        if (dbox > r0 + h && nd.diagonal < max_angle * dc) {
            // f(|x - p|) averaged over the node ~ f(d) + (1/2) tr(H Sigma), H the Hessian in p:
            // f'' u u^T + (f'/d)(I - u u^T), u = (c - x)/d (f' and f'' tabulated with f).
            const Vec3 u = (nd.centre - x) * (1.0 / dc);
            const double* C = nd.cov;
            const double uCu = u.x * (C[0] * u.x + C[3] * u.y + C[4] * u.z) +
                               u.y * (C[3] * u.x + C[1] * u.y + C[5] * u.z) +
                               u.z * (C[4] * u.x + C[5] * u.y + C[2] * u.z);
            const double trace = C[0] + C[1] + C[2];
            Rgb f0, f1, f2;
            rd.eval(dc, &f0, &f1, &f2);
            Rgb avg;
            for (int k = 0; k < 3; ++k)
                avg[k] = std::max(0.0, f0[k] + 0.5 * (f2[k] * uCu + f1[k] / dc * (trace - uCu)));
            sum += avg * nd.flux;
            continue;
        }
        for (int k = 0; k < nd.children; ++k) stack[top++] = nd.child + k;
    }
    if (visited) *visited += opened;
    return sum;
}

Rgb PointCloud::far_exitance_exact(const Dipole& dipole, const Vec3& x, double r0, double h) const {
    Rgb sum;
    for (const SurfacePoint& s : points_) {
        const double r = length(x - s.p);
        const double w = window(r, r0, h);
        if (w > 0) sum += dipole.rd(r) * s.irradiance * (s.area * w);
    }
    return sum;
}

CloudStats PointCloud::stats() const {
    CloudStats s;
    s.points = points_.size();
    s.nodes = nodes_.size();
    for (const SurfacePoint& p : points_) s.total_area += p.area;
    return s;
}

// ---------------------------------------------------------------- Subsurface

struct Subsurface::Entry {
    std::once_flag once;
    std::shared_ptr<const PointCloud> cloud;
};

Subsurface::Subsurface(const Medium& medium, const SubsurfaceSettings& settings, FdrModel fdr)
    : dipole_(medium, fdr), settings_(settings) {
    model_ = std::make_shared<DipoleRadialProfile>(dipole_);
    init();
}

Subsurface::Subsurface(const Medium& medium, const SubsurfaceSettings& settings, std::shared_ptr<const RadialProfile> model)
    : dipole_(medium), settings_(settings), model_(std::move(model)) {
    if (!model_) model_ = std::make_shared<DipoleRadialProfile>(dipole_);
    init();
}

void Subsurface::init() {
    if (!(settings_.max_angle > 0 && settings_.max_angle <= 2.0))
        throw std::invalid_argument("dipole: error threshold must be in (0, 2], got " + std::to_string(settings_.max_angle));
    if (!(settings_.spacing >= 0) || !std::isfinite(settings_.spacing))
        throw std::invalid_argument("dipole: spacing must be >= 0 (0: automatic)");
    cutoff_ = model_->cutoff();
    const RadialProfile* m = model_.get();
    if (auto d = dynamic_cast<const DipoleRadialProfile*>(m)) {
        profile_ = std::make_unique<RdProfile>(d->dipole(), cutoff_ > 0 ? cutoff_ : 1.0);
        transmit_handle_ = finish_model_register(make_finish_model(std::make_shared<TransmittanceBrdf>(dipole_.medium().eta)));
    } else {
        profile_ = std::make_unique<RdProfile>([m](double r) { return m->rd(r); }, m->mean_free_path(), cutoff_ > 0 ? cutoff_ : 1.0);
        transmit_handle_ = finish_model_register(make_finish_model(std::make_shared<ProfileTransmittanceBrdf>(model_)));
    }
}

Subsurface::~Subsurface() { finish_model_release(transmit_handle_); }

double Subsurface::mean_free_path() const { return model_->mean_free_path(); }

double Subsurface::sample_spacing(double extent) const {
    if (settings_.spacing > 0) return settings_.spacing;
    double fine = 0.5 * mean_free_path();
    double cap = extent / std::max(1, settings_.max_lines);
    double h = std::max(fine, cap);
    return h > 0 ? h : 1.0;
}

const PointCloud& Subsurface::cloud(const void* key,
                                    const std::function<std::vector<SurfacePoint>(double*)>& make_points) const {
    std::shared_ptr<Entry> e;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        auto& slot = entries_[key];
        if (!slot) slot = std::make_shared<Entry>();
        e = slot;
    }
    std::call_once(e->once, [&] {
        auto t0 = std::chrono::steady_clock::now();
        double h = 0;
        std::vector<SurfacePoint> pts = make_points(&h);
        if (!(h > 0)) h = 1.0;
        auto cloud = std::make_shared<const PointCloud>(std::move(pts), h, near_reflectance(h));
        g_clouds += 1;
        g_points += cloud->points().size();
        g_build_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
        e->cloud = std::move(cloud);
    });
    return *e->cloud;
}

Rgb Subsurface::near_reflectance(double h) const {
    // (1 - w) = 1 below R0 - h: the closed-form disc integral; over the ramp, Simpson.
    const double r0 = near_radius(h), a = std::max(0.0, r0 - h), b = r0 + h;
    Rgb sum = model_->rd_disc(a);
    const int n = 256;
    const double step = (b - a) / n;
    for (int i = 0; i <= n; ++i) {
        const double r = a + i * step;
        const double wt = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
        sum += model_->rd(r) * ((1.0 - PointCloud::window(r, r0, h)) * 2.0 * kPi * r * wt * step / 3.0);
    }
    return sum;
}

Rgb Subsurface::radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                         const Rgb& irradiance_here) const {
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0)) return Rgb(0.0);
    const double h = cloud.spacing(), r0 = near_radius(h);
    std::size_t visited = 0;
    Rgb m = cloud.far_exitance(*profile_, x, r0, h, settings_.max_angle, cutoff_, &visited);
    g_lookups += 1;
    g_visited += visited;
    m += irradiance_here * cloud.near_reflectance();
    return m * model_->exit_factor(cos_o);
}

// ---------------------------------------------------------------- BRDFs

Rgb TransmittanceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return Rgb(fresnel_transmittance(wi.z, eta_) * kInvPi);
}
std::string TransmittanceBrdf::describe() const { return "transmittance(eta=" + std::to_string(eta_) + ")"; }

Rgb ProfileTransmittanceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return model_->entry_factor(wi.z) * kInvPi;
}
std::string ProfileTransmittanceBrdf::describe() const { return "transmittance(" + model_->describe() + ")"; }

DipoleSurfaceBrdf::DipoleSurfaceBrdf(std::shared_ptr<const Subsurface> s, BrdfPtr coat)
    : s_(std::move(s)), coat_(std::move(coat)) {
    if (!s_) throw std::invalid_argument("DipoleSurfaceBrdf: no subsurface");
}
Rgb DipoleSurfaceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    Rgb v = s_->settings().single_scatter ? s_->dipole().single_scatter_brdf(wo, wi) : Rgb(0.0);
    if (coat_) v += coat_->f(wo, wi);
    return v;
}
std::string DipoleSurfaceBrdf::describe() const {
    return std::string("dipole(") + (s_->settings().single_scatter ? "single scattering" : "no single scattering") +
           (coat_ ? ", coat " + coat_->describe() : "") + ")";
}

}  // namespace shading
