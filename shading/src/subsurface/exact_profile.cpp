// ExactProfile: the tables evaluated per channel in scene units, and its slabs; see
// exact_profile.h.
#include "shading/subsurface/exact_profile.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "shading/core/format.h"
#include "shading/subsurface/rd_profile.h"
#include "shading/subsurface/transport_mc.h"

namespace shading {

using detail::fmt;

namespace {

// Throws std::invalid_argument (named for the file) when the tables were made by another
// generator version than this library's (their values would differ from what the library
// builds; a file's generator is inside its checksum), or are slab tables given as the
// semi-infinite ones.
void check_identity(const ProfileTables& t, bool slabs) {
    const std::string name = t.name.empty() ? std::string(slabs ? "slab tables" : "profile tables") : t.name;
    if (t.generator_version != kProfileGeneratorVersion)
        throw std::invalid_argument(name + ": built by profile generator " + std::to_string(t.generator_version) +
                                    ", this renderer reads generator " + std::to_string(kProfileGeneratorVersion) +
                                    "'s: rebuild it (make brdf-data, or sstool build --if-stale -o FILE)");
    if (!slabs && t.faces != 1)
        throw std::invalid_argument(name + ": expected semi-infinite tables (one face), found slab tables "
                                    "(subsurface_slabs.ssp is the slab file; make brdf-data builds both)");
}

}  // namespace

ExactProfile::ExactProfile(const Medium& m, std::shared_ptr<const ProfileTables> tables,
                           std::shared_ptr<const ProfileTables> slab_tables,
                           std::shared_ptr<const ProfileTables> forward_slab_tables)
    : tables_(std::move(tables)) {
    const std::string bad = m.validate();
    if (!bad.empty()) throw std::invalid_argument("dipole medium: " + bad);
    if (!tables_) throw std::invalid_argument("exact profile: no tables");
    // Tables another generator made, or of another kind than asked for, are never used.
    check_identity(*tables_, false);
    if (slab_tables) check_identity(*slab_tables, true);
    if (forward_slab_tables) check_identity(*forward_slab_tables, true);
    eta_ = m.eta;
    const ProfileBuildSettings& s = tables_->settings;
    const std::string range = ChannelProfile::range_error(*tables_, s.g.front(), m.eta, std::numeric_limits<double>::infinity());
    if (!range.empty()) throw std::invalid_argument("exact profile: " + range + "; use `profile dipole` for this medium");
    const Rgb ssp = m.sigma_s_prime();
    static const char* names[3] = {"r", "g", "b"};
    std::vector<std::pair<double, std::string>> clamped;  // g value, its channels
    for (int c = 0; c < 3; ++c) {
        const double sp = ssp[c], sa = m.sigma_a[c];
        const double st = sp + sa;
        if (!(st > 0) || !(sp > 0)) continue;  // no scattering: nothing diffuses
        double g = m.g[c];
        g_[c] = g;
        const double gc = std::clamp(g, s.g.front(), s.g.back());
        if (gc != g) {
            auto it = std::find_if(clamped.begin(), clamped.end(), [&](const auto& p) { return p.first == g; });
            if (it == clamped.end()) clamped.push_back({g, names[c]});
            else it->second += std::string(", ") + names[c];
        }
        ch_[c] = std::make_unique<ChannelProfile>(*tables_, sp / st, gc, m.eta);
        st_[c] = st * m.mm_per_unit;
        // all but 1e-6 of the channel; without absorption a power-law tail, capped at 1e6 mfp'
        const double r = std::min(ch_[c]->radius_containing(1.0 - 1e-6), 1e6);
        cutoff_ = std::max(cutoff_, r / st_[c]);
    }
    // Slab tables: the first set with every scattering channel's (g, eta) inside it (thickness:
    // per node, slab.h): the isotropic file (more iors and photons), else the forward-scattering
    // one; slab_gap_ says why neither where none does.
    auto gap = [&](const ProfileTables* t) -> std::string {
        if (!t) return "no slab tables";
        if (t->faces < 2) return "the slab tables have no transmission face";
        for (int c = 0; c < 3; ++c)
            if (ch_[c]) {
                std::string e = ChannelProfile::range_error(*t, g_[c], m.eta, 1.0);
                if (!e.empty()) return e;
            }
        return "";
    };
    const std::string gap_iso = gap(slab_tables.get()), gap_forward = gap(forward_slab_tables.get());
    if (gap_iso.empty()) {
        slab_tables_ = std::move(slab_tables);
    } else if (gap_forward.empty()) {
        slab_tables_ = std::move(forward_slab_tables);
    } else {
        slab_gap_ = std::string(kSlabFile) + ": " + gap_iso + "\n  " + kForwardSlabFile + ": " + gap_forward;
    }
    build_exit_weights();
    for (const auto& [g, channels] : clamped) {
        const double gc = std::clamp(g, s.g.front(), s.g.back());
        notes_.push_back("g = " + fmt(g) + " (" + channels + ") is outside the exact profile's tables [" + fmt(s.g.front()) +
                         ", " + fmt(s.g.back()) + "]: the g = " + fmt(gc) + " table is used at the same reduced albedo");
    }
}

Rgb ExactProfile::rd(double r) const {
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = st_[c] * st_[c] * ch_[c]->rd(r * st_[c]);
    return v;
}

Rgb ExactProfile::rd_disc(double R) const {
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ch_[c]->disc(R * st_[c]);
    return v;
}

Rgb ExactProfile::total() const {
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ch_[c]->total();
    return v;
}

double ExactProfile::mean_free_path() const {
    double l = 0;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) l = l == 0 ? 1.0 / st_[c] : std::min(l, 1.0 / st_[c]);
    return l;
}

