// Monte Carlo photon migration in a homogeneous layer (semi-infinite or a slab), the transport
// that the exact subsurface profiles (ss_profile.h) are tabulated from. See shading/DIPOLE.md,
// section "Exact profiles".
//
// Model and units:
//  * Lengths are in mean free paths 1/sigma_t (sigma_t = 1). The medium fills 0 <= z <= d
//    (z is depth; d = infinity: semi-infinite), with Henyey-Greenstein scattering of asymmetry g.
//  * A pencil beam enters at the origin; INSIDE the medium it travels at cosine `cos_inside` with
//    the normal, in the xz plane (the refracted direction: Snell's law is the caller's,
//    refracted_cos in dipole.h). Nothing here depends on the incident Fresnel reflection:
//    everything is per unit power ENTERING the medium (as Rd and Jensen's S = (1/pi) Ft Rd Ft
//    are normalised).
//  * Paths are traced WITHOUT absorption and every exit is weighted alpha^n for each albedo
//    alpha of a grid (n the number of scattering events along the path), so one set of paths
//    gives every albedo at once. Likewise one set of paths serves several relative indices
//    eta = n_medium / n_outside (the same at both faces): a face reflects every eta along the
//    same mirrored direction, so each eta only carries its own weight, multiplied at each face
//    by its exact Fresnel reflectance (the transmitted part is tallied for that eta).
//  * Two roulettes keep the cost bounded: on the Fresnel weight (when the largest over the etas
//    falls below 0.1, survive with probability 1/2), and on the path length (each time n passes
//    roulette_order * 2^j, survive with probability 1/2), both unbiased (survivors carry twice
//    the weight).
//  * Optional "short" photons are stopped after `short_orders` scattering events. Exits of
//    order <= short_orders are estimated from all photons, higher orders from the full ones only
//    (unbiased, and many more samples of the low orders that make the near field).
//  * Seeded and deterministic: photon i has its own random stream (splitmix64 of seed, class
//    and index) and tallies are summed per fixed chunk of photons, in chunk order, so results
//    are bit-identical for any number of threads.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace shading {

constexpr int kMaxEtas = 32;

// Radial bins in transport mean free paths rho = r sigma_t' (sigma_t' = 1 - alpha g in these
// units, different for each albedo): bin 0 is the disc [0, rho_0), bin b >= 1 the annulus
// [rho_0 10^((b-1)/per_decade), rho_0 10^(b/per_decade)).
struct RadialBins {
    double rho_0 = 0.01;
    int per_decade = 10;
    int count = 51;  // disc + 50 annuli: 0.01 .. 1000
    double inner(int b) const;
    double outer(int b) const;
    double area(int b) const;  // pi (outer^2 - inner^2)
    // Bin of rho, or `count` beyond the last.
    int index(double rho) const;
};

struct McSettings {
    double g = 0.0;
    std::vector<double> eta{1.0};  // relative indices, each in [1, 4] (at most kMaxEtas)
    double thickness = std::numeric_limits<double>::infinity();  // mean free paths; inf: semi-infinite
    double cos_inside = 1.0;  // cosine of the entering beam's direction inside, (0, 1]
    std::uint64_t photons = 100000;  // full paths
    std::uint64_t short_photons = 0; // extra paths stopped after short_orders events
    int short_orders = 0;
    double roulette_order = 1000.0;  // path-length roulette from this many scattering events on
    std::uint64_t seed = 1;
    int threads = 0;  // 0: std::thread::hardware_concurrency()
    std::vector<double> albedos;  // single-scattering albedos in [0, 1]
    RadialBins bins;
    int angle_bins = 32;  // inside cosine of light arriving at a face, uniform in [0, 1]
    bool radial = true;   // tally radial profiles and angles (off: totals only)
    // Next-event estimate of the radiance reaching each face from inside at the cosines
    // radiance_cosines(), for the scattering orders 2 .. radiance_orders (0: off). Then
    // `arrivals` holds only the orders above radiance_orders. Needs cos_inside = 1 (the
    // azimuthal symmetry of normal incidence: the estimate uses a fixed azimuth).
    int radiance_orders = 0;
    int radiance_nodes = 8;
    // 0.5 (1 - cos(pi (j + 1/2) / (n - 1/2))), j < n: increasing, the last 1
    std::vector<double> radiance_cosines() const;
    // The top face's exit distribution per distance from the entry point: the outer edges
    // (mean free paths, increasing, > 0) of bands [0, e_0), [e_0, e_1), ..., [e_last, inf);
    // empty: off. Needs the radiance estimate (the band of a next-event estimate is where its
    // direction meets the face, at an azimuth drawn from a stream of its own, so the photons'
    // paths and every other tally stay as without bands). See McFace::band_*.
    std::vector<double> exit_bands;
    int band_count() const { return exit_bands.empty() ? 0 : int(exit_bands.size()) + 1; }
    // Oblique incidence's exit distribution (0: off): the top face's next-event radiance at the
    // cosines radiance_cosines() and at `oblique_azimuths` azimuths phi_a = pi a / (A - 1) about
    // the normal, measured from the beam's tangential direction (+x: phi 0 is forward), for the
    // orders 2 .. radiance_orders (McFace::radiance_azimuth). Each node's estimate is the mean
    // of phi_a and -phi_a (the expectation is symmetric about the plane of incidence). Any
    // cos_inside; replaces the normal-incidence estimate (`radiance`), and needs no radial tallies.
    int oblique_azimuths = 0;
    // From this order on (0: off), the multiple-scattering exits of higher orders are tallied
    // apart (McFace::multi_high), and so is the normal-incidence radiance of the orders above it
    // (McFace::radiance_high): the diffusive orders, whose exit distribution hardly depends on how
    // the light entered.
    int high_from = 0;
    // Empty if valid, else the first problem.
    std::string validate() const;
};

