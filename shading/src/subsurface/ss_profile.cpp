// Evaluating the exact-profile tables for one channel (ChannelProfile) and inverting them
// (alpha_prime_for_total); see ss_profile.h. Building them: ss_profile_build.cpp; the file:
// ss_profile_io.cpp.
#include "shading/subsurface/ss_profile.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "shading/brdf/fresnel.h"
#include "shading/subsurface/ss_profile_curve.h"
#include "shading/subsurface/transport_mc.h"

namespace shading {

using namespace ss_detail;

namespace {

// Critical inside cosine of a face: light inside with mu below it is totally reflected.
double critical_cos(double eta) { return eta > 1.0 ? std::sqrt(1.0 - 1.0 / (eta * eta)) : 0.0; }

// The transport's asymptotic decay rate per mean free path at albedo alpha and g
// (transport_decay_rate: an eigenvalue problem of some 400 moments), kept per (alpha, g): a slab
// cache builds many profiles from the same few records.
double decay_per_mfp(double alpha, double g) {
    static std::mutex mutex;
    static std::map<std::pair<double, double>, double> known;
    std::lock_guard<std::mutex> lock(mutex);
    auto [it, fresh] = known.try_emplace({alpha, g}, 0.0);
    if (fresh) it->second = transport_decay_rate(alpha, g);
    return it->second;
}

// Cubic Lagrange weights on up to 4 nodes around x (fewer near the ends or on small grids);
// exact at the nodes, x clamped to the axis.
std::vector<std::pair<int, double>> axis_weights(const std::vector<double>& axis, double x) {
    const int n = int(axis.size());
    if (n == 1) return {{0, 1.0}};
    x = std::clamp(x, axis.front(), axis.back());
    int i = int(std::upper_bound(axis.begin(), axis.end(), x) - axis.begin()) - 1;
    i = std::clamp(i, 0, n - 2);
    // On a node (to a float's precision: POV hands g and the ior over as floats, and g 0.9 read
    // as 0.899999976 took the 4-node stencil, whose g 0.95 node's slab is twice as many mean free
    // paths thick: the tables then held a g 0.9 slab only half as thick as they could).
    for (int j = 0; j < n; ++j)
        if (std::fabs(axis[j] - x) <= 1e-6 * std::max(1.0, std::fabs(x))) return {{j, 1.0}};
    int first = std::max(0, i - 1), last = std::min(n - 1, i + 2);
    std::vector<std::pair<int, double>> w;
    for (int j = first; j <= last; ++j) {
        double l = 1.0;
        for (int m = first; m <= last; ++m)
            if (m != j) l *= (x - axis[m]) / (axis[j] - axis[m]);
        w.push_back({j, l});
    }
    return w;
}

// Catmull-Rom weights on the uniform albedo grid at fractional index s (clamped at the last
// node). Below the first node (s < 0: alpha under 1 - e^-u_0, e.g. Ketchup's green and blue)
// every quantity is continued linearly in u through the first two nodes: multiple scattering
// there is alpha^2 D2 (1 + alpha D3 / D2 + ...), so ln(v / alpha^2) is linear in u ~ alpha to
// first order, and the shape and exit distribution change at the same rate. Holding node 0
// instead rendered Ketchup's blue (alpha' 0.02) 14-17 % too bright (DIPOLE.md 10.3).
std::vector<std::pair<int, double>> albedo_weights(int n, double s) {
    if (s < 0) return {{0, 1.0 - s}, {1, s}};
    s = std::min(s, double(n - 1));
    int i = std::min(int(std::floor(s)), n - 2);
    const double t = s - i;
    if (t == 0) return {{i, 1.0}};
    const double t2 = t * t, t3 = t2 * t;
    double w[4] = {-0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1, -1.5 * t3 + 2 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2};
    std::vector<std::pair<int, double>> out;
    for (int j = 0; j < 4; ++j) {
        int idx = i - 1 + j;
        // ends: mirror the missing neighbour linearly (p[-1] = 2 p0 - p1), i.e. fold its weight
        if (idx < 0) {
            out.push_back({0, 2 * w[j]});
            out.push_back({1, -w[j]});
        } else if (idx > n - 1) {
            out.push_back({n - 1, 2 * w[j]});
            out.push_back({n - 2, -w[j]});
        } else {
            out.push_back({idx, w[j]});
        }
    }
    return out;
}

}  // namespace

std::string ChannelProfile::range_error(const ProfileTables& t, double g, double eta, double thickness) {
    const ProfileBuildSettings& s = t.settings;
    if (!(g >= s.g.front() - 1e-6 && g <= s.g.back() + 1e-6))
        return "g = " + num(g) + " is outside the tables' range [" + num(s.g.front()) + ", " + num(s.g.back()) + "]";
    if (!(eta >= s.eta.front() - 1e-6 && eta <= s.eta.back() + 1e-6))
        return "ior = " + num(eta) + " is outside the tables' range [" + num(s.eta.front()) + ", " + num(s.eta.back()) + "]";
    if (thickness == kInf) {
        if (s.thickness.back() != kInf) return "the tables have no semi-infinite node";
    } else {
        if (!(thickness > 0)) return "thickness = " + num(thickness) + ": expected > 0 transport mfp";
        if (s.thickness.front() == kInf) return "the tables have no slabs";
    }
    return "";
}

ChannelProfile::ChannelProfile(const ProfileTables& t, double alpha_prime, double g, double eta, double thickness, int face)
    : alpha_prime_(alpha_prime), eta_(eta) {
    const std::string err = range_error(t, g, eta, thickness);
    if (!err.empty()) throw std::invalid_argument("exact profile: " + err);
    if (!(alpha_prime >= 0 && alpha_prime <= 1)) throw std::invalid_argument("exact profile: reduced albedo outside [0, 1]");
    if (face < 0 || face >= t.faces) throw std::invalid_argument("exact profile: these tables have no transmission face");
    const ProfileBuildSettings& s = t.settings;
    const int nb = s.bins.count, nci = int(s.cos_inside.size());

    // Node weights: g and eta cubic Lagrange; the thickness (transport mfp, like the radii) is
    // converted per g node to the tables' mean free paths, d / (1 - alpha g), then linear in ln d
    // between the two finite nodes around it. The light through a slab falls as e^(-kappa d) once
    // it is a few of its own diffusion lengths thick (kappa: transport_decay_rate), and ln T,
    // linear in d there, is concave in ln d: between nodes sqrt(2) apart (the forward file) linear
    // in ln d read T low by about 1.5 % x kappa d (Skin1's blue seen through 7.7 mfp' at g 0.9:
    // -8.8 % against the Monte Carlo at that thickness, the nodes on both sides within 2.2 %). So
    // the transmitted total is interpolated as ln T + kappa d (kappa each record's own, at its
    // albedo and g), which is flat in a thick slab and, where kappa d is small, ln T itself.
    // The transmitted exit distribution (the inside radiance's samples) is cubic Lagrange in ln d
    // over four nodes: the light through a forward-scattering sheet a few mfp thick peaks at the
    // normal, and that peak falls faster than exponentially with thickness (the low orders leave
    // it), so between nodes sqrt(2) apart read linearly it was high: Skin1's red at g 0.9 through
    // 9.6 mfp, pi L / M at the normal 2.007 against 1.910 from a node built there (1.938 cubic),
    // and the sheet seen straight through rendered +5.2 % (DIPOLE.md 10.3). The reflected face's
    // stays linear: read cubic, a 0.25 mfp' sheet's lit side moved by -1 to -1.7 %, away from the
    // reference (400 000 paths, noise 1.1 %) and within the nodes' noise of a node built there.
    auto wg = axis_weights(s.g, g), we = axis_weights(s.eta, eta);
    std::vector<double> lnd;
    for (double d : s.thickness)
        if (d != kInf) lnd.push_back(std::log(d));
    auto thickness_weights = [&](double alpha, double gn, bool cubic) -> std::vector<std::pair<int, double>> {
        if (thickness == kInf) return {{int(s.thickness.size()) - 1, 1.0}};
        const double x = std::log(thickness / (1.0 - alpha * gn));
        if (!(x >= lnd.front() - 1e-9 && x <= lnd.back() + 1e-9))
            throw std::invalid_argument("exact profile: thickness " + num(thickness) + " transport mfp (" + num(std::exp(x)) +
                                        " mfp at g = " + num(gn) + ") is outside the tables' slabs [" + num(std::exp(lnd.front())) +
                                        ", " + num(std::exp(lnd.back())) + "] mfp");
        if (lnd.size() == 1) return {{0, 1.0}};
        int i = int(std::upper_bound(lnd.begin(), lnd.end(), x) - lnd.begin()) - 1;
        i = std::clamp(i, 0, int(lnd.size()) - 2);
        const double f = std::clamp((x - lnd[i]) / (lnd[i + 1] - lnd[i]), 0.0, 1.0);
        if (!cubic) return {{i, 1 - f}, {i + 1, f}};
        return axis_weights(lnd, x);
    };

    rho_.resize(nb);
    for (int b = 0; b < nb; ++b) rho_[b] = t.node_rho(b);
    lnv_.assign(nb, 0.0);
    angle_.assign(129, 0.0);  // inside radiance at mu' = mu_c + (1 - mu_c) j / 128 (this channel's eta)
    incidence_.assign(nci, 0.0);
    shift_.assign(nci, 0.0);
    ci_ = s.cos_inside;
    double ln_total = 0, single = 0, ballistic = 0, tail_k = 0, wsum_total = 0, own_flux = 0;
    const double mu_c = critical_cos(eta);
    // Every record is read at the same cosines: the Lagrange bases once (bit for bit the
    // polynomial's values), the exit sums' per eta node.
    std::vector<double> angle_mu(129);
    for (int j = 0; j <= 128; ++j) angle_mu[std::size_t(j)] = mu_c + (1 - mu_c) * j / 128.0;
    const AngleBasis angle_basis(s.angle_nodes, angle_mu);
    const int B = thickness == kInf && face == 0 ? s.band_count() : 0;
    band_rho_.assign(std::size_t(B), 0.0);
    band_ratio_.assign(std::size_t(B) * s.angle_nodes, 0.0);
    band_nodes_ = std::size_t(s.angle_nodes);
    // Oblique exits (semi-infinite reflection only): as angle_, per oblique inside cosine and azimuth.
    const int A = thickness == kInf && face == 0 ? s.oblique_azimuths : 0;
    oblique_azimuths_ = A;
    oblique_.assign(A > 0 ? std::size_t(nci - 1) * A * 129 : 0, 0.0);
    std::vector<double> slice(std::size_t(s.angle_nodes));
    std::vector<ExitSum> exit_sums;
    for (auto [ie, w2] : we) exit_sums.emplace_back(s.angle_nodes, s.eta[ie]);
    for (auto [ig, w1] : wg) {
        const double gn = s.g[ig];
        // The node's albedo at the same reduced albedo: alpha' = alpha (1 - g) / (1 - alpha g).
        const double alpha = alpha_prime / (1.0 - gn + alpha_prime * gn);
        // One pass over the nodes of either stencil, each with its two weights (id, linear, cubic).
        std::vector<std::array<double, 3>> wd;
        for (auto [id, wl] : thickness_weights(alpha, gn, false)) wd.push_back({double(id), wl, 0.0});
        for (auto [id, wc] : thickness_weights(alpha, gn, face == 1)) {
            auto at = std::find_if(wd.begin(), wd.end(), [&](const auto& n) { return int(n[0]) == id; });
            if (at == wd.end()) wd.push_back({double(id), 0.0, wc});
            else (*at)[2] = wc;
        }
        const double d_mfp = thickness / (1.0 - alpha * gn);  // the tables' mean free paths at this g
        for (std::size_t ke = 0; ke < we.size(); ++ke)
            for (const auto& node : wd) {
                const int id = int(node[0]);
                const auto [ie, w2] = we[ke];
                const double w = w1 * w2 * node[1], w_angle = w1 * w2 * node[2];
                const double u = alpha < 1.0 ? -std::log1p(-alpha) : 1e300;
                // Multiple scattering goes as alpha^2 for small alpha: the profile values and the
                // total are interpolated as ln(v / alpha^2) (smooth in u down to alpha = 0, and
                // continued linearly below the first node: albedo_weights).
                const double sidx = (u - s.u_0) / s.u_step;
                const double ln_a2 = alpha > 0 ? 2.0 * std::log(alpha) : std::log(kTiny);
                for (auto [k, wk] : albedo_weights(s.albedos, sidx)) {
                    const FaceRecord& r = t.record(ig, ie, id, face, k);
                    if (r.angle.size() != std::size_t(s.angle_nodes))
                        throw std::logic_error("exact profile: a record's angle samples differ from the tables' count");
                    const double ww = w * wk, ww_angle = w_angle * wk;
                    const double ln_scale = ln_a2 - 2.0 * std::log(t.albedo(k));
                    // (the same shift for the radial profile's nodes would leave its shape as it
                    // is: it is scaled to the total below)
                    const double decay = face == 1 && thickness != kInf
                                             ? decay_per_mfp(t.albedo(k), gn) * (s.thickness[std::size_t(id)] - d_mfp)
                                             : 0.0;
                    ln_total += ww * (std::log(std::max(r.multi, kTiny)) + ln_scale + decay);
                    wsum_total += ww;
                    single += ww * r.single;
                    ballistic += ww * r.ballistic;
                    tail_k += ww * r.tail_k;
                    for (int b = 0; b < nb; ++b) lnv_[b] += ww * (std::log(std::max(r.profile[b], kTiny)) + ln_scale);
                    for (int j = 0; j < nci; ++j) incidence_[j] += ww * r.incidence[j];
                    for (int j = 0; j < nci && j < int(r.shift.size()); ++j) shift_[j] += ww * r.shift[j];
                    if (ww_angle != 0)
                        for (int j = 0; j <= 128; ++j) angle_[j] += ww_angle * angle_basis.value(r.angle, std::size_t(j));
                    if (B > 0 && (r.band_rho.size() != std::size_t(B) || r.band_ratio.size() != band_ratio_.size()))
                        throw std::logic_error("exact profile: a record's distance bands differ from the tables' count");
                    if (A > 0 && r.oblique.size() != std::size_t(nci - 1) * A * s.angle_nodes)
                        throw std::logic_error("exact profile: a record's oblique exits differ from the tables' count");
                    for (std::size_t ia = 0; ia < std::size_t(A > 0 ? (nci - 1) * A : 0); ++ia) {
                        std::copy_n(r.oblique.begin() + std::ptrdiff_t(ia * s.angle_nodes), s.angle_nodes, slice.begin());
                        for (int j = 0; j <= 128; ++j) oblique_[ia * 129 + std::size_t(j)] += ww * angle_basis.value(slice, std::size_t(j));
                    }
                    for (int b = 0; b < B; ++b) band_rho_[b] += ww * r.band_rho[b];
                    for (std::size_t i = 0; i < band_ratio_.size(); ++i) band_ratio_[i] += ww * r.band_ratio[i];
                    // 2 integral_0^1 Ft(mu_o) I(mu'(mu_o)) / eta^2 mu_o dmu_o of the stored samples
                    // pi I / M: the exit distribution's integral (1 up to the interpolant's error).
                    if (ww_angle != 0) own_flux += ww_angle * exit_sums[ke](r.angle) / (s.eta[ie] * s.eta[ie]);
                }
            }
    }
    (void)wsum_total;
    total_ = std::exp(ln_total);
    if (total_ < 1e-30) total_ = 0;
    single_ = std::max(0.0, single);
    ballistic_ = std::max(0.0, ballistic);
    tail_k_ = std::max(0.0, tail_k);
    for (double& v : angle_) v = std::max(0.0, v);
    for (double& v : incidence_) v = std::max(0.0, v);
    for (double& v : shift_) v = std::max(0.0, v);
    for (double& v : band_ratio_) v = std::max(0.0, v);
    for (double& v : oblique_) v = std::max(0.0, v);
    // mean distances: increasing and > 0 (a mix of records keeps them so but for rounding)
    for (std::size_t b = 0; b < band_rho_.size(); ++b)
        band_rho_[b] = std::max(band_rho_[b], b ? band_rho_[b - 1] * (1 + 1e-9) : 1e-9);

    // Disc integrals at the nodes, then the tail beyond the last node (continuous there), then
    // one scale so the profile integrates to the interpolated total.
    RadialCurve c{rho_.data(), lnv_.data(), nb, std::log(10.0) / s.bins.per_decade};
    cum_.assign(nb, 0.0);
    for (int b = 1; b < nb; ++b) cum_[b] = cum_[b - 1] + c.integral_in(b - 1, rho_[b - 1], rho_[b]);
    const double last = rho_[nb - 1];
    tail_a_ = std::exp(lnv_[nb - 1]) / tail_shape(tail_k_, last);
    if (!std::isfinite(tail_a_)) tail_a_ = 0;
    const double whole = cum_[nb - 1] + (tail_a_ > 0 ? tail_a_ * tail_flux(tail_k_, last) : 0.0);
    const double fix = whole > 0 && total_ > 0 ? total_ / whole : 0.0;
    for (double& v : lnv_) v += fix > 0 ? std::log(fix) : std::log(kTiny);
    for (double& v : cum_) v *= fix;
    tail_a_ *= fix;

    // The exit distribution per distance band is tabulated as each band's mean (over its exits)
    // and read as a curve linear in ln rho between the bands' mean distances. Where the ratio
    // changes fast (near the entry point, more so at low albedo and ior 1) that curve's mean
    // over a band, weighted by Rd, is not the band's value: the node values are corrected until
    // it is (12 rounds, each band's mean by 32 steps in ln rho over the profile's own disc integrals).
    // Band edges are in transport mfp of the albedo-1 medium: rho = e / (1 - g + alpha' g).
    // Before (2026-12-05) the rd scene at ior 1 rendered 1.5-6 % too bright within 2 mfp'.
    if (!band_rho_.empty()) {
        const std::size_t B = band_rho_.size(), J = band_nodes_;
        const double scale = 1.0 / (1.0 - g + alpha_prime * g);
        std::vector<double> edge(B + 1, 0.0);
        for (std::size_t b = 0; b + 1 < B; ++b) edge[b + 1] = s.exit_bands[b] * scale;
        edge[B] = edge[B - 1] * 64;
        // Per band the 32 steps' midpoints and Rd flux, once (they do not change between rounds).
        constexpr int kSteps = 32;
        std::vector<double> mid(B * kSteps), flux(B * kSteps);
        for (std::size_t b = 0; b < B; ++b) {
            const double lo = b ? edge[b] : std::min(1e-3, edge[1] * 1e-3), hi = edge[b + 1];
            double below = disc(lo);
            for (int q = 0; q < kSteps; ++q) {
                const double above = disc(lo * std::pow(hi / lo, (q + 1) / double(kSteps)));
                mid[b * kSteps + q] = lo * std::pow(hi / lo, (q + 0.5) / kSteps);
                flux[b * kSteps + q] = above - below;
                below = above;
            }
        }
        const std::vector<double> target = band_ratio_;
        for (int it = 0; it < 12; ++it)
            for (std::size_t j = 0; j < J; ++j)
                for (std::size_t b = 0; b < B; ++b) {
                    double num = 0, den = 0;
                    for (int q = 0; q < kSteps; ++q) {
                        num += flux[b * kSteps + q] * exit_band_ratio(mid[b * kSteps + q], int(j));
                        den += flux[b * kSteps + q];
                    }
                    if (num > 0 && den > 0) band_ratio_[b * J + j] *= target[b * J + j] / (num / den);
                }
    }
    angle_norm_ = 1.0 / (eta * eta);  // radiance leaving = Ft L_inside / eta^2
    // Mixing the inside radiance of nodes at other etas does not keep its exitance: scale it so
    // that the exit distribution integrates to the weighted integrals of the nodes' own (1 up to
    // their interpolants' error; at a node the scale is 1 and the samples stay as measured).
    double mixed = 0;
    const int steps = 512;
    for (int i = 0; i < steps; ++i) mixed += 2.0 * exit_factor((i + 0.5) / steps) * ((i + 0.5) / steps) / steps;
    if (mixed > 0 && own_flux > 0) angle_norm_ *= own_flux / mixed;
    if (incidence_.back() > 0) {
        const double last = incidence_.back();
        for (double& v : incidence_) v /= last;  // exactly 1 at normal incidence
    }
}

int ChannelProfile::segment_of(double rho) const {
    const int n = int(rho_.size());
    if (!(rho > rho_[1])) return 0;
    const double h = std::log(rho_[2] / rho_[1]);
    return std::clamp(1 + int(std::floor(std::log(rho / rho_[1]) / h)), 1, n - 2);
}

double ChannelProfile::rd(double rho) const {
    if (total_ <= 0 || !(rho >= 0)) return 0.0;
    const int n = int(rho_.size());
    if (rho >= rho_[n - 1]) return rho == kInf ? 0.0 : tail_a_ * tail_shape(tail_k_, rho);
    const RadialCurve c{rho_.data(), lnv_.data(), n, std::log(rho_[2] / rho_[1])};
    return c.eval_in(segment_of(rho), rho);
}

double ChannelProfile::segment_integral(int b, double r1, double r2) const {
    const RadialCurve c{rho_.data(), lnv_.data(), int(rho_.size()), std::log(rho_[2] / rho_[1])};
    return c.integral_in(b, r1, r2);
}

double ChannelProfile::disc(double R) const {
    if (total_ <= 0 || !(R > 0)) return 0.0;
    const int n = int(rho_.size());
    if (R >= rho_[n - 1]) {
        if (R == kInf) return total_;
        const double beyond_last = tail_a_ * tail_flux(tail_k_, rho_[n - 1]);
        const double beyond_R = tail_a_ * tail_flux(tail_k_, R);
        return cum_[n - 1] + (beyond_last - beyond_R);
    }
    const int b = segment_of(R);
    return cum_[b] + segment_integral(b, rho_[b], R);
}

double ChannelProfile::annulus_mean(double r1, double r2) const {
    if (!(r2 > r1)) return rd(r1);
    return (disc(r2) - disc(r1)) / (kPi * (r2 * r2 - r1 * r1));
}

double ChannelProfile::radius_containing(double fraction) const {
    if (total_ <= 0) return 0.0;
    if (!(fraction < 1)) return kInf;
    const double want = fraction * total_;
    double lo = 0, hi = rho_[1];
    while (disc(hi) < want) {
        lo = hi;
        hi *= 2;
        if (hi > 1e15) return hi;
    }
    for (int it = 0; it < 200 && hi - lo > 1e-15 * hi; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (disc(mid) >= want) hi = mid;
        else lo = mid;
    }
    return hi;
}

double ChannelProfile::inside_index(double cos_o) const {
    const double mu_c = critical_cos(eta_);
    const double mi = std::sqrt(std::max(0.0, 1.0 - (1.0 - cos_o * cos_o) / (eta_ * eta_)));
    return std::clamp((mi - mu_c) / (1 - mu_c) * 128.0, 0.0, 128.0);
}

double ChannelProfile::exit_factor(double cos_o) const {
    if (!(cos_o > 0)) return 0.0;
    cos_o = std::min(cos_o, 1.0);
    const double ft = 1.0 - fresnel_dielectric(cos_o, eta_);
    if (!(ft > 0)) return 0.0;
    const double x = inside_index(cos_o);
    const int j = std::min(127, int(x));
    const double i = angle_[j] + (angle_[j + 1] - angle_[j]) * (x - j);
    return ft * i * angle_norm_;
}

double ChannelProfile::exit_factor_oblique(double cos_i, double cos_o, double cos_phi) const {
    const int n = int(ci_.size());
    if (oblique_.empty() || n < 2) return exit_factor(cos_o);
    if (!(cos_o > 0)) return 0.0;
    cos_o = std::min(cos_o, 1.0);
    const double ft = 1.0 - fresnel_dielectric(cos_o, eta_);
    if (!(ft > 0)) return 0.0;
    // the entering beam's inside cosine (Snell), and its place among the tables' (the last 1)
    const double c = std::clamp(cos_i, 0.0, 1.0);
    const double ci = std::sqrt(std::max(0.0, 1.0 - (1.0 - c * c) / (eta_ * eta_)));
    if (ci >= ci_.back()) return exit_factor(cos_o);
    int i = 0;
    double f = 0;
    if (ci > ci_.front()) {
        i = std::clamp(int(std::upper_bound(ci_.begin(), ci_.end(), ci) - ci_.begin()) - 1, 0, n - 2);
        f = (ci - ci_[i]) / (ci_[i + 1] - ci_[i]);
    }
    const double x = inside_index(cos_o);
    const int j = std::min(127, int(x));
    const double fx = x - j;
    const int A = oblique_azimuths_;
    const double t = std::acos(std::clamp(cos_phi, -1.0, 1.0)) / kPi * (A - 1);
    const int a = std::min(A - 2, int(t));
    const double fa = t - a;
    auto at = [&](int node) {  // inside radiance of inside-cosine node `node` at (x, azimuth)
        if (node == n - 1) return angle_[j] + (angle_[j + 1] - angle_[j]) * fx;
        const double* p0 = &oblique_[(std::size_t(node) * A + a) * 129];
        const double* p1 = p0 + 129;
        const double v0 = p0[j] + (p0[j + 1] - p0[j]) * fx, v1 = p1[j] + (p1[j + 1] - p1[j]) * fx;
        return v0 + (v1 - v0) * fa;
    };
    const double v = f > 0 ? at(i) * (1 - f) + at(i + 1) * f : at(i);
    return ft * v * angle_norm_;
}

double ChannelProfile::interpolate_inside(const std::vector<double>& v, double cos_o) const {
    if (!(cos_o > 0)) return v.front();
    // Snell: the refracted beam's inside cosine
    const double cos_i = std::sqrt(std::max(0.0, 1.0 - (1.0 - std::min(1.0, cos_o * cos_o)) / (eta_ * eta_)));
    const int n = int(ci_.size());
    if (cos_i <= ci_.front()) return v.front();
    if (cos_i >= ci_.back()) return v.back();
    int i = int(std::upper_bound(ci_.begin(), ci_.end(), cos_i) - ci_.begin()) - 1;
    i = std::clamp(i, 0, n - 2);
    const double f = (cos_i - ci_[i]) / (ci_[i + 1] - ci_[i]);
    return v[i] * (1 - f) + v[i + 1] * f;
}

double ChannelProfile::exit_band_cosine(int j) const { return angle_node(j, int(band_nodes_)); }

double ChannelProfile::exit_band_ratio(double rho, int j) const {
    const std::size_t B = band_rho_.size(), J = band_nodes_;
    if (B == 0) return 1.0;
    auto at = [&](std::size_t b) { return band_ratio_[b * J + std::size_t(j)]; };
    if (!(rho > band_rho_[0])) return at(0);
    if (rho >= band_rho_[B - 1]) return at(B - 1);
    std::size_t b = 0;
    while (rho >= band_rho_[b + 1]) ++b;
    const double t = std::log(rho / band_rho_[b]) / std::log(band_rho_[b + 1] / band_rho_[b]);
    return at(b) + (at(b + 1) - at(b)) * t;
}

double ChannelProfile::entry_factor(double cos_o) const { return interpolate_inside(incidence_, cos_o); }

double ChannelProfile::entry_shift(double cos_o) const { return interpolate_inside(shift_, cos_o); }

double alpha_prime_for_total(const ProfileTables& t, double total, double g, double eta,
                             const std::function<double(double)>& single) {
    auto f = [&](double ap) { return ChannelProfile(t, ap, g, eta).total() + (single ? single(ap) : 0.0); };
    if (!(total > 0)) return 0.0;
    if (total >= f(1.0)) return 1.0;
    double lo = 0.0, hi = 1.0;  // the total rises monotonically with alpha'
    for (int it = 0; it < 60 && hi - lo > 1e-10; ++it) {
        const double mid = 0.5 * (lo + hi);
        (f(mid) < total ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

// ---------------------------------------------------------------- the tables

const FaceRecord& ProfileTables::record(int ig, int ie, int id, int face, int k) const {
    const std::size_t ne = settings.eta.size(), nd = settings.thickness.size();
    const std::size_t i = (((std::size_t(ig) * ne + ie) * nd + id) * faces + face) * settings.albedos + k;
    return records.at(i);
}

double ProfileTables::angle_cosine(int j) const { return angle_node(j, settings.angle_nodes); }

double ProfileTables::node_rho(int b) const {
    return b <= 0 ? 0.0 : std::sqrt(settings.bins.inner(b) * settings.bins.outer(b));
}

}  // namespace shading
