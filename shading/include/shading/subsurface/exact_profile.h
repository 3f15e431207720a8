// The exact multiple-scattering profile behind RadialProfile: the library's own Monte Carlo
// transport, tabulated (ss_profile.h), with the exit distribution and incidence factor of the
// same transport; single scattering is the exact BRDF (Dipole::single_scatter_brdf), added once
// by the finish. See shading/DIPOLE.md 10.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "shading/subsurface/dipole.h"
#include "shading/subsurface/radial_profile.h"
#include "shading/subsurface/slab.h"
#include "shading/subsurface/ss_profile.h"

namespace shading {

class ExactProfile final : public RadialProfile {
public:
    // Per channel: reduced albedo alpha' = sigma_s' / (sigma_s' + sigma_a), g, eta of the medium;
    // lengths scaled by sigma_t' = (sigma_s' + sigma_a) mm_per_unit. A g outside the tables is
    // clamped to their range at the same reduced albedo (similarity; listed in notes()). Throws
    // std::invalid_argument for an invalid medium or an eta outside the tables.
    // `slab_tables` (optional; make brdf-data ships kSlabFile, g 0): exact reflection and
    // transmission faces of slabs for thin geometry (make_exact_slab_profiles below), used
    // where they cover every scattering channel's (g, eta); else `forward_slab_tables`
    // (kForwardSlabFile, g 0 to 0.95, fewer iors) where they do; slab_gap() says why neither.
    ExactProfile(const Medium& m, std::shared_ptr<const ProfileTables> tables,
                 std::shared_ptr<const ProfileTables> slab_tables = nullptr,
                 std::shared_ptr<const ProfileTables> forward_slab_tables = nullptr);
    static constexpr const char* kSlabFile = "subsurface_slabs.ssp";
    static constexpr const char* kForwardSlabFile = "subsurface_slabs_forward.ssp";
    // (The interface's overrides, in DipoleRadialProfile's order.)
    Rgb rd(double r) const override;
    Rgb rd_disc(double R) const override;
    Rgb total() const override;
    double cutoff() const override { return cutoff_; }
    double mean_free_path() const override;
    Rgb exit_factor(double cos_o) const override;
    Rgb entry_factor(double cos_i) const override;
    Rgb entry_shift(double cos_i) const override;
    Rgb exit_factor_oblique(double cos_i, double cos_o, double cos_phi) const override;
    bool oblique_exits() const override;
    bool exit_weight(double cos_o, RadialWeight* w) const override;
    bool includes_single_scattering() const override { return false; }
    std::string describe() const override { return "exact"; }
    // Thin geometry: the tables' slabs where they cover a channel (make_exact_slab_profiles),
    // the multipole scaled to this profile's total elsewhere.
    SlabProfiles slab_profiles(const Dipole& dipole, double d, bool single_traced) const override;
    // Why thin objects take the multipole, and from a channel's g of kForwardSheetNote on, that
    // a forward-scattering sheet wants the walk.
    std::string slab_note() const override;
    static constexpr double kForwardSheetNote = 0.5;
    // Warnings for the user (g clamped to the tables).
    const std::vector<std::string>& notes() const { return notes_; }
    // The channel in transport units (nullptr for a channel that does not scatter).
    const ChannelProfile* channel(int c) const { return ch_[c].get(); }
    double sigma_t_prime(int c) const { return st_[c]; }  // per scene unit
    double g(int c) const { return g_[c]; }                 // the medium's (not clamped)
    double eta() const { return eta_; }
    // The slab tables that cover (g, eta) of every scattering channel, else nullptr; then
    // slab_gap() says why for each file (no file, or the g / ior outside it) for the statistics.
    const ProfileTables* slab_tables() const { return slab_tables_.get(); }
    const std::string& slab_gap() const { return slab_gap_; }

private:
    std::shared_ptr<const ProfileTables> tables_, slab_tables_;
    std::unique_ptr<ChannelProfile> ch_[3];
    double st_[3] = {0, 0, 0}, g_[3] = {0, 0, 0};
    std::string slab_gap_;
    double eta_ = 1;
    double cutoff_ = 0;
    // exit_weight's table: per RadialWeight node i (scale = mean_free_path()), band cosine j and
    // channel c, the ratio normalised to average 1 against Rd: band_w_[(i * J + j) * 3 + c].
    std::vector<double> band_cos_, band_w_;
    int band_r_nodes_ = 0;
    double band_inv_scale_ = 1;
    void build_exit_weights();
    std::vector<std::string> notes_;
};

// The slab of the exact profile (thin geometry with `profile exact`): per channel, where the
// model's slab tables (ExactProfile::slab_tables, the library's own transport Monte Carlo of
// slabs, faces R and T) cover the channel's thickness d sigma_t' (transport mfp), R(s) and T(rho)
// are those faces in scene units, rd_scene(r) = st'^2 rd(r st') as ExactProfile does for the
// half-space. R is the multiple-scattering face (single scattering is the finish's BRDF, added
// once, as for the half-space). T has the tables' total of all orders (multi + single: light
// scattered once on its way through leaves the opposite face too, and no BRDF renders it) in
// the multipole's radial shape: the tables' own transmission profile is photon noise near
// rho = 0 beyond a few mfp, while their total holds (DIPOLE.md 6a). Channels the tables don't
// cover (no tables, or d outside their slab nodes): the multipole with R scaled by `scale`, as
// make_slab_profiles.
// `tabulated` (optional): how many channels came from the tables. single_traced: T holds the
// multiple scattering only where it comes from the tables (t_single_apart; the finish adds
// single scattering itself, on both faces).
SlabProfiles make_exact_slab_profiles(const ExactProfile& model, const Dipole& dipole, double d, const Rgb& scale,
                                      int* tabulated = nullptr, bool single_traced = false);

}  // namespace shading
