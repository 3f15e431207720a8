// Helpers shared by the libFuzzer targets (not part of the library).
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "shading/core/bytes.h"
#include "shading/tables/table.h"

// A failed invariant is a crash: libFuzzer saves the input.
inline void fuzz_check(bool ok, const char* what) {
    if (!ok) {
        std::fprintf(stderr, "fuzz: check failed: %s\n", what);
        std::abort();
    }
}

// A copy of a .brdf image whose checksum field (bytes 88..95) holds the FNV-1a-64 of the
// bytes from the header's payload offset (bytes 12..15) to the end, so that mutations of
// the payload get past the checksum. False when the data has no such offset.
inline bool fix_checksum(const uint8_t* data, size_t size, std::vector<uint8_t>& out) {
    if (size < shading::kTableFixedHeader) return false;
    const uint32_t off = uint32_t(data[12]) | uint32_t(data[13]) << 8 | uint32_t(data[14]) << 16 | uint32_t(data[15]) << 24;
    if (off > size) return false;
    out.assign(data, data + size);
    const uint64_t sum = shading::fnv1a64(out.data() + off, size - off);
    for (int k = 0; k < 8; ++k) out[88 + k] = uint8_t(sum >> (8 * k));
    return true;
}
