// Internal: short number formatting for describe() strings and error messages.
#pragma once

#include <sstream>
#include <string>

#include "shading/vec.h"

namespace shading {
namespace detail {

// 6 significant digits, shortest form ("0.3", "1e-05").
inline std::string fmt(double v) {
    std::ostringstream s;
    s.precision(6);
    s << v;
    return s.str();
}
// A grey colour as one number, otherwise "r,g,b" (the form model specs accept).
inline std::string fmt(const Rgb& c) {
    if (c.r == c.g && c.g == c.b) return fmt(c.r);
    return fmt(c.r) + "," + fmt(c.g) + "," + fmt(c.b);
}

}  // namespace detail
}  // namespace shading
