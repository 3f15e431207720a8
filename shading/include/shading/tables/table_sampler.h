// Importance sampling of a table from its own data: the glossy rays of a
// `brdf_table { "file" samples N }` finish follow the measured lobe, not a generic mixture.
// Two forms, one per kind of interpolation, each with its viewer nodes mixed the same way: a
// viewer between nodes chooses a node with probability proportional to its interpolation
// weight times the node's total mass (the interpolated table's albedo splits the same way);
// pdf() is the same mixture. Cells are chosen from a marginal over rows and a conditional over
// columns, integer CDFs of 2^30 units each (sample() and pdf() read the same integers, so they
// agree exactly; a positive weight keeps at least one unit, so every cell where the table is
// positive stays reachable and the estimator stays unbiased).
//
// Isotropic tables: the table's own cells (theta_i x phi) at each theta_r node j. At a node
// the table is bilinear in (theta_i, phi) inside each cell, and between theta_r nodes it is
// linear in theta_r, so the proposal is the table itself: per unit of (theta_i, phi) the
// density is the cell's bilinear f times L, the linear interpolation of sin theta_i
// cos theta_i between the cell's edges (theta_i from the quadratic marginal by Newton's method
// on its cubic CDF, phi from the linear conditional). f cos / pdf is then the viewer's albedo
// times sin cos / L for every sample: within 1.5e-4 over a 1 deg cell, measured 0.00 % rms in
// the white furnace at m = 0.02 ... 0.5 (per channel, a table whose channels differ, such as
// a measurement with noise, keeps the spread of each channel around their mean). The node
// values are the table's own (channel mean, read on use): memory is the CDFs only, 5.9 MB for
// a 1 deg table (9.1 MB folded RGB payload).
//
// Half/difference and anisotropic tables: a grid in half-vector space, where a glossy lobe is
// compact and hardly moves with the viewer (a microfacet lobe is D(h) for every wo):
//  * Viewer nodes: half/difference tables every degree of theta_o (the half vector reflects
//    the viewer itself); anisotropic tables the table's theta_r nodes x every 30 deg of phi_o
//    (the half vector reflects the node's theta_o at the viewer's azimuth).
//  * Per node, rows in theta_h with edges at (pi/2) (k / H)^2.5 (fine near the normal, where
//    narrow lobes are: 0.05 deg at k = 16 of 256), columns in phi_h: half/difference grids
//    measure phi_h from the viewer's azimuth over [0, pi] (the table is even in it; each side
//    of the plane of incidence gets half the mass), anisotropic ones from the tangent over
//    [0, 2 pi).
//  * At every grid node the target g(h) = f(wo, wi) cos(theta_i) 4 (wo . h) (the channel mean
//    of the interpolated table for wi = reflect(wo, h)): the density of f cos per unit solid
//    angle of h. Inside a cell the density is bilinear in (1 - cos theta_h, phi_h) between its
//    four nodes (sampled exactly by inverting the linear marginal and conditional).
//  * A grid node where the table is zero keeps a floor (1e-2 of its largest neighbour next to
//    a positive node, else 1e-6 of the node's mean density) wherever wi is above or near the
//    horizon, so every direction keeps a positive density.
//  * pdf(wi) = pdf_h(h) / (4 wo . h). A half vector whose reflection falls below the horizon is
//    "no sample" (weight zero, counted in N: still unbiased; under 0.1 % of samples).
//  The per-sample spread of f cos / pdf falls with the rows squared: with 256 x 48 cells 0.3 %
//  for Beckmann m = 0.02, 0.1 % for m = 0.1. Memory per viewer node (H + 1)(P + 1) float node
//  values and H (P + 1) 32-bit CDF entries: 9.1 MB for a half/difference table, 7.6 MB for a
//  5 deg anisotropic one.
//
// Directions are in the local frame (normal +z, tangent +x).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "shading/core/vec.h"

namespace shading {

class BrdfTable;

class TableSampler {
public:
    // Any layout (isotropic, anisotropic, half/difference): reads the table once.
    explicit TableSampler(const BrdfTable& table);
    ~TableSampler();
    TableSampler(const TableSampler&) = delete;
    TableSampler& operator=(const TableSampler&) = delete;

