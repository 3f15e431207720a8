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
    const uint32_t off = shading::bytes::rd_u32(data + 12);
    if (off > size) return false;
    out.assign(data, data + size);
    shading::bytes::wr_u64(out, 88, shading::fnv1a64(out.data() + off, size - off));
    return true;
}

// The header of a .brdf image, or false where parse_table_header refuses it (a TableError,
// the expected outcome for most inputs; anything else is a crash).
inline bool table_header(const uint8_t* data, size_t size, shading::TableHeader* h) {
    try {
        *h = shading::parse_table_header(data, size, "fuzz.brdf");
    } catch (const shading::TableError&) {
        return false;
    }
    return true;
}

// A target's whole run: `check` on the input as given, then on a copy whose checksum `fix`
// made right (where it can), so mutations of the payload reach the checks behind it.
template <class Check, class Fix>
int run_with_fixed_checksum(const uint8_t* data, size_t size, Check check, Fix fix) {
    check(data, size);
    std::vector<uint8_t> fixed;
    if (fix(data, size, fixed)) check(fixed.data(), fixed.size());
    return 0;
}