// The tallies of one face (top: reflection, bottom: transmission), per albedo k, per unit
// entering power.
struct McFace {
    std::vector<double> ballistic;  // exits without scattering (n = 0)
    std::vector<double> single;     // n = 1
    std::vector<double> multi;      // n >= 2
    // Of the same exits, the weight times the exit's x (mean free paths; the beam travels
    // toward +x inside): multi_x / multi is their mean offset along the beam's tangential
    // direction (0 at normal incidence, by symmetry).
    std::vector<double> multi_x;
    std::vector<double> single_se, multi_se;  // standard errors (photons taken as independent)
    // Multiple-scattering exitance per unit area (transport mfp^2) in RadialBins:
    // radial[k * bins.count + b], and its standard error (exits taken as independent).
    std::vector<double> radial, radial_se;
    // Multiple-scattered light reaching the face from inside, before the Fresnel split, by the
    // inside cosine mu of its direction: arrivals[k * angle_bins + a], a = floor(mu * angle_bins)
    // (orders above radiance_orders only, when the radiance estimate is on).
    std::vector<double> arrivals;
    // Radiance reaching the face from inside at radiance_cosines()[j], uniform illumination, per
    // unit entering flux density, orders 2 .. radiance_orders: radiance[k * radiance_nodes + j].
    std::vector<double> radiance;
    // Per exit-distance band b < B = McSettings::band_count() (top face only; else empty), per
    // albedo k: the multiple-scattering exits' weight band_multi[k * B + b] and weight times
    // distance (mean free paths) band_r[k * B + b]; the next-event radiance of the light
    // leaving within the band band_radiance[(k * B + b) * J + j] (as `radiance`: its sum over
    // the bands) and the high orders' arrivals band_arrivals[(k * B + b) * angle_bins + a] (as
    // `arrivals`).
    std::vector<double> band_multi, band_r, band_radiance, band_arrivals;
    // With McSettings::oblique_azimuths = A (top face only): the radiance reaching the face from
    // inside toward inside cosine mu_j at azimuth phi_a, orders 2 .. radiance_orders, per unit
    // entering power: radiance_azimuth[(k * A + a) * J + j].
    std::vector<double> radiance_azimuth;
    // With McSettings::high_from = h: the exits of order above h (per albedo), and `radiance`'s
    // share of the orders h + 1 .. radiance_orders ([k * J + j]; normal incidence).
    std::vector<double> multi_high, radiance_high;
};

struct McResult {
    McSettings settings;
    std::vector<McFace> top, bottom;  // per eta
    std::uint64_t steps = 0;  // flights simulated
    double seconds = 0;
    int threads_used = 1;
};

// Runs the simulation; throws std::invalid_argument on invalid settings.
McResult run_transport_mc(const McSettings& s);

// The slowest decay rate kappa (per mean free path) of the transport equation in an infinite
// medium with HG scattering: the field far from any source falls as exp(-kappa x). It is 1/nu
// for the largest nu of the P_N recursion (1 - alpha g^l)(2l + 1) phi_l = (l phi_{l-1} +
// (l + 1) phi_{l+1}) / nu, solved as a symmetric tridiagonal eigenproblem (bisection on Sturm
// counts) with N = `moments` terms. 0 for alpha >= 1. Isotropic scattering gives the root of
// (alpha / (2 kappa)) ln((1 + kappa) / (1 - kappa)) = 1.
double transport_decay_rate(double albedo, double g, int moments = 400);

}  // namespace shading