Rgb ExactProfile::exit_factor(double cos_o) const {
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ch_[c]->exit_factor(cos_o);
    return v;
}

Rgb ExactProfile::exit_factor_oblique(double cos_i, double cos_o, double cos_phi) const {
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ch_[c]->exit_factor_oblique(cos_i, cos_o, cos_phi);
    return v;
}

bool ExactProfile::oblique_exits() const {
    for (int c = 0; c < 3; ++c)
        if (ch_[c] && ch_[c]->oblique_exits()) return true;
    return false;
}

void ExactProfile::build_exit_weights() {
    // The channels' band nodes (one set of inside cosines: every channel reads the same tables).
    int J = 0;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) J = std::max(J, ch_[c]->exit_band_nodes());
    if (J == 0) return;
    const double mfp = mean_free_path();
    band_inv_scale_ = 1.0 / mfp;
    // nodes out to the cutoff
    int n = 2;
    while (n < RadialWeight::kMaxNodes && RadialWeight::node_x(n - 1) * mfp < cutoff_) ++n;
    band_r_nodes_ = n;
    band_cos_.resize(std::size_t(J));
    band_w_.assign(std::size_t(n) * J * 3, 1.0);
    for (int c = 0; c < 3; ++c) {
        if (!ch_[c] || ch_[c]->exit_band_nodes() != J) continue;
        const ChannelProfile& ch = *ch_[c];
        const double st = st_[c];
        for (int j = 0; j < J; ++j) {
            band_cos_[std::size_t(j)] = ch.exit_band_cosine(j);
            auto w = [&](int i) -> double& { return band_w_[(std::size_t(i) * J + j) * 3 + c]; };
            for (int i = 0; i < n; ++i) w(i) = ch.exit_band_ratio(RadialWeight::node_x(i) * mfp * st, j);
            // Its mean against Rd (the weight is linear in r on each segment: 8 midpoints per
            // segment, each with the disc integral over its part), then scaled to 1.
            double sum = 0;
            for (int i = 0; i + 1 < n; ++i) {
                const double a = RadialWeight::node_x(i) * mfp, b = RadialWeight::node_x(i + 1) * mfp;
                double below = ch.disc(a * st);
                for (int q = 0; q < 8; ++q) {
                    const double hi = a + (b - a) * (q + 1) / 8.0, above = ch.disc(hi * st);
                    sum += (above - below) * (w(i) + (w(i + 1) - w(i)) * (q + 0.5) / 8.0);
                    below = above;
                }
            }
            sum += (ch.total() - ch.disc(RadialWeight::node_x(n - 1) * mfp * st)) * w(n - 1);
            const double scale = sum > 0 && ch.total() > 0 ? ch.total() / sum : 1.0;
            for (int i = 0; i < n; ++i) w(i) *= scale;
        }
    }
}

