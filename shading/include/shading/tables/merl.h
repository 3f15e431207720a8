// MERL BRDF database import (Matusik et al. 2003, "A Data-Driven Reflectance Model").
//
// A MERL .binary file is three little-endian int32 dimensions (90, 90, 180: theta_h,
// theta_d, phi_d bins) followed by 3 x 90 x 90 x 180 little-endian doubles, channel-major
// (all red samples, then green, then blue); within a channel the index is
// (theta_h_bin * 90 + theta_d_bin) * 180 + phi_d_bin. Values are scaled by
// 1/1500 (R), 1.15/1500 (G), 1.66/1500 (B) to give the BRDF in 1/sr. Negative samples
// (and NaN) mean "no data".
//
// The bins use Rusinkiewicz's half/difference angles (to_half_diff below), looked up as
// in MERL's reference reader (BRDFRead.cpp), i.e. the lower bin, clamped to the last:
//   theta_h bin = floor(sqrt(theta_h / (pi/2)) * 90)   (finer near the specular peak)
//   theta_d bin = floor(theta_d / (pi/2) * 90)
//   phi_d bin   = floor(phi_d / pi * 180), phi_d first moved to [0, pi) by adding pi
//                 when negative (reciprocity: f is unchanged under phi_d -> phi_d + pi).
// Files with other (positive) dimensions use the same formulas with their own counts.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "shading/tables/table.h"

namespace shading {

// Half/difference angles (Rusinkiewicz 1998) of a direction pair in the local frame:
// h = normalize(wi + wo); (theta_h, phi_h) its spherical angles; d = R_y(-theta_h) R_z(-phi_h) wi.
struct HalfDiff {
    double theta_h = 0, phi_h = 0, theta_d = 0, phi_d = 0;
};
HalfDiff to_half_diff(const Vec3& wi, const Vec3& wo);
// Inverse of to_half_diff: wi = R_z(phi_h) R_y(theta_h) d, wo its mirror image about h.
void from_half_diff(const HalfDiff& hd, Vec3& wi, Vec3& wo);

uint32_t merl_theta_h_bin(double theta_h, uint32_t n);
uint32_t merl_theta_d_bin(double theta_d, uint32_t n);
uint32_t merl_phi_d_bin(double phi_d, uint32_t n);

struct MerlDims {
    uint32_t theta_h = 90, theta_d = 90, phi_d = 180;
    uint64_t per_channel() const { return uint64_t(theta_h) * theta_d * phi_d; }
    bool standard() const { return theta_h == 90 && theta_d == 90 && phi_d == 180; }
};

class MerlBrdf final : public Brdf {
public:
    static constexpr double kScale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};
    static constexpr uint32_t kMaxDim = 4096;

    // Validates the whole image (dims in [1, 4096], exact byte count, no +-Inf) before
    // allocating; errors are TableError "NAME: offset N: expected X, found Y".
    static std::unique_ptr<MerlBrdf> parse(const uint8_t* data, size_t size, const std::string& name);
    static std::unique_ptr<MerlBrdf> load_file(const std::string& path);
    // Raw (unscaled) channel-major samples, as in the file. Throws std::invalid_argument on
    // dimensions out of range, a sample count that does not match them, or any +-Inf sample.
    MerlBrdf(const MerlDims& dims, std::vector<double> raw, std::string name);

    struct Bin {
        uint32_t theta_h = 0, theta_d = 0, phi_d = 0;
        uint64_t index = 0;  // within one channel
    };
    Bin bin(const HalfDiff& hd) const;
    Bin bin(const Vec3& wi, const Vec3& wo) const { return bin(to_half_diff(wi, wo)); }
    // Scaled samples of a bin; a negative or NaN channel means no data.
    Rgb value(const Bin& b) const;
    // Byte offset of a bin's sample of `channel` in the .binary file.
    uint64_t file_offset(const Bin& b, int channel) const { return 12 + 8 * (channel * dims_.per_channel() + b.index); }

    // The reference lookup; channels without data read 0 (never negative light).
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    std::string describe() const override;

    const MerlDims& dims() const { return dims_; }
    const std::string& name() const { return name_; }
    uint64_t nodata_bins() const { return nodata_bins_; }  // bins with a channel without data

private:
    MerlDims dims_;
    std::vector<double> raw_;
    std::string name_;
    uint64_t nodata_bins_ = 0;
};

struct MerlConvertOptions {
    double step_deg = 1.0;
    int channels = 3;  // 1: mean of R, G, B
    NoDataPolicy nodata = NoDataPolicy::Fill;
    bool fold = false;  // lossless for MERL data: the parameterisation is reciprocal
    Interp interp = Interp::Linear;
};
// Evaluates the reference lookup at every (theta_i, theta_r, phi) node (wi at azimuth 0,
// wo at azimuth phi). Nodes whose bin has no data become no-data cells: Fill fills them in
// the table's angles (see NoDataPolicy); Reject throws naming the MERL sample's offset.
std::unique_ptr<BrdfTable> merl_to_table(const MerlBrdf& merl, const MerlConvertOptions& opt);

// MERL's own grid as a half/difference table (layout 3, table.h), without resampling: node
// (i, j, k) holds bin (i, j, k), channel scales applied (float32 of raw x scale; 1 channel:
// the mean of R, G, B). Bins without data (negative or NaN) follow opt.nodata for cells
// inside the domain (Reject: TableError naming the MERL sample's byte offset; Fill: the
// table's no-data rule); outside cells (a direction below the horizon, where MERL files
// hold -1) are filled under either policy and not counted. opt.step_deg and opt.fold do not
// apply (std::invalid_argument for fold). Dimensions below 2 are std::invalid_argument.
std::unique_ptr<BrdfTable> merl_to_halfdiff(const MerlBrdf& merl, const MerlConvertOptions& opt);

}  // namespace shading
