// Internal: number formatting for describe() strings, specs and error messages.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

#include "shading/core/vec.h"

namespace shading {
namespace detail {

// `digits` significant digits, shortest form (printf's %g: "0.3", "1e-05"); 17 digits
// round-trip a double exactly, 9 a float.
inline std::string fmt(double v, int digits = 6) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    return buf;
}
// A stored float as messages show it: "nan", "inf", "-inf" or 9 digits (the float exactly).
inline std::string fmt_float(float v) {
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    return fmt(v, 9);
}
// A checksum as the file formats' messages print it: "0x" and 16 hex digits.
inline std::string hex64(uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
    return buf;
}
// A grey colour as one number, otherwise "r,g,b" (the form model specs accept).
inline std::string fmt(const Rgb& c, int digits = 6) {
    if (c.r == c.g && c.g == c.b) return fmt(c.r, digits);
    return fmt(c.r, digits) + "," + fmt(c.g, digits) + "," + fmt(c.b, digits);
}

}  // namespace detail
}  // namespace shading