bool ExactProfile::exit_weight(double cos_o, RadialWeight* out) const {
    if (band_w_.empty()) return false;
    const int J = int(band_cos_.size()), n = band_r_nodes_;
    // the refracted (inside) cosine, between the band cosines (held beyond them)
    const double c2 = std::clamp(cos_o, 0.0, 1.0);
    const double mi = std::sqrt(std::max(0.0, 1.0 - (1.0 - c2 * c2) / (eta_ * eta_)));
    int j = 0;
    while (j + 2 < J && mi > band_cos_[std::size_t(j) + 1]) ++j;
    const double t = std::clamp((mi - band_cos_[std::size_t(j)]) / (band_cos_[std::size_t(j) + 1] - band_cos_[std::size_t(j)]), 0.0, 1.0);
    out->inv_scale = band_inv_scale_;
    out->nodes = n;
    for (int i = 0; i < n; ++i) {
        const double* a = &band_w_[(std::size_t(i) * J + j) * 3];
        const double* b = a + 3;
        for (int c = 0; c < 3; ++c) out->w[i][c] = a[c] + (b[c] - a[c]) * t;
    }
    return true;
}

Rgb ExactProfile::entry_factor(double cos_i) const {
    const double ft = fresnel_transmittance(std::clamp(cos_i, 0.0, 1.0), eta_);
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ft * ch_[c]->entry_factor(cos_i);
    return v;
}

Rgb ExactProfile::entry_shift(double cos_i) const {
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ch_[c]->entry_shift(cos_i) / st_[c];
    return v;
}

SlabProfiles ExactProfile::slab_profiles(const Dipole& dipole, double d, bool single_traced) const {
    // With slab tables covering (g, eta): its own slabs (DIPOLE.md 6a), the multipole where a
    // channel's thickness lies outside the tables' nodes.
    return make_exact_slab_profiles(*this, dipole, d, multipole_scale(dipole), nullptr, single_traced);
}

std::string ExactProfile::slab_note() const {
    if (slab_tables()) return "";
    std::string note = "Dipole: thin objects with profile exact use the multipole, scaled to the\n"
                       "  exact total; slab tables:\n  " + slab_gap();
    // A forward-scattering sheet's light is mostly low orders, which no diffusion profile holds:
    // say what it costs and what gets it right (walk_bench's sheets, DIPOLE.md 6a).
    double g = 0;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) g = std::max(g, g_[c]);
    if (g >= kForwardSheetNote)
        note += "\n  A sheet a few mean free paths thin of a forward-scattering medium is lit\n"
                "  mostly by low orders, which the multipole misses (Skin1 at g 0.9, ior 1,\n"
                "  0.25 reduced mfp thick: seen through 99 % dark, its lit side 3.4x too\n"
                "  bright). " + std::string(kForwardSlabFile) + " (`make brdf-data`) holds\n"
                "  g 0 to 0.95 at ior 1 to 1.5; elsewhere `method random_walk` (or `method\n"
                "  auto`) follows the transport exactly.";
    return note;
}

// ---------------------------------------------------------------- slabs

