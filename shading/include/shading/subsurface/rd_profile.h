// A radial profile Rd(r) per channel, tabulated once for the inner loop of the hierarchical
// evaluation (point_cloud.h), with its disc integrals and its part inside the near field.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <vector>

#include "shading/core/vec.h"

namespace shading {

// The window between a lookup's near field and its far field: 0 below r0 - h, 1 above r0 + h,
// between them the C2 smootherstep t^3 (6 t^2 - 15 t + 10) of t = (r - r0 + h) / 2h (on a grid
// of spacing h its quadrature leaves a fainter pattern than smoothstep's).
inline double far_window(double r, double r0, double h) {
    double t = (r - (r0 - h)) / (2.0 * h);
    if (t <= 0) return 0.0;
    if (t >= 1) return 1.0;
    return t * t * t * (t * (6.0 * t - 15.0) + 10.0);
}

// Rd(r) per channel (exitance at distance r per unit flux entering the medium, per scene
// unit^2), tabulated once for the octree's inner loop with its first two derivatives: cubic
// Hermite in r between nodes (f from f and f', f'' from f'' and f'''). Nodes lie at
// r = scale (s - 1) for s = 2^e (1 + k/64): 64 per octave of 1 + r/scale, uniform within
// `scale` of the peak and logarithmic beyond (the same relative step along an exponential or
// power-law tail), found from the bits of s without a logarithm. 0 at and beyond r_max.
// Relative error below 1e-4 wherever Rd > 1e-9 Rd(0) (SubsurfaceRdProfile tests).
class RdProfile {
public:
    using Fn = std::function<Rgb(double)>;
    // rd(r): the profile, finite and >= 0 for every r >= 0 (called only here, while building
    // and for the near field). disc(R) (may be empty): its integral over a disc of radius R,
    // dimensionless, disc(inf) the total diffuse reflectance; empty: integrated numerically
    // from rd (4-point Gauss-Legendre on each node interval, summed once). scale > 0: the
    // length of the profile's peak (the smallest mean free path 1/sigma_t'); r_max > 0: where
    // rd may be taken as 0. Throws std::invalid_argument for a bad range.
    // sample_every (1, 2, 4, 8, 16): rd is called only at every that many nodes (each with
    // its derivatives); the nodes between take the values and derivatives of the quintic
    // Hermite through those (f, f', f'' at both ends), and a profile without `disc` is
    // integrated on its own table (the interpolant, exactly), not by calling rd. For a
    // profile that is smooth on the scale of that many nodes and costly to call (the
    // multipole's image sums of a slab, made per thickness node in every render). One more
    // call at each sampled interval's middle node checks the quintic there; an interval it
    // misses (the drop to 0 at r_max) is sampled whole. At 4 (slab.h kSlabSampleEvery): the
    // full table to 1.3e-7 of its total per unit of ln r, 5x fewer calls (SlabProfile tests).
    RdProfile(Fn rd, Fn disc, double scale, double r_max, int sample_every = 1);
    // A tabulated profile: radii 0 = r[0] < r[1] < ... and rd per channel at each (>= 0),
    // interpolated monotonically (Fritsch-Carlson cubic in log rd; linear where rd is 0),
    // 0 beyond the last radius. Throws std::invalid_argument on unsorted or bad input.
    static std::shared_ptr<const RdProfile> tabulated(std::vector<double> r, std::vector<Rgb> rd, double scale);

