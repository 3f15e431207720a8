// Exact subsurface profiles: the multiple-scattering exitance of a flat homogeneous medium
// (semi-infinite, or a slab of thickness d), tabulated from the library's own Monte Carlo
// transport (transport_mc.h) over albedo x radius, one table per (g, eta, d), and evaluated for
// a Medium. Single scattering is NOT in the tables: it is the exact single-scattering BRDF of
// dipole.h, so single and multiple scattering are each counted once.
//
// Units: a table works in the medium's own scales. Albedo nodes are the single-scattering albedo
// alpha on a uniform grid in u = -ln(1 - alpha); radii are transport mean free paths
// rho = r sigma_t' (sigma_t' = sigma_s (1 - g) + sigma_a), so Rd(rho) is per transport mfp^2;
// slab thicknesses are mean free paths 1/sigma_t. Everything is per unit power ENTERING the
// medium (Fresnel at the entry is the renderer's).
//
// The file format (.ssp, little-endian; specified in shading/DIPOLE.md "Profile tables") holds
// a grid of (g, eta, d) nodes; load_profile_tables checks every field and reports
// "NAME: offset N: <what>: expected ..., found ..." (ProfileError).
//
// Building the tables: ss_profile_build.cpp; the file: ss_profile_io.cpp; evaluating them
// (ChannelProfile): ss_profile.cpp.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "shading/subsurface/transport_mc.h"
#include "shading/core/vec.h"