namespace {

// The light through a slab d transport mfp thick for a beam refracted to cosine mu, over that
// at normal incidence: first scattered at depth z with density e^(-z/mu)/mu, each depth passing
// in proportion to sinh(kappa (z + zb)), the transport's slowest mode (kappa:
// transport_decay_rate) vanishing at the entry face's extrapolated boundary (zb, transport
// mfp). Where the tables' transmitted light is too faint for their oblique runs (below
// kTransmitTabulated) their incidence factor is photon noise (0.05 ... 1.5 at one incidence);
// where both hold (T 0.05 of the light entering) the two agree within 3-8 % (DIPOLE.md 6a).
// transmit_through(mu, ...) / transmit_through(1, ...) is that ratio.
double transmit_through(double mu, double d, double kappa, double zb) {
    auto depth = [&](double a) {  // integral over [0, d] of e^(-z a / mu) / mu
        const double x = d * a / mu;
        return std::fabs(x) < 1e-12 ? d / mu : -std::expm1(-x) / a;
    };
    return std::exp(kappa * zb) * depth(1.0 - kappa * mu) - std::exp(-kappa * zb) * depth(1.0 + kappa * mu);
}

// The tables' transmitted incidence factor in full from this share of the light entering, the
// model's below a fifth of it, between them weighted by ln T (geometric means of the two).
constexpr double kTransmitTabulated = 0.05;

}  // namespace

