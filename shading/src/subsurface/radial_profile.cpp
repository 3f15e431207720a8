// The radial profile interface's defaults, the dipole behind it, its table and its entry
// factor as a BRDF; see radial_profile.h.
#include "shading/subsurface/radial_profile.h"

#include <algorithm>
#include <stdexcept>

namespace shading {

SlabProfiles RadialProfile::slab_profiles(const Dipole& dipole, double d, bool) const {
    return make_slab_profiles(dipole, d, multipole_scale(dipole));
}

Rgb RadialProfile::multipole_scale(const Dipole& dipole) const {
    const Rgb model_total = rd_disc(kInf), dipole_total = dipole.rd_total();
    Rgb k(1.0);
    for (int c = 0; c < 3; ++c)
        if (dipole_total[c] > 0) k[c] = model_total[c] / dipole_total[c];
    return k;
}

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

SlabProfiles DipoleRadialProfile::slab_profiles(const Dipole& dipole, double d, bool) const {
    return make_slab_profiles(dipole, d, Rgb(1.0));
}

// ---------------------------------------------------------------- its table, its entry as a BRDF

std::shared_ptr<const RdProfile> make_rd_profile(std::shared_ptr<const RadialProfile> model) {
    if (!model) throw std::invalid_argument("make_rd_profile: no profile");
    const double cutoff = model->cutoff();
    const double r_max = cutoff > 0 ? cutoff : 1.0;  // every channel empty: Rd = 0 anyway
    const double mfp = model->mean_free_path();  // the dipole's: its smallest zr = 1/sigma_t'
    const double scale = mfp > 0 ? mfp : r_max;
    return std::make_shared<const RdProfile>([model](double r) { return model->rd(r); },
                                             [model](double R) { return model->rd_disc(R); }, scale, r_max);
}

TransmittanceBrdf::TransmittanceBrdf(std::shared_ptr<const RadialProfile> model) : model_(std::move(model)) {
    if (!model_) throw std::invalid_argument("TransmittanceBrdf: no profile");
}
Rgb TransmittanceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return model_->entry_factor(wi.z) * kInvPi;
}
std::string TransmittanceBrdf::describe() const { return "transmittance(" + model_->describe() + ")"; }

}  // namespace shading
