// Importance sampling of a table from its own data: the glossy rays of a
// `brdf_table { "file" samples N }` finish follow the measured lobe, not a generic mixture.
//
// The distribution lives in half-vector space, where a glossy lobe is compact and hardly
// moves with the viewer (a microfacet lobe is D(h) for every wo), so a fixed grid resolves a
// lobe of any width the grid's finest rows can hold:
//  * Viewer nodes: isotropic tables use the table's theta_r nodes, half/difference tables
//    every degree of theta_o; anisotropic tables the table's theta_r nodes x every 30 deg of
//    phi_o. A viewer between nodes mixes the nodes' distributions with probabilities
//    proportional to their interpolation weights times their total mass (the interpolated
//    table's albedo splits the same way); pdf() is the same mixture.
//  * Per node, a grid over the half vector h: rows in theta_h with edges at
//    (pi/2) (k / H)^2 (fine near the normal, where narrow lobes are: 0.9 deg at k = 8 of 128),
//    columns in phi_h. Isotropic layouts measure phi_h from the viewer's azimuth over
//    [0, pi] (the table is even in phi; each side of the plane of incidence gets half the
//    mass); anisotropic tables from the tangent over [0, 2 pi).
//  * At every grid node the target g(h) = f(wo, wi) cos(theta_i) 4 (wo . h), the channel
//    mean of the interpolated table for wi = reflect(wo, h): the density of f cos per unit
//    solid angle of h. Inside a cell the density per solid angle is bilinear in
//    (1 - cos theta_h, phi_h) between the cell's four nodes (sampled exactly by inverting the
//    linear marginal and conditional), so it follows the lobe's slope, not only its cell
//    mean; cells are chosen from a marginal over rows and a conditional over columns (integer
//    CDFs: sample() and pdf() read the same integers, so they agree exactly).
//  * Every node value is floored at 1e-3 of the node's mean density wherever wi is above or
//    near the horizon, so every direction where the table can be positive keeps a positive
//    density (the estimator stays unbiased whatever the table does between grid nodes).
//  * wi = reflect(wo, h) and pdf(wi) = pdf_h(h) / (4 wo . h). A half vector whose reflection
//    falls below the horizon is "no sample" (weight zero, counted in N: still unbiased).
// Memory per viewer node: (H + 1)(P + 1) float node values, H 32-bit row and H P 16-bit
// column entries; 3.6 MB for a 1 deg isotropic table (9.1 MB folded RGB payload).
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
        Vec3 ref[4];  // the direction each node's half vectors reflect (node_frame_)
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
    void build_node(const BrdfTable& table, int k, const Vec3& wo, std::vector<double>& g);
    void place_rows();
    Vec3 node_direction(int k) const;

    bool mirror_ = true;
    // Half vectors reflect the node's own theta_o at the viewer's azimuth (isotropic and
    // anisotropic grids: a table between theta_r nodes is the blend of its node planes, which the
    // nodes' mixture then follows exactly), or the viewer itself (half/difference tables, whose
    // lobes are fixed in h).
    bool node_frame_ = true;          // isotropic: phi_h in [0, pi], either side with probability 1/2
    int n_to_ = 0, n_po_ = 1;     // viewer nodes in theta_o and phi_o
    double step_to_ = 0, step_po_ = 0;  // radians
    int cells_h_ = 0, cells_p_ = 0;     // H, P
    double dphi_ = 0;                   // column width, radians
    std::vector<double> omc_;           // 1 - cos(theta_h) at the H + 1 row edges
    std::vector<double> total_;         // per node: its mass (an estimate of the albedo)
    std::vector<float> value_;          // [k][a][b]: g at the nodes (floored), (H+1)(P+1) per node
    std::vector<uint32_t> marginal_;    // [k][a]: inclusive cumulative row units
    std::vector<uint16_t> conditional_; // [k][a][b]: inclusive cumulative cell units
    size_t bytes_ = 0;
};

}  // namespace shading