    // wi with density pdf(wo, wi) per solid angle, from (u1, u2) in [0, 1)^2; the zero vector
    // when there is no sample (viewer below the surface, a half vector whose reflection is
    // below the horizon, or a table that is zero there).
    Vec3 sample(const Vec3& wo, double u1, double u2) const;
    double pdf(const Vec3& wo, const Vec3& wi) const;

    size_t bytes_used() const;
    int theta_h_cells() const { return cells_h_; }
    int phi_h_cells() const { return cells_p_; }
    int viewer_nodes() const { return n_to_ * n_po_; }

    // Bytes held by all live samplers, now and at most since the process started (for the
    // renderer's statistics).
    struct Memory {
        size_t live = 0, peak = 0;
    };
    static Memory memory();

private:
    struct Mixture {
        int node[4];
        double p[4];  // probability of each node
        Vec3 ref[4];  // the direction each node's half vectors reflect (see mirror_)
        int count;
    };
    bool mixture(const Vec3& wo, Mixture* m) const;
    // The half vector's cell (a, b) and place (s, t) in it, from h in the viewer's frame.
    struct HPos {
        int a, b;
        double s, t;
    };
    // Density of node k at a place, per unit of (s, t) area of its cell times the cell's
    // probability: the bilinear node values over their cell mean, times P(cell).
    double node_density(int k, const HPos& pos) const;
    // Every layout: the CDFs of node k from its cells' masses (H x P, row-major); the
    // probability of cell (a, b); the node a mixture's u2 chooses (v: u2 stretched back).
    void fill_cdfs(int k, const std::vector<double>& mass);
    double cell_probability(int k, int a, int b) const;
    int choose_node(const Mixture& m, double u2, double* v) const;
    void build_node(const BrdfTable& table, int k, const Vec3& wo, std::vector<double>& g);
    void place_rows();
    Vec3 node_direction(int k) const;
    // Isotropic tables: the table's own cells (see the top of the file and table_sampler.cpp).
    void build_cells(const BrdfTable& table);
    const float* row(int j, int a) const;  // the table's stored row (theta_i a, theta_r j)
    void corners(int j, int a, int b, double v[4]) const;  // channel means: (a,b) (a,b+1) (a+1,b) (a+1,b+1)
    double cell_mass(int a, const double v[4]) const;
    double cell_density(int j, int a, int b, double s, double t) const;
    Vec3 sample_cells(const Vec3& wo, const Mixture& m, double u1, double u2) const;
    double pdf_cells(const Vec3& wo, const Vec3& wi, const Mixture& m) const;
    bool cells_mode_ = false;
    const BrdfTable* table_ = nullptr;  // cells mode: the table that owns this sampler
    int n_ti_ = 0, channels_ = 3;
    double step_ti_ = 0;          // radians
    std::vector<double> sincos_;  // sin theta cos theta of each theta_i node
    // Isotropic and half/difference layouts: phi in [0, pi], either side of the viewer's plane
    // with probability 1/2. Anisotropic grids (false) also reflect each node's own theta_o at
    // the viewer's azimuth, not the viewer (a table between theta_r nodes is the blend of its
    // node planes, which the nodes' mixture then follows); half/difference lobes are fixed in h.
    bool mirror_ = true;
    int n_to_ = 0, n_po_ = 1;     // viewer nodes in theta_o and phi_o
    double step_to_ = 0, step_po_ = 0;  // radians
    int cells_h_ = 0, cells_p_ = 0;     // H, P
    double dphi_ = 0;                   // column width, radians
    std::vector<double> omc_;           // half-vector grids: row edges, 1 - cos(theta_h)
    std::vector<double> total_;         // per node: its mass (an estimate of the albedo)
    std::vector<float> value_;          // [k][a][b]: g at the nodes (floored), (H+1)(P+1) per node
    std::vector<uint32_t> marginal_;    // [k][a]: inclusive cumulative row units
    std::vector<uint32_t> conditional_; // [k][a][b]: inclusive cumulative cell units
    size_t bytes_ = 0;
};

}  // namespace shading
