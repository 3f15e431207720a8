// Importance sampling of a table from its own data: the glossy rays of a
// `brdf_table { "file" samples N }` finish follow the measured lobe, not a generic mixture.
//
// The distribution (in the spirit of pbrt-v4's measured BxDF: tabulated marginal and
// conditional distributions, built once per table):
//  * For each theta_o node j of the table (its theta_r axis: the viewer), every cell
//    (theta_i in [t_a, t_a+1], phi in [p_b, p_b+1]) of the table's own grid gets the weight
//        W_jab = mean of the cell's four corner values (channel average) x integral of cos
//                over the cell and its mirror image -phi (= dphi (sin^2 t_a+1 - sin^2 t_a)),
//    an estimate of the cell's share of the directional albedo a(theta_o_j). A cell weighs
//    more than zero exactly when one of its corners does, so every direction where the
//    interpolated table is positive can be sampled (the estimator stays unbiased).
//  * Cells are chosen from a marginal over theta_i rows and a conditional over phi cells
//    (integer CDFs: every positive weight keeps at least one unit, and sample() and pdf()
//    read the same integers, so they agree exactly); inside a cell the density is
//    proportional to cos(theta_i) (sin^2 theta uniform, phi uniform), and the sign of phi
//    is chosen with probability 1/2.
//  * A viewer between nodes j0 and j1 (theta_o weight t toward j1) samples node j0 with
//    probability alpha = (1-t) A_j0 / ((1-t) A_j0 + t A_j1), A_j the node's total weight:
//    the interpolated table's albedo splits the same way. pdf() is the same mixture.
// Memory: per node, (n_theta - 1) 32-bit marginal entries and (n_theta - 1)(n_phi - 1)
// 16-bit conditional entries: 2.9 MB for a 1 deg table (9.1 MB folded RGB payload).
//
// Directions are in the local frame (normal +z); the table's phi = phi_r - phi_i is measured
// from the viewer's azimuth, so the sampler is isotropic like the table.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "shading/core/vec.h"

namespace shading {

class BrdfTable;

class TableSampler {
public:
    // Isotropic tables: reads the nodes once. Half/difference tables: their values on a 1 deg
    // isotropic grid (the same distribution, cells floored at 1e-3 of the mean value so a
    // lobe narrower than a cell is still reachable). Anisotropic: std::invalid_argument.
    explicit TableSampler(const BrdfTable& table);
    ~TableSampler();
    TableSampler(const TableSampler&) = delete;
    TableSampler& operator=(const TableSampler&) = delete;

    // wi with density pdf(wo, wi) per solid angle, from (u1, u2) in [0, 1)^2; the zero vector
    // when there is no sample (viewer below the surface, or a table that is zero there).
    Vec3 sample(const Vec3& wo, double u1, double u2) const;
    double pdf(const Vec3& wo, const Vec3& wi) const;

    size_t bytes_used() const;

    // Bytes held by all live samplers, now and at most since the process started (for the
    // renderer's statistics).
    struct Memory {
        size_t live = 0, peak = 0;
    };
    static Memory memory();

private:
    struct Mixture {
        int j0, j1;
        double alpha;  // probability of node j0
    };
    bool mixture(double cos_o, Mixture* m) const;
    double cell_pdf(int j, int a, int b) const;  // probability of cell (a, b) at node j

    int n_theta_i_ = 0, n_theta_o_ = 0, n_phi_ = 0;  // nodes per axis
    int cells_t_ = 0, cells_p_ = 0;                  // cells: nodes - 1
    double step_t_deg_ = 0, step_o_deg_ = 0, step_p_deg_ = 0;
    std::vector<double> sin2_;                // sin^2 of each theta_i node
    std::vector<double> total_;               // per theta_o node: the sum of its cell weights
    std::vector<uint32_t> marginal_;          // [j][a]: inclusive cumulative row units
    std::vector<uint16_t> conditional_;       // [j][a][b]: inclusive cumulative cell units
    size_t bytes_ = 0;
};

}  // namespace shading
