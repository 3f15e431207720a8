// MERL .binary import and conversion to BrdfTable (see merl.h for the layout and bins).
#include "shading/tables/merl.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>

#include "shading/core/bytes.h"
#include "shading/core/format.h"

namespace shading {

namespace {

// Rotations about the frame axes by angle a (right-handed).
Vec3 rot_z(const Vec3& v, double a) {
    double c = std::cos(a), s = std::sin(a);
    return {v.x * c - v.y * s, v.x * s + v.y * c, v.z};
}
Vec3 rot_y(const Vec3& v, double a) {
    double c = std::cos(a), s = std::sin(a);
    return {v.x * c + v.z * s, v.y, -v.x * s + v.z * c};
}

using bytes::rd_f64;
using bytes::rd_i32;

const char* kChannelName[3] = {"R", "G", "B"};

}  // namespace

HalfDiff to_half_diff(const Vec3& wi, const Vec3& wo) {
    Vec3 h = wi + wo;
    double len = length(h);
    // wi = -wo happens only for two opposite horizon directions; the limit of the mirror
    // configuration approaching them is h = n, so use that instead of dividing by 0.
    h = len > 1e-12 ? h * (1.0 / len) : Vec3(0, 0, 1);
    HalfDiff r;
    r.theta_h = std::atan2(std::hypot(h.x, h.y), h.z);
    r.phi_h = std::atan2(h.y, h.x);
    Vec3 d = rot_y(rot_z(wi, -r.phi_h), -r.theta_h);
    r.theta_d = std::atan2(std::hypot(d.x, d.y), d.z);
    r.phi_d = std::atan2(d.y, d.x);
    return r;
}

void from_half_diff(const HalfDiff& hd, Vec3& wi, Vec3& wo) {
    Vec3 d = spherical_direction(hd.theta_d, hd.phi_d);
    wi = rot_z(rot_y(d, hd.theta_h), hd.phi_h);
    Vec3 h = spherical_direction(hd.theta_h, hd.phi_h);
    wo = h * (2.0 * dot(h, wi)) - wi;
}

// Lower bin, clamped, as in MERL's reference reader. sqrt() spreads the theta_h bins so
// they are finest near theta_h = 0, where specular peaks live.
uint32_t merl_theta_h_bin(double theta_h, uint32_t n) {
    if (!(theta_h > 0)) return 0;
    double x = std::sqrt(theta_h / (kPi / 2)) * n;
    return x >= double(n - 1) ? n - 1 : uint32_t(x);
}
uint32_t merl_theta_d_bin(double theta_d, uint32_t n) {
    double x = theta_d / (kPi / 2) * n;
    if (!(x > 0)) return 0;
    return x >= double(n - 1) ? n - 1 : uint32_t(x);
}
uint32_t merl_phi_d_bin(double phi_d, uint32_t n) {
    if (phi_d < 0) phi_d += kPi;  // reciprocity: phi_d and phi_d + pi share a bin
    double x = phi_d / kPi * n;
    if (!(x > 0)) return 0;
    return x >= double(n - 1) ? n - 1 : uint32_t(x);
}

MerlBrdf::MerlBrdf(const MerlDims& dims, std::vector<double> raw, std::string name)
    : dims_(dims), raw_(std::move(raw)), name_(std::move(name)) {
    if (dims_.theta_h < 1 || dims_.theta_d < 1 || dims_.phi_d < 1 || dims_.theta_h > kMaxDim ||
        dims_.theta_d > kMaxDim || dims_.phi_d > kMaxDim)
        throw std::invalid_argument("MerlBrdf: dimensions out of range [1, 4096]");
    if (raw_.size() != 3 * dims_.per_channel())
        throw std::invalid_argument("MerlBrdf: " + std::to_string(raw_.size()) + " samples, needs " +
                                    std::to_string(3 * dims_.per_channel()));
    // +-Inf is never a no-data marker (parse() rejects it with the sample's offset): a bin
    // holding +Inf would pass the lookup's ">= 0" test and shine infinitely.
    for (size_t k = 0; k < raw_.size(); ++k)
        if (std::isinf(raw_[k]))
            throw std::invalid_argument("MerlBrdf: sample " + std::to_string(k) + " is " + (raw_[k] > 0 ? "inf" : "-inf") +
                                        " (no-data markers are negative or NaN)");
    const uint64_t n = dims_.per_channel();
    for (uint64_t k = 0; k < n; ++k)
        for (int c = 0; c < 3; ++c)
            if (!(raw_[c * n + k] >= 0)) {
                ++nodata_bins_;
                break;
            }
}

std::unique_ptr<MerlBrdf> MerlBrdf::parse(const uint8_t* data, size_t size, const std::string& name) {
    if (size < 12)
        throw_table_error(name, size, "a 12-byte header (three int32 dimensions)",
                          "end of data after " + std::to_string(size) + " bytes");
    int32_t d[3] = {rd_i32(data), rd_i32(data + 4), rd_i32(data + 8)};
    static const char* dim_name[3] = {"theta_h", "theta_d", "phi_d"};
    for (int k = 0; k < 3; ++k)
        if (d[k] < 1 || d[k] > int32_t(kMaxDim))
            throw_table_error(name, 4 * size_t(k),
                              std::string(dim_name[k]) + " dimension in [1, 4096] (standard: 90, 90, 180)",
                              std::to_string(d[k]));
    MerlDims dims{uint32_t(d[0]), uint32_t(d[1]), uint32_t(d[2])};
    const uint64_t count = 3 * dims.per_channel();  // <= 3 * 4096^3: no overflow in bytes
    const uint64_t total = 12 + 8 * count;
    std::ostringstream shape;
    shape << total << " bytes (12-byte header + 3 channels x " << d[0] << "x" << d[1] << "x" << d[2] << " doubles)";
    if (size < total) throw_table_error(name, size, shape.str(), "end of data");
    if (size > total) throw_table_error(name, total, "end of data after " + shape.str(),
                                        std::to_string(size - total) + " trailing bytes");
    for (uint64_t k = 0; k < count; ++k) {
        double v = rd_f64(data + 12 + 8 * k);
        if (std::isinf(v))
            throw_table_error(name, 12 + 8 * k, "a finite sample or a no-data marker (negative or NaN)", detail::fmt(v, 9));
    }
    std::vector<double> raw(count);
    for (uint64_t k = 0; k < count; ++k) raw[k] = rd_f64(data + 12 + 8 * k);
    return std::make_unique<MerlBrdf>(dims, std::move(raw), name);
}

std::unique_ptr<MerlBrdf> MerlBrdf::load_file(const std::string& path) {
    std::vector<uint8_t> bytes = read_file_bytes(path);
    return parse(bytes.data(), bytes.size(), path);
}

MerlBrdf::Bin MerlBrdf::bin(const HalfDiff& hd) const {
    Bin b;
    b.theta_h = merl_theta_h_bin(hd.theta_h, dims_.theta_h);
    b.theta_d = merl_theta_d_bin(hd.theta_d, dims_.theta_d);
    b.phi_d = merl_phi_d_bin(hd.phi_d, dims_.phi_d);
    b.index = (uint64_t(b.theta_h) * dims_.theta_d + b.theta_d) * dims_.phi_d + b.phi_d;
    return b;
}

Rgb MerlBrdf::value(const Bin& b) const {
    const uint64_t n = dims_.per_channel();
    return {raw_[b.index] * kScale[0], raw_[n + b.index] * kScale[1], raw_[2 * n + b.index] * kScale[2]};
}

Rgb MerlBrdf::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    Rgb v = value(bin(wi, wo));
    for (int c = 0; c < 3; ++c)
        if (!(v[c] >= 0)) v[c] = 0.0;  // no data: never negative light
    return v;
}