namespace shading {

// Bumped whenever the generator's output for the same settings changes (Monte Carlo, the
// processing of its tallies); part of a table file's identity (ProfileTables::stale).
constexpr std::uint32_t kProfileGeneratorVersion = 8;
// The .ssp layout's version (3: the checksum at bytes 24..31 covers the whole file, header
// included; 4: each record holds the oblique beams' exit shifts; 5: and the exit distribution per
// distance band; 6: and per oblique incidence and azimuth; DIPOLE.md 10.4). Files of another
// version are refused; `sstool build --if-stale` (make brdf-data) rebuilds them.
constexpr std::uint32_t kProfileFormatVersion = 6;

class ProfileError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What a table file is built from (the generator's settings, recorded in the file).
struct ProfileBuildSettings {
    std::vector<double> g{0.0};
    std::vector<double> eta{1.0};
    std::vector<double> thickness{std::numeric_limits<double>::infinity()};  // mfp; inf: semi-infinite
    // Cosines of the refracted (inside) beam for the incidence factor, increasing, the last 1
    // (normal). Inside cosines, so that one set of paths serves every eta.
    // (dense toward grazing, where the exit distribution changes fastest: with {0.2, 0.45, ...}
    // linear interpolation left the normal view of a g 0.9 medium under light at 70 degrees
    // outside, ior 1, 4-5 % dark; DIPOLE.md 6e)
    std::vector<double> cos_inside{0.2, 0.3, 0.4, 0.5, 0.65, 0.8, 0.9, 1.0};
    double u_0 = 0.1, u_step = 0.25;  // albedo nodes u_k = u_0 + k u_step, u = -ln(1 - alpha)
    int albedos = 48;                  // up to u = 11.85: alpha = 1 - 7.1e-6
    RadialBins bins;                   // disc [0, 0.01) + 10 per decade to 1000 transport mfp
    int angle_bins = 32;               // inside cosine histogram of the high orders (quadratic fit)
    int angle_nodes = 8;               // inside radiance samples (angle_cosine: the last at 1)
    double radiance_orders = 64;       // next-event radiance up to 64 / (1 - g) events, histogram above
    std::uint64_t photons = 80000;     // full paths at normal incidence, per g (all etas at once)
                                       // (more in thick slabs: normal_photons)
    std::uint64_t short_photons = 800000;   // low-order paths (see McSettings)
    double short_orders = 20;          // ... stopped after this many transport events: 20 / (1 - g) events
    double roulette_order = 250;       // path-length roulette from 250 / (1 - g) events on
    double oblique_fraction = 0.06;    // photons at each oblique incidence, relative to `photons`
    // The exit distribution per distance from the entry point (semi-infinite tables only; empty
    // for slabs): outer edges of the bands [0, e_0), ..., [e_last, inf) in transport mfp of the
    // albedo-1 medium (mean free paths e (1 - g)^-1 at each g node). DIPOLE.md 10.3, 10.7.
    std::vector<double> exit_bands{0.25, 0.5, 1, 2, 4, 8, 16};
    int band_count() const { return exit_bands.empty() ? 0 : int(exit_bands.size()) + 1; }
    // The exit distribution of light entering at each oblique cos_inside, at this many azimuths
    // from the beam's forward direction (0 .. 180 degrees in equal steps; semi-infinite tables
    // only, 0 for slabs or none): the orders up to oblique_orders / (1 - g) from the oblique
    // runs' own next-event estimate, the higher ones (which have forgotten the beam's direction)
    // as at normal incidence in the oblique run's share of them. DIPOLE.md 6e.
    int oblique_azimuths = 7;
    int oblique_orders = 10;
    std::uint64_t seed = 1;
    int threads = 0;                   // 0: all hardware threads
    std::string validate() const;
    // The full paths of the normal-incidence run of a slab `thickness` mfp thick at anisotropy
    // g: `photons` times (d' / 1.6)^2 within [1, 8], d' = thickness (1 - g) the slab's transport
    // thickness at albedo 1. Few paths cross a thick slab, after hundreds of scatterings: the
    // transmitted face's exit distribution at 64 mfp and g 0.9 (6.4 d') varied by 3.5 % from
    // seed to seed at 20 000 paths (1.9 % at 3.2 d', 0.7 % at 1.6 d'), and the
    // shipped table's 45-degree exit read 10 % high (DIPOLE.md 10.3). Not the oblique runs (their
    // totals only) nor the short paths (the low orders, near the lit face).
    std::uint64_t normal_photons(double thickness, double g) const;
    // The settings a build with these records (and ProfileTables::stale compares): a slab table
    // (any finite thickness) has no distance bands and no oblique exits.
    ProfileBuildSettings recorded() const;
};

// The tables `make brdf-data` ships (build/brdf_data/subsurface_profiles.ssp): semi-infinite,
// g in {0, 0.2, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95}, eta in {1, 1.1, 1.2, 1.3, 1.33, 1.4,
// 1.5, 1.6, 1.8, 2}, the other settings ProfileBuildSettings' defaults (10 Monte Carlo runs at
// normal incidence, each serving all etas, and 5 oblique ones each; a few CPU minutes).
ProfileBuildSettings default_profile_build_settings();

// One face (reflection or transmission) of one node at one albedo: the file's record.
struct FaceRecord {
    double multi = 0;      // multiple-scattering exitance, normal incidence (n >= 2)
    double single = 0;     // single-scattering exitance of the Monte Carlo (checks only)
    double ballistic = 0;  // unscattered exitance (slabs)
    double tail_k = 0;     // beyond rho_tail: Rd = tail_a (1 + k rho) exp(-k rho) / rho^3, k per transport mfp
    double tail_a = 0;
    double rho_tail = 0;
    std::vector<double> angle;      // pi L_inside / M at the inside cosines angle_cosine(j)
    std::vector<double> incidence;  // multi(cos_inside[i]) / multi(1)
    // The mean offset of the multiple-scattering exits from the entry point along the oblique
    // beam's tangential direction at cos_inside[i], transport mfp (0 at normal incidence).
    std::vector<double> shift;
    std::vector<double> profile;    // Rd at the radial nodes (per transport mfp^2)
    // Per distance band b (ProfileBuildSettings::exit_bands; empty without bands): the mean
    // distance of the band's exits from the entry point (transport mfp), and the band's exit
    // distribution against the whole face's at each inside cosine angle_cosine(j):
    // band_ratio[b * angle_nodes + j] = (I_b(mu_j) / M_b) / (I(mu_j) / M), I the inside radiance
    // (sum over the bands), M each one's exitance implied by it (ss_detail::exit_sum). The
    // bands' ratios weighted by their M_b / M average to 1 at every cosine. 1 where a band has
    // too few exits to say (then the band inside it).
    std::vector<double> band_rho, band_ratio;
    // Oblique incidence (ProfileBuildSettings::oblique_azimuths = A; empty without): pi L_inside /
    // M at the inside cosines angle_cosine(j) for light entering at cos_inside[i] (i below the
    // last, normal, which is `angle`), toward azimuth pi a / (A - 1) from the beam's forward
    // tangential direction: oblique[(i * A + a) * angle_nodes + j]; M that incidence's own
    // multiple-scattering exitance.
    std::vector<double> oblique;
};

// The tables of one file: axes and records. Radial node 0 is rho = 0 (the disc's mean), node
// b >= 1 the geometric centre of RadialBins bin b.
class ProfileTables {
public:
    ProfileBuildSettings settings;   // axes and the generator settings it was built with
    std::uint32_t generator_version = kProfileGeneratorVersion;
    int faces = 1;                   // 1: reflection; 2: reflection and transmission (slabs)
    std::vector<FaceRecord> records; // [((ig * n_eta + ie) * n_d + id) * faces + face] * albedos + k
    double build_seconds = 0;        // not stored
    std::string name;                // the name the loader was given (messages), not stored

    const FaceRecord& record(int ig, int ie, int id, int face, int k) const;
    double albedo(int k) const { return 1.0 - std::exp(-(settings.u_0 + k * settings.u_step)); }
    // Inside cosine of angle sample j: 0.5 (1 - cos(pi (j + 1/2) / (angle_nodes - 1/2))); the last 1.
    double angle_cosine(int j) const;
    double node_rho(int b) const;    // radial node position (transport mfp)
    int radial_nodes() const { return settings.bins.count; }

    // The table file image and its reader (byte-offset errors, ProfileError).
    std::vector<std::uint8_t> serialize() const;
    // True when a file built with `wanted` would differ (other generator version or settings).
    bool stale(const ProfileBuildSettings& wanted) const;
    std::string describe() const;
};

// The file's checksum: FNV-1a-64 of every byte of the image, the checksum field (bytes 24..31)
// read as zeros. Stored at bytes 24..31.
std::uint64_t profile_file_checksum(const std::uint8_t* data, std::size_t size);
// Reads a table file image; `name` prefixes every error message. Checks, in order: size of the
// header, magic, format version, the checksum of the whole file, then every field.
std::shared_ptr<const ProfileTables> load_profile_tables(const std::uint8_t* data, std::size_t size,
                                                         const std::string& name);
// Builds every node with run_transport_mc; `log` (optional) gets one line per node.
std::shared_ptr<ProfileTables> build_profile_tables(const ProfileBuildSettings& s,
                                                    const std::function<void(const std::string&)>& log = {});
// Tables shared by every finish that names the same key (the resolved path), like shared_table.
std::shared_ptr<const ProfileTables> shared_profile_tables(
    const std::string& key, const std::function<std::shared_ptr<const ProfileTables>()>& load);

// ---------------------------------------------------------------------------------------------
// Evaluation for one colour channel: the tables interpolated at (g, eta, d) and the reduced
// albedo alpha' (albedo cubic in u, then cubic Lagrange across g and eta at equal alpha'),
// in transport units. rd, disc are per unit power entering; angles are outside cosines.
class ChannelProfile {
public:
    // face 0: reflection, 1: transmission (slab tables only). `thickness` is in transport mfp
    // (like the radii; converted per g node to the tables' mean free paths). Throws
    // std::invalid_argument if (g, eta, d) lies outside the tables (range_error says why for g
    // and eta).
    ChannelProfile(const ProfileTables& t, double alpha_prime, double g, double eta,
                   double thickness = std::numeric_limits<double>::infinity(), int face = 0);
    // Empty string when the tables cover (g, eta, d); otherwise the message.
    static std::string range_error(const ProfileTables& t, double g, double eta, double thickness);

    double alpha_prime() const { return alpha_prime_; }
    double total() const { return total_; }    // multiple-scattering exitance, normal incidence
    double single() const { return single_; }  // Monte Carlo single scattering (checks)
    double ballistic() const { return ballistic_; }
    double rd(double rho) const;               // per transport mfp^2
    double disc(double R) const;               // integral of rd over the disc of radius R
    double annulus_mean(double r1, double r2) const;
    double radius_containing(double fraction) const;
    // pi L(cos_o) / M: radiance leaving towards outside cosine cos_o per unit exitance
    // (integrates to 1 against 2 cos_o dcos_o; Lambertian = 1).
    double exit_factor(double cos_o) const;
    // multi(cos_i) / multi(1) for the outside incidence cosine cos_i: refracted with this
    // channel's eta, then linear between the tables' inside cosines.
    double entry_factor(double cos_i) const;
    // The mean offset (transport mfp) of the multiple-scattering exitance from the entry point,
    // along the refracted beam's tangential direction, for light arriving at outside cosine
    // cos_i: interpolated like entry_factor (0 at normal incidence).
    double entry_shift(double cos_i) const;
    // pi L(cos_o) / M toward outside cosine cos_o for light that entered at outside cosine cos_i
    // (refracted with this channel's eta, linear between the tables' inside cosines, held below
    // the first), cos_phi the cosine of the azimuth between the view's and the entering beam's
    // tangential directions (1: the viewer ahead of the beam, forward; linear in the angle
    // between the tables' azimuths). exit_factor(cos_o) at normal incidence, and where the
    // tables have no oblique exits (oblique_exits() false).
    double exit_factor_oblique(double cos_i, double cos_o, double cos_phi) const;
    bool oblique_exits() const { return !oblique_.empty(); }
    // The exit distribution's change with distance (semi-infinite tables with distance bands;
    // DIPOLE.md 10.7): exit_bands() nodes j at the inside cosines exit_band_cosine(j); at
    // distance rho (transport mfp) from the entry point the radiance toward inside cosine mu_j
    // is exit_factor's times exit_band_ratio(rho, j): the bands' ratios, linear in ln rho
    // between their mean distances (held beyond the first and the last). 0 nodes: no bands.
    int exit_band_nodes() const { return band_rho_.empty() ? 0 : int(band_nodes_); }
    double exit_band_cosine(int j) const;
    double exit_band_ratio(double rho, int j) const;

private:
    double interpolate_inside(const std::vector<double>& v, double cos_o) const;
    double node_value(int b) const { return std::exp(lnv_[b]); }
    double segment_integral(int b, double r1, double r2) const;  // of 2 pi rho rd over [r1, r2] in segment b
    int segment_of(double rho) const;
    double alpha_prime_ = 0, total_ = 0, single_ = 0, ballistic_ = 0, eta_ = 1;
    std::vector<double> rho_, lnv_, cum_;  // nodes, ln Rd at the nodes, disc integral at the nodes
    double tail_k_ = 0, tail_a_ = 0;       // beyond the last node
    std::vector<double> angle_, ci_, incidence_, shift_;
    std::vector<double> band_rho_, band_ratio_;  // the records' band data, mixed like the angles
    std::size_t band_nodes_ = 0;
    double angle_norm_ = 1;
    // oblique_[(i * A + a) * 129 + j]: as angle_, per oblique inside cosine i and azimuth a
    std::vector<double> oblique_;
    int oblique_azimuths_ = 0;
    double inside_index(double cos_o) const;  // exit_factor's position in angle_ (0 .. 128)
};

// The reduced albedo alpha' whose total diffuse reflectance at normal incidence, multiple
// scattering (these tables) plus `single(alpha')` (the caller's single-scattering albedo, e.g.
// from Dipole::single_scatter_brdf), equals `total` (in [0, the total at alpha' = 1]): the
// inversion "this diffuse colour" of pbrt's SubsurfaceFromDiffuse, by bisection (1e-10 in
// alpha'). Returns 1 when `total` is at or above the largest reachable value.
double alpha_prime_for_total(const ProfileTables& t, double total, double g, double eta,
                             const std::function<double(double)>& single);

}  // namespace shading
