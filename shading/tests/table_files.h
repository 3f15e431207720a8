// Helpers of the tests that damage .brdf images and MERL files and read what the readers say
// (table_test.cpp, table_halfdiff_test.cpp, merl_test.cpp, robustness_test.cpp).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <exception>
#include <regex>
#include <string>
#include <vector>

#include "shading/core/bytes.h"
#include "shading/tables/table.h"

namespace table_files {

// Rewrites the payload checksum (bytes 88..95) after an edit, so the checks behind it are reached.
inline void fix_checksum(std::vector<uint8_t>& b) {
    const uint32_t off = shading::bytes::rd_u32(&b[12]);
    shading::bytes::wr_u64(b, 88, shading::fnv1a64(b.data() + off, b.size() - off));
}

// A copy of `b` with `v` written at byte `at` (host byte order: little-endian).
template <class T>
std::vector<uint8_t> with_value(const std::vector<uint8_t>& b, size_t at, T v) {
    std::vector<uint8_t> out = b;
    std::memcpy(&out[at], &v, sizeof v);
    return out;
}

// The message of the TableError that fn throws ("NO EXCEPTION", or "WRONG EXCEPTION TYPE: ...").
template <class Fn>
std::string table_error_of(Fn&& fn) {
    try {
        fn();
    } catch (const shading::TableError& e) {
        return e.what();
    } catch (const std::exception& e) {
        return std::string("WRONG EXCEPTION TYPE: ") + e.what();
    }
    return "NO EXCEPTION";
}

// The loader's message for the image `b` called `name` ("(no error)" when it loads).
inline std::string load_error(const std::vector<uint8_t>& b, const std::string& name,
                              const shading::LoadOptions& opt = {}) {
    try {
        shading::load_table(b.data(), b.size(), name, opt);
    } catch (const shading::TableError& e) {
        return e.what();
    }
    return "(no error)";
}

// `msg` reads "NAME: offset N: expected X, found Y" with N = `offset`.
inline void expect_error_at(const std::string& msg, const std::string& name, uint64_t offset) {
    const std::string quoted = std::regex_replace(name, std::regex("\\."), "\\.");
    EXPECT_TRUE(std::regex_match(msg, std::regex(quoted + ": offset [0-9]+: expected .+, found .+"))) << msg;
    EXPECT_NE(msg.find("offset " + std::to_string(offset) + ":"), std::string::npos) << msg;
}

}  // namespace table_files
