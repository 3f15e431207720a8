// The dipole and the exact Monte Carlo profile behind RadialProfile; see radial_profile.h.
#include "shading/subsurface/radial_profile.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace shading {

// ---------------------------------------------------------------- dipole

DipoleRadialProfile::DipoleRadialProfile(const Dipole& d) : d_(d) {
    // The radius holding all but 1e-6 of each channel's reflectance; without absorption Rd's
    // tail is a power law and that radius grows without bound: a million transport lengths
    // caps it there.
    for (int c = 0; c < 3; ++c)
        if (!d_.channel(c).empty)
            cutoff_ = std::max(cutoff_, std::min(d_.channel(c).radius_containing(1.0 - 1e-6), 1e6 * d_.channel(c).zv));
}

double DipoleRadialProfile::mean_free_path() const {
    double l = 0;
    for (int c = 0; c < 3; ++c) {
        const DipoleChannel& ch = d_.channel(c);
        if (!ch.empty) l = l == 0 ? ch.zr : std::min(l, ch.zr);
    }
    return l;
}

Rgb DipoleRadialProfile::exit_factor(double cos_o) const {
    return Rgb(fresnel_transmittance(cos_o, d_.medium().eta));
}

Rgb DipoleRadialProfile::entry_factor(double cos_i) const {
    return Rgb(fresnel_transmittance(cos_i, d_.medium().eta));
}

// ---------------------------------------------------------------- exact

namespace {
std::string num(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}
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
                           std::shared_ptr<const ProfileTables> slab_tables)
    : tables_(std::move(tables)), slab_tables_(std::move(slab_tables)) {
    const std::string bad = m.validate();
    if (!bad.empty()) throw std::invalid_argument("dipole medium: " + bad);
    if (!tables_) throw std::invalid_argument("exact profile: no tables");
    // Tables another generator made, or of another kind than asked for, are never used.
    check_identity(*tables_, false);
    if (slab_tables_) check_identity(*slab_tables_, true);
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
    // Slab tables: every scattering channel's (g, eta) inside them (thickness: per node, slab.h).
    if (!slab_tables_) {
        slab_gap_ = "no slab tables";
    } else if (slab_tables_->faces < 2) {
        slab_gap_ = "the slab tables have no transmission face";
    } else {
        for (int c = 0; c < 3 && slab_gap_.empty(); ++c)
            if (ch_[c]) slab_gap_ = ChannelProfile::range_error(*slab_tables_, g_[c], m.eta, 1.0);
    }
    for (const auto& [g, channels] : clamped) {
        const double gc = std::clamp(g, s.g.front(), s.g.back());
        notes_.push_back("g = " + num(g) + " (" + channels + ") is outside the exact profile's tables [" + num(s.g.front()) +
                         ", " + num(s.g.back()) + "]: the g = " + num(gc) + " table is used at the same reduced albedo");
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

Rgb ExactProfile::entry_factor(double cos_i) const {
    const double ft = fresnel_transmittance(std::clamp(cos_i, 0.0, 1.0), eta_);
    Rgb v;
    for (int c = 0; c < 3; ++c)
        if (ch_[c]) v[c] = ft * ch_[c]->entry_factor(cos_i);
    return v;
}

}  // namespace shading