std::string MerlBrdf::describe() const {
    std::ostringstream s;
    s << "merl(" << name_ << ", " << dims_.theta_h << "x" << dims_.theta_d << "x" << dims_.phi_d
      << (dims_.standard() ? "" : " non-standard") << ", " << nodata_bins_ << " bins without data)";
    return s.str();
}

std::unique_ptr<BrdfTable> merl_to_table(const MerlBrdf& merl, const MerlConvertOptions& opt) {
    TableGrid grid(TableGeometry::isotropic(opt.step_deg, opt.channels));
    const TableGeometry& g = grid.geom;
    const int C = g.channels;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (uint32_t i = 0; i < g.n[0]; ++i) {
        Vec3 wi = spherical_direction(g.axis_deg(0, i) * kDegree, 0.0);
        for (uint32_t r = 0; r < g.n[1]; ++r)
            for (uint32_t p = 0; p < g.n[2]; ++p) {
                Vec3 wo = spherical_direction(g.axis_deg(1, r) * kDegree, g.axis_deg(2, p) * kDegree);
                MerlBrdf::Bin b = merl.bin(wi, wo);
                Rgb v = merl.value(b);
                for (int c = 0; c < 3; ++c)
                    if (!(v[c] >= 0) && opt.nodata == NoDataPolicy::Reject) {
                        std::ostringstream e;
                        e << "a sample >= 0 for table node theta_i=" << detail::fmt(g.axis_deg(0, i), 9)
                          << " theta_r=" << detail::fmt(g.axis_deg(1, r), 9) << " phi=" << detail::fmt(g.axis_deg(2, p), 9)
                          << " deg (bin theta_h=" << b.theta_h << " theta_d=" << b.theta_d << " phi_d=" << b.phi_d
                          << ", channel " << kChannelName[c] << "; no-data policy: reject)";
                        throw_table_error(merl.name(), merl.file_offset(b, c), e.str(), detail::fmt(v[c] / MerlBrdf::kScale[c], 9));
                    }
                const uint64_t cell = grid.cell(i, r, p);
                if (C == 1) {
                    bool ok = v.r >= 0 && v.g >= 0 && v.b >= 0;
                    grid.values[cell] = ok ? float(v.average()) : nan;
                } else {
                    for (int c = 0; c < 3; ++c) grid.values[cell * 3 + c] = v[c] >= 0 ? float(v[c]) : nan;
                }
            }
    }
    BuildOptions bo;
    bo.nodata = opt.nodata;
    bo.fold = opt.fold;
    bo.interp = opt.interp;
    bo.name = merl.name();
    bo.description = "MERL " + merl.name() + " (" + std::to_string(merl.dims().theta_h) + "x" +
                     std::to_string(merl.dims().theta_d) + "x" + std::to_string(merl.dims().phi_d) +
                     ", reference bin lookup)";
    return build_table(std::move(grid), bo);
}

