// The radial profile of multiple scattering that the hierarchical subsurface evaluation
// (subsurface.h) integrates, per colour channel in SCENE units, behind one interface:
//  * DipoleRadialProfile: Jensen et al. 2001's dipole (dipole.h), whose Rd approximates single
//    and multiple scattering together, with Jensen's exit and entry factors Ft(cos);
//  * ExactProfile: the exact multiple-scattering profile of the library's own Monte Carlo
//    transport (ss_profile.h), with the exit distribution and incidence factor of the same
//    transport; single scattering is the exact BRDF (Dipole::single_scatter_brdf), added once
//    by the finish.
// See shading/DIPOLE.md ("Exact profiles").
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "shading/subsurface/dipole.h"
#include "shading/subsurface/ss_profile.h"

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
    // Whether rd already stands for single scattering too (the dipole): then the finish does not
    // add the single-scattering BRDF by default.
    virtual bool includes_single_scattering() const = 0;
    virtual std::string describe() const = 0;
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
    const Dipole& dipole() const { return d_; }

private:
    Dipole d_;
    double cutoff_ = 0;
};

class ExactProfile final : public RadialProfile {
public:
    // Per channel: reduced albedo alpha' = sigma_s' / (sigma_s' + sigma_a), g, eta of the medium;
    // lengths scaled by sigma_t' = (sigma_s' + sigma_a) mm_per_unit. A g outside the tables is
    // clamped to their range at the same reduced albedo (similarity; listed in notes()). Throws
    // std::invalid_argument for an invalid medium or an eta outside the tables.
    // `slab_tables` (optional; make brdf-data ships subsurface_slabs.ssp): exact reflection and
    // transmission faces of slabs for thin geometry (slab.h make_exact_slab_profiles), used
    // where they cover every scattering channel's (g, eta); slab_gap() says why they don't.
    ExactProfile(const Medium& m, std::shared_ptr<const ProfileTables> tables,
                 std::shared_ptr<const ProfileTables> slab_tables = nullptr);
    Rgb rd(double r) const override;
    Rgb rd_disc(double R) const override;
    Rgb total() const override;
    double cutoff() const override { return cutoff_; }
    double mean_free_path() const override;
    Rgb exit_factor(double cos_o) const override;
    Rgb entry_factor(double cos_i) const override;
    bool includes_single_scattering() const override { return false; }
    std::string describe() const override { return "exact"; }
    // Warnings for the user (g clamped to the tables).
    const std::vector<std::string>& notes() const { return notes_; }
    // The channel in transport units (nullptr for a channel that does not scatter).
    const ChannelProfile* channel(int c) const { return ch_[c].get(); }
    double sigma_t_prime(int c) const { return st_[c]; }  // per scene unit
    double g(int c) const { return g_[c]; }                 // the medium's (not clamped)
    double eta() const { return eta_; }
    // The slab tables when they cover (g, eta) of every scattering channel, else nullptr; then
    // slab_gap() says why (no file, or the g / ior outside it) for the statistics.
    const ProfileTables* slab_tables() const { return slab_gap_.empty() ? slab_tables_.get() : nullptr; }
    const std::string& slab_gap() const { return slab_gap_; }

private:
    std::shared_ptr<const ProfileTables> tables_, slab_tables_;
    std::unique_ptr<ChannelProfile> ch_[3];
    double st_[3] = {0, 0, 0}, g_[3] = {0, 0, 0};
    std::string slab_gap_;
    double eta_ = 1;
    double cutoff_ = 0;
    std::vector<std::string> notes_;
};

}  // namespace shading