SlabProfiles make_exact_slab_profiles(const ExactProfile& model, const Dipole& dipole, double d, const Rgb& k,
                                      int* tabulated, bool single_traced) {
    if (!(d > 0) || !std::isfinite(d)) throw std::invalid_argument("make_exact_slab_profiles: thickness must be finite and > 0");
    const ProfileTables* tables = model.slab_tables();
    if (tabulated) *tabulated = 0;
    if (!tables) return make_slab_profiles(dipole, d, k);
    // Per channel: the tables' faces (shared: the profiles' functions outlive this call), or
    // the multipole.
    struct Channel {
        std::shared_ptr<const ChannelProfile> r, t;
        // a channel on a smaller g node: its own g's faces at d*, whose exit distributions it takes
        std::shared_ptr<const ChannelProfile> r_exit, t_exit;
        double st = 0, t_scale = 1, r_scale = 1, t_ratio = 1;
        SlabChannel multipole;
        // the transmitted incidence factor: the tables' share of it (the rest the model's),
        // the model's decay rate and extrapolation distance (transport mfp), the slab's thickness
        double t_tabulated = 1, kappa = 0, zb = 0, d = 0, t_normal = 0;
    };
    auto ch = std::make_shared<std::array<Channel, 3>>();
    SlabProfiles out;
    out.d = d;
    double scale = kInf, cutoff = 0;
    int from_tables = 0, scattering = 0;
    for (int c = 0; c < 3; ++c) {
        Channel& x = (*ch)[c];
        const ChannelProfile* half = model.channel(c);
        if (!half) continue;  // does not scatter: nothing diffuses
        ++scattering;
        const double st = model.sigma_t_prime(c);
        // The tables' thickness axis is in mean free paths, d' / (1 - alpha g) at each g node: the
        // forward file's last, 64 mfp, is 6.4 mfp' at g 0.9. A channel thicker than the tables
        // hold at its own g takes their largest g node below it that holds it (similarity, which a
        // thick slab's diffusion meets: Skin1 16 mfp' at g 0.9 taken as g 0, R within 2 %). The
        // multipole there (60-70 % off seen through a g 0.9 sheet) put a step into the slab
        // cache's interpolation beside the tables' last node: Marble at g 0.9 seen through 3-4
        // mfp' read -12 to -18 %. Both faces are then scaled by their ratio of the channel's own g
        // to the node's at the thickest slab its own g holds, d*: continuous at d*, and the
        // boundary layers that set the ratio are a thick slab's whatever its thickness (Skin1's
        // blue, 7.7 mfp' at g 0.9 taken as g 0.8 unscaled, read +4.6 % on the lit side of a 4 mfp'
        // sheet). Their exit distributions are its own g's at d* too: past a few mfp' a face's
        // light leaves as the Milne problem's, while the nodes' exit factors at normal view read
        // 1.19 / 1.21 / 1.27 at g 0.5 / 0.7 / 0 (Marble's red through 16 mfp', 24 samples of
        // 20 000 paths: photon noise), against 1.27 at g 0.9's d*; Marble seen through 16 mfp'
        // read -11 % with the node's.
        const std::vector<double>& g_nodes = tables->settings.g;
        for (int k = int(g_nodes.size());;) {
            const double gq = k == int(g_nodes.size()) ? model.g(c) : g_nodes[std::size_t(k)];
            try {
                x.r = std::make_shared<const ChannelProfile>(*tables, half->alpha_prime(), gq, model.eta(), d * st, 0);
                x.t = std::make_shared<const ChannelProfile>(*tables, half->alpha_prime(), gq, model.eta(), d * st, 1);
                if (k < int(g_nodes.size())) {
                    const double ap = half->alpha_prime(), g = model.g(c), eta = model.eta();
                    auto holds = [&](double dt) {
                        try {
                            ChannelProfile(*tables, ap, g, eta, dt, 0);
                            return true;
                        } catch (const std::invalid_argument&) {
                            return false;
                        }
                    };
                    double lo = tables->settings.thickness.front(), hi = d * st;
                    if (holds(lo)) {
                        for (int it = 0; it < 40 && hi > lo * 1.001; ++it) {  // ~12 constructions
                            const double mid = std::sqrt(lo * hi);
                            (holds(mid) ? lo : hi) = mid;
                        }
                        x.r_exit = std::make_shared<const ChannelProfile>(*tables, ap, g, eta, lo, 0);
                        x.t_exit = std::make_shared<const ChannelProfile>(*tables, ap, g, eta, lo, 1);
                        const ChannelProfile &r_own = *x.r_exit, &t_own = *x.t_exit;
                        const ChannelProfile r_node(*tables, ap, gq, eta, lo, 0), t_node(*tables, ap, gq, eta, lo, 1);
                        const double single = single_traced ? 0.0 : 1.0;
                        const double t_o = t_own.total() + single * t_own.single(), t_n = t_node.total() + single * t_node.single();
                        if (r_node.total() > 0) x.r_scale = r_own.total() / r_node.total();
                        if (t_n > 0) x.t_ratio = t_o / t_n;
                    }
                }
                break;
            } catch (const std::invalid_argument&) {  // d outside the tables' slab nodes
                x.r.reset();
                x.t.reset();
                if (!(d * st > tables->settings.thickness.front())) break;  // too thin: no g holds it
                do --k;
                while (k >= 0 && !(g_nodes[std::size_t(k)] < gq));
                if (k < 0) break;
            }
        }
        if (x.r) {
            ++from_tables;
            x.st = st;
            // T: the tables' total of all orders in the multipole's radial shape (the tables'
            // transmission profile is photon noise near rho = 0 beyond a few mfp: slab.h); its
            // multiple scattering alone where the finish traces single scattering itself.
            x.multipole = SlabChannel::make(dipole.channel(c), d);
            const double t_all = x.t_ratio * (x.t->total() + (single_traced ? 0.0 : x.t->single()));
            const double t_multipole = x.multipole.empty ? 0.0 : x.multipole.T_total();
            x.t_scale = t_multipole > 1e-300 ? t_all / t_multipole : 0.0;
            out.R_total[c] = x.r_scale * x.r->total();
            out.T_total[c] = x.t_scale > 0 ? t_all : 0.0;
            const double t_multi = x.t->total();
            x.t_tabulated = t_multi > 0 ? std::clamp(std::log(t_multi / (0.2 * kTransmitTabulated)) / std::log(5.0), 0.0, 1.0)
                                        : 0.0;
            if (x.t_tabulated < 1) {
                x.kappa = transport_decay_rate(half->alpha_prime(), model.g(c));
                x.zb = x.multipole.empty ? 0.0 : x.multipole.zb * st;
                x.d = d * st;
                x.t_normal = transmit_through(1.0, x.d, x.kappa, x.zb);
            }
            out.t_single_apart[c] = single_traced ? 1.0 : 0.0;
            if (x.r->total() > 0) cutoff = std::max(cutoff, std::min(x.r->radius_containing(1.0 - 1e-6), 1e6) / st);
            cutoff = std::max(cutoff, std::max(x.multipole.cutoff, 1.0 / st));
            scale = std::min(scale, std::min(1.0 / st, x.multipole.empty ? d : x.multipole.z0));
        } else {
            x.multipole = SlabChannel::make(dipole.channel(c), d);
            if (x.multipole.empty) continue;
            out.R_total[c] = k[c] * x.multipole.R_total();
            out.T_total[c] = x.multipole.T_total();
            scale = std::min(scale, x.multipole.z0);
            cutoff = std::max(cutoff, x.multipole.cutoff);
        }
    }
    if (tabulated) *tabulated = from_tables;
    if (!(cutoff > 0)) scale = cutoff = d;  // every channel empty
    scale = std::min(scale, cutoff);
    auto same = [ch, k](double r) {
        Rgb v;
        for (int c = 0; c < 3; ++c) {
            const Channel& x = (*ch)[c];
            v[c] = x.r ? x.r_scale * x.st * x.st * x.r->rd(r * x.st) : x.multipole.empty ? 0.0 : k[c] * x.multipole.R(r);
        }
        return v;
    };
    auto transmit = [ch](double rho) {
        Rgb v;
        for (int c = 0; c < 3; ++c) {
            const Channel& x = (*ch)[c];
            v[c] = x.multipole.empty ? 0.0 : (x.t ? x.t_scale : 1.0) * x.multipole.T(rho);
        }
        return v;
    };
    // R with every channel from the tables: their disc integrals; otherwise numerically (as the
    // multipole), and T always so.
    RdProfile::Fn same_disc;
    if (from_tables == scattering && scattering > 0) {
        same_disc = [ch](double R) {
            Rgb v;
            for (int c = 0; c < 3; ++c)
                if ((*ch)[c].r) v[c] = (*ch)[c].r_scale * (*ch)[c].r->disc(R * (*ch)[c].st);
            return v;
        };
    }
    out.same = std::make_shared<const RdProfile>(same, same_disc, scale, cutoff);
    out.transmit = std::make_shared<const RdProfile>(transmit, RdProfile::Fn(), scale, cutoff, kSlabSampleEvery);
    // Each face's own exit distribution where the tables hold it (the transmitted light of a
    // thin slab leaves more obliquely: pi L / M at normal 0.85 at 0.25 mfp against the
    // half-space's 1.02; the harness Monte Carlo's transmitted radiance agrees, DIPOLE.md 6a).
    if (from_tables > 0) {
        const ExactProfile* half = &model;  // outlives the slab (Subsurface holds both)
        out.exit = [ch, half](double cos_o, Rgb* same_exit, Rgb* opposite_exit) {
            const Rgb h = half->exit_factor(cos_o);
            *same_exit = h;
            *opposite_exit = h;
            for (int c = 0; c < 3; ++c)
                if ((*ch)[c].r) {
                    const Channel& x = (*ch)[c];
                    (*same_exit)[c] = (x.r_exit ? x.r_exit : x.r)->exit_factor(cos_o);
                    (*opposite_exit)[c] = (x.t_exit ? x.t_exit : x.t)->exit_factor(cos_o);
                }
        };
        // ... and its incidence factors over the half-space's (both refract with the same eta)
        const double eta = model.eta();
        out.incidence = [ch, half, eta](double cos_i, bool same) {
            Rgb v(1.0);
            for (int c = 0; c < 3; ++c) {
                const Channel& x = (*ch)[c];
                const ChannelProfile* h = half->channel(c);
                if (!x.r || !h) continue;
                const double base = h->entry_factor(cos_i);
                if (!(base > 0)) continue;
                double f = (same ? x.r : x.t)->entry_factor(cos_i);
                if (!same && x.t_tabulated < 1) {
                    const double mu = refracted_cos(cos_i, eta);
                    const double m = x.t_normal > 0 && mu > 0 ? transmit_through(mu, x.d, x.kappa, x.zb) / x.t_normal : 1.0;
                    f = x.t_tabulated > 0 && f > 0 ? std::exp(x.t_tabulated * std::log(f) + (1 - x.t_tabulated) * std::log(m)) : m;
                }
                v[c] = f / base;
            }
            return v;
        };
    }
    return out;
}

}  // namespace shading