std::unique_ptr<BrdfTable> merl_to_halfdiff(const MerlBrdf& merl, const MerlConvertOptions& opt) {
    const MerlDims& d = merl.dims();
    if (opt.fold)
        throw std::invalid_argument("merl_to_halfdiff: a half/difference table is reciprocal by construction (no --fold)");
    if (d.theta_h < 2 || d.theta_d < 2 || d.phi_d < 2)
        throw std::invalid_argument("merl_to_halfdiff: " + merl.describe() +
                                    ": a half/difference table needs at least 2 bins per axis");
    TableGrid grid(TableGeometry::halfdiff(d.theta_h, d.theta_d, d.phi_d, opt.channels));
    const TableGeometry& g = grid.geom;
    const int C = g.channels;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    uint32_t idx[4];
    Vec3 wi, wo;
    for (uint64_t cell = 0, cells = g.cells(); cell < cells; ++cell) {
        g.unravel(cell, idx);
        MerlBrdf::Bin b;
        b.theta_h = idx[0];
        b.theta_d = idx[1];
        b.phi_d = idx[2];
        b.index = cell;  // the same row-major order as MERL's channel planes
        const Rgb v = merl.value(b);
        bool ok = true;
        for (int c = 0; c < 3; ++c) ok = ok && v[c] >= 0;
        if (!ok && opt.nodata == NoDataPolicy::Reject && g.halfdiff_node_pair(idx, wi, wo)) {
            int c = 0;
            while (v[c] >= 0) ++c;
            std::ostringstream e;
            e << "a sample >= 0 in bin theta_h=" << b.theta_h << " theta_d=" << b.theta_d << " phi_d=" << b.phi_d
              << " (channel " << kChannelName[c] << ", both directions above the horizon; no-data policy: reject)";
            throw_table_error(merl.name(), merl.file_offset(b, c), e.str(), detail::fmt(v[c] / MerlBrdf::kScale[c], 9));
        }
        if (C == 1)
            grid.values[cell] = ok ? float(v.average()) : nan;
        else
            for (int c = 0; c < 3; ++c) grid.values[cell * 3 + c] = v[c] >= 0 ? float(v[c]) : nan;
    }
    BuildOptions bo;
    bo.nodata = NoDataPolicy::Fill;  // inside no-data cells were rejected above if asked to
    bo.interp = opt.interp;
    bo.name = merl.name();
    bo.description = "MERL " + merl.name() + " (" + std::to_string(d.theta_h) + "x" + std::to_string(d.theta_d) + "x" +
                     std::to_string(d.phi_d) + ", bins stored as nodes, no resampling)";
    return build_table(std::move(grid), bo);
}

}  // namespace shading
