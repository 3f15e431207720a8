// The radial profile of multiple scattering that the hierarchical subsurface evaluation
// (subsurface.h) integrates, per colour channel in SCENE units, behind one interface:
//  * DipoleRadialProfile: Jensen et al. 2001's dipole (dipole.h), whose Rd approximates single
//    and multiple scattering together, with Jensen's exit and entry factors Ft(cos);
//  * ExactProfile (exact_profile.h): the exact multiple-scattering profile of the library's
//    own Monte Carlo transport (ss_profile.h).
// A profile also gives its thin slabs (slab_profiles) for thin geometry; the table the octree
// reads is make_rd_profile(profile). See shading/DIPOLE.md 6 and 10.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"
#include "shading/subsurface/dipole.h"
#include "shading/subsurface/rd_profile.h"
#include "shading/subsurface/slab.h"

namespace shading {

class RadialProfile {
public:
    virtual ~RadialProfile() = default;
    // Radiant exitance at distance r (scene units) per unit power entering, per scene-unit^2.
    virtual Rgb rd(double r) const = 0;
    // Integral of rd over the disc of radius R around the entry point (dimensionless).
    virtual Rgb rd_disc(double R) const = 0;
    // The whole integral (uniform illumination: exitance per unit entering irradiance).
    virtual Rgb total() const = 0;
    // Radius (scene units) holding all but 1e-6 of every channel's total, capped where the tail
    // is a power law (no absorption): beyond it rd is left out.
    virtual double cutoff() const = 0;
    // Smallest channel's transport mean free path 1/sigma_t' (scene units); 0 if no channel scatters.
    virtual double mean_free_path() const = 0;
    // pi L / M toward a viewer at outside cosine cos_o: pixel += M exit_factor (POV's pixel is
    // pi x radiance). Jensen's dipole: Ft(cos_o).
    virtual Rgb exit_factor(double cos_o) const = 0;
    // Irradiance transmitted into the profile per unit irradiance arriving at outside cosine cos_i:
    // Ft(cos_i) for the dipole; Ft(cos_i) times the transport's incidence factor for the exact profile.
    virtual Rgb entry_factor(double cos_i) const = 0;
    // Light entering at a slant travels on inside: the mean offset (scene units, per channel)
    // of its multiple-scattering exitance from the entry point, along the refracted beam's
    // tangential direction, for light arriving at outside cosine cos_i. 0: a profile that does
    // not know (the dipole), and at normal incidence.
    virtual Rgb entry_shift(double cos_i) const {
        (void)cos_i;
        return Rgb(0.0);
    }
    // pi L / M toward outside cosine cos_o of the light that entered at outside cosine cos_i,
    // cos_phi the cosine of the azimuth between the view's tangential direction and the entering
    // beam's (1: the viewer ahead of the beam). Light entering at a slant leaves more toward
    // where it was going (DIPOLE.md 6e). exit_factor(cos_o) for a profile that does not know
    // (the dipole: oblique_exits() false).
    virtual Rgb exit_factor_oblique(double cos_i, double cos_o, double cos_phi) const {
        (void)cos_i;
        (void)cos_phi;
        return exit_factor(cos_o);
    }
    virtual bool oblique_exits() const { return false; }
    // The exit distribution's change with distance from the entry point: light leaving near it
    // leaves closer to the normal than the exitance-weighted mean, a few transport mfp out more
    // obliquely (DIPOLE.md 10.7). Fills `w` for a viewer at outside cosine cos_o so that
    // pixel = exit_factor(cos_o) x the sum of Rd(r) w(r) A E_t, w averaging 1 against Rd (a
    // uniformly lit half-space renders as without it); false (w untouched): no such weight
    // (the dipole; the exact profile without distance bands).
    virtual bool exit_weight(double cos_o, RadialWeight* w) const {
        (void)cos_o;
        (void)w;
        return false;
    }
    // Whether rd already stands for single scattering too (the dipole): then the finish does not
    // add the single-scattering BRDF by default.
    virtual bool includes_single_scattering() const = 0;
    virtual std::string describe() const = 0;
    // Thin geometry: the profiles of a slab of thickness d (scene units) of this medium, whose
    // dipole is `dipole`. By default the multipole (slab.h) with R scaled per channel to this
    // profile's half-space total (multipole_scale), so that a slab at the threshold reflects
    // what the half-space does; T as it is. single_traced: the finish adds single scattering
    // itself on both faces (traced in the object's shape, `single_scatter_samples`, or the flat
    // slab's at each lookup, Subsurface::slab_single_at_lookup), so T must leave it out where
    // it holds it (the exact profile's tables; SlabProfiles::t_single_apart says where).
    virtual SlabProfiles slab_profiles(const Dipole& dipole, double d, bool single_traced) const;
    // What thin geometry falls back to with this profile, for the statistics ("": nothing).
    virtual std::string slab_note() const { return ""; }

protected:
    // Per channel, this profile's half-space total rd_disc(inf) over the dipole's (1 where the
    // dipole's is 0).
    Rgb multipole_scale(const Dipole& dipole) const;
};

class DipoleRadialProfile final : public RadialProfile {
public:
    explicit DipoleRadialProfile(const Dipole& d);
    Rgb rd(double r) const override { return d_.rd(r); }
    Rgb rd_disc(double R) const override { return d_.rd_disc(R); }
    Rgb total() const override { return d_.rd_total(); }
    double cutoff() const override { return cutoff_; }
    double mean_free_path() const override;
    Rgb exit_factor(double cos_o) const override;
    Rgb entry_factor(double cos_i) const override;
    bool includes_single_scattering() const override { return true; }
    std::string describe() const override { return "dipole"; }
    // The multipole itself (its R meets this dipole's half-space).
    SlabProfiles slab_profiles(const Dipole& dipole, double d, bool single_traced) const override;
    const Dipole& dipole() const { return d_; }

private:
    Dipole d_;
    double cutoff_ = 0;
};

// The table the hierarchical evaluation reads (rd_profile.h) of a radial profile: its rd and
// disc integral, scale = its smallest mean free path, r_max = its cutoff.
std::shared_ptr<const RdProfile> make_rd_profile(std::shared_ptr<const RadialProfile> model);

// RadialProfile::entry_factor(cos_i) / pi as a Brdf (wo ignored above the surface; the
// dipole's: Ft(eta, cos_i) / pi): lit by the renderer's light loop it yields the transmitted
// irradiance E_t at a point (the adapter's finish model for it: FinishModel::transmittance,
// finish.h).
class TransmittanceBrdf final : public Brdf {
public:
    explicit TransmittanceBrdf(std::shared_ptr<const RadialProfile> model);
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    std::string describe() const override;

private:
    std::shared_ptr<const RadialProfile> model_;
};

}  // namespace shading