    Rgb rd(double r) const;                           // the table (fast)
    void eval(double r, Rgb* f, Rgb* d1, Rgb* d2) const;  // Rd and d/dr, d2/dr2 (table)
    double rd_channel(int c, double r) const;         // one channel of rd(r)
    void eval_channel(int c, double r, double* f, double* d1, double* d2) const;  // one channel of eval
    Rgb exact(double r) const { return rd_(r); }      // the callable itself
    Rgb disc(double R) const;                         // integral over a disc of radius R
    Rgb total() const { return total_; }              // disc(r_max)
    // Smallest radius holding `fraction` of the total in every channel (bisection on disc).
    double radius_containing(double fraction) const;
    // The part of the profile inside the near/far window of spacing h (R0 = 2h, ramp [h, 3h]):
    // integral of (1 - w(r)) Rd(r) 2 pi r dr per channel.
    Rgb near_reflectance(double h) const;
    double r_max() const { return r_max_; }
    double scale() const { return scale_; }
    // How much a node's squared size/distance ratio may grow at squared distance d2 beyond the
    // profile's peak of 2 pi r^2 Rd(r) (its share of the total per unit log r): by
    // sqrt(peak / share), the aggregation error (~ angle^4 x share) then stays that of the peak,
    // at most 4 (twice the angle). 1 within the peak. Per octave of 1 + d2/scale^2, the smallest
    // over that octave and beyond.
    double angle_gain2(double d2) const {
        const double s2 = 1.0 + d2 * inv_scale_ * inv_scale_;
        std::uint64_t bits;
        std::memcpy(&bits, &s2, sizeof bits);
        const std::size_t e = std::size_t(bits >> 52) - 1023;
        return e < gain2_.size() ? gain2_[e] : gain2_.back();
    }

private:
    struct Node {
        double f[3], d1[3], d2[3], d3[3];
    };
    // The cubic Hermite basis at r < r_max: its interval's nodes, the weights of their values
    // and slopes (h), and those weights' derivatives per unit r (g).
    struct Hermite {
        const Node *a, *b;
        double h00, h10, h01, h11, g00, g10, g11;
        double f(int c) const { return h00 * a->f[c] + h10 * a->d1[c] + h01 * b->f[c] + h11 * b->d1[c]; }
        double d1(int c) const { return g00 * (a->f[c] - b->f[c]) + g10 * a->d1[c] + g11 * b->d1[c]; }
        double d2(int c) const { return h00 * a->d2[c] + h10 * a->d3[c] + h01 * b->d2[c] + h11 * b->d3[c]; }
    };
    Hermite hermite(double r) const;
    // hermite()'s value weights alone (the same arithmetic, the same bits), inline: what a
    // lookup of Rd needs (rd, rd_channel, eval_channel), millions of times per render.
    struct Values {
        const Node *a, *b;
        double u, dr, h00, h10, h01, h11;
        double f(int c) const { return h00 * a->f[c] + h10 * a->d1[c] + h01 * b->f[c] + h11 * b->d1[c]; }
    };
    Values values(double r) const;
    Fn rd_, disc_;
    double scale_ = 1, inv_scale_ = 1, r_max_ = 1;
    Rgb total_;
    Rgb interval_integral(double a, double b) const;
    bool integrate_table_ = false;  // interval_integral of the table, not of rd_ (sample_every > 1)
    std::vector<Node> nodes_;
    std::vector<double> node_r_;
    std::vector<Rgb> cumulative_;  // without a disc callable: the integral up to each node
    std::vector<double> gain2_;
};

// A weight per channel on a radial profile for one lookup, varying slowly with r: the exit
// distribution's change with distance from the entry point (RadialProfile::exit_weight;
// DIPOLE.md 10.7). Linear in s = 1 + r / scale between nodes at s = 2^e (1 + q/4), q < 4 (four
// per octave of s: 0, scale / 4, ... uniform near 0, logarithmic far out), found from the bits
// of s like RdProfile's nodes; node 0 at r = 0; the last node's value held beyond it.
struct RadialWeight {
    static constexpr int kPerOctave = 4;
    static constexpr int kMaxNodes = kPerOctave * 40 + 1;
    double inv_scale = 1;
    int nodes = 1;            // nodes in use, 1 .. kMaxNodes
    double w[kMaxNodes][3];   // per node, per channel

    // r / scale at node i
    static double node_x(int i) { return std::ldexp(1.0 + double(i % kPerOctave) / kPerOctave, i / kPerOctave) - 1.0; }
    double at(int c, double r) const {
        if (nodes < 2) return w[0][c];
        int i;
        const double t = locate(r, &i);
        return w[i][c] + (w[i + 1][c] - w[i][c]) * t;
    }
    Rgb at(double r) const {
        if (nodes < 2) return Rgb(w[0][0], w[0][1], w[0][2]);
        int i;
        const double t = locate(r, &i);
        const double* a = w[i];
        const double* b = w[i + 1];
        return Rgb(a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t);
    }

private:
    // The segment [i, i + 1] holding r and the fraction of it (nodes >= 2); beyond the last
    // node (or for a bad r) i = nodes - 2 with fraction 1.
    double locate(double r, int* i) const {
        const double s = 1.0 + r * inv_scale;
        if (!(s >= 1.0 && s < 1e300)) {
            *i = nodes - 2;
            return 1.0;
        }
        std::uint64_t bits;
        std::memcpy(&bits, &s, sizeof bits);
        const std::uint64_t m = bits & ((std::uint64_t(1) << 52) - 1);
        const int k = int((bits >> 52) - 1023) * kPerOctave + int(m >> 50);
        if (k >= nodes - 1) {
            *i = nodes - 2;
            return 1.0;
        }
        *i = k;
        return double(m & ((std::uint64_t(1) << 50) - 1)) * 0x1p-50;
    }
};

}  // namespace shading
