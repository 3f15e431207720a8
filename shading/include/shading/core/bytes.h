// Internal: little-endian reads and writes of the binary formats (.brdf, .ssp, MERL .binary, the
// fitter's direct payload scan), and their checksum: every reader and writer of the library goes
// through these, so they agree on byte order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

namespace shading {
namespace bytes {

inline uint32_t rd_u32(const uint8_t* p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}
inline uint64_t rd_u64(const uint8_t* p) { return uint64_t(rd_u32(p)) | uint64_t(rd_u32(p + 4)) << 32; }
inline int32_t rd_i32(const uint8_t* p) {
    const uint32_t u = rd_u32(p);
    int32_t i;
    std::memcpy(&i, &u, 4);
    return i;
}
inline float rd_f32(const uint8_t* p) {
    const uint32_t u = rd_u32(p);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}
inline double rd_f64(const uint8_t* p) {
    const uint64_t u = rd_u64(p);
    double d;
    std::memcpy(&d, &u, 8);
    return d;
}

inline void wr_u32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
    for (int k = 0; k < 4; ++k) b[at + k] = uint8_t(v >> (8 * k));
}
inline void wr_u64(std::vector<uint8_t>& b, size_t at, uint64_t v) {
    for (int k = 0; k < 8; ++k) b[at + k] = uint8_t(v >> (8 * k));
}
inline void wr_f32(std::vector<uint8_t>& b, size_t at, float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    wr_u32(b, at, u);
}
inline void wr_f64(std::vector<uint8_t>& b, size_t at, double d) {
    uint64_t u;
    std::memcpy(&u, &d, 8);
    wr_u64(b, at, u);
}

// Appended at the end of `b`.
inline void put_u32(std::vector<uint8_t>& b, uint32_t v) {
    for (int k = 0; k < 4; ++k) b.push_back(uint8_t(v >> (8 * k)));
}
inline void put_u64(std::vector<uint8_t>& b, uint64_t v) {
    put_u32(b, uint32_t(v));
    put_u32(b, uint32_t(v >> 32));
}
inline void put_f32(std::vector<uint8_t>& b, float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    put_u32(b, u);
}
inline void put_f64(std::vector<uint8_t>& b, double d) {
    uint64_t u;
    std::memcpy(&u, &d, 8);
    put_u64(b, u);
}

}  // namespace bytes

// FNV-1a, 64 bit (offset basis 0xcbf29ce484222325, prime 0x100000001b3): the checksum of the
// .brdf and .ssp formats. `h`: the hash of the bytes before `data` (a hash over several pieces).
inline uint64_t fnv1a64(const uint8_t* data, size_t size, uint64_t h = 0xcbf29ce484222325ull) {
    for (size_t k = 0; k < size; ++k) {
        h ^= data[k];
        h *= 0x100000001b3ull;
    }
    return h;
}

}  // namespace shading
