// Reading and writing the spec grammar (spec_args.h).
#include "shading/brdf/spec_args.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

#include "shading/core/format.h"

namespace shading {

void spec_error(const std::string& msg) { throw std::invalid_argument("make_brdf: " + msg); }

namespace {
std::string range_text(const SpecKey& k) {
    return k.lo <= k.hi ? ", range [" + detail::fmt(k.lo) + "," + detail::fmt(k.hi) + "]" : "";
}
}  // namespace

std::string help_line(const SpecKey& k, const std::string& def) {
    std::string head = std::string(k.name) + "=" + k.type;
    head.resize(std::max<size_t>(head.size() + 2, 16), ' ');
    return head + k.what + (def.empty() ? "" : ", default " + def) + range_text(k) + k.note + "\n";
}

// ---------------------------------------------------------------- SpecArgs

bool SpecArgs::has(const std::string& key) const {
    for (auto& p : kv_)
        if (p.first == key) return true;
    return false;
}

std::vector<std::string> SpecArgs::all(const std::string& key) {
    used_.insert(key);
    std::vector<std::string> out;
    for (auto& p : kv_)
        if (p.first == key) out.push_back(p.second);
    return out;
}

const std::string* SpecArgs::one(const std::string& key) {
    used_.insert(key);
    const std::string* v = nullptr;
    for (auto& p : kv_) {
        if (p.first != key) continue;
        if (v) spec_error(where(key) + "given more than once");
        v = &p.second;
    }
    return v;
}

std::string SpecArgs::where(const std::string& key) const { return model_ + ": key '" + key + "': "; }

double SpecArgs::number(const std::string& key, double def, double lo, double hi, bool required) {
    const std::string* v = one(key);
    if (!v) {
        if (required) spec_error(where(key) + "required, range [" + detail::fmt(lo) + ", " + detail::fmt(hi) + "]");
        return def;
    }
    double x = parse_number(key, *v);
    check_range(key, x, lo, hi);
    return x;
}

Rgb SpecArgs::rgb(const std::string& key, const Rgb& def, double lo, double hi, bool required) {
    const std::string* v = one(key);
    if (!v) {
        if (required)
            spec_error(where(key) + "required (scalar or r,g,b), range [" + detail::fmt(lo) + ", " + detail::fmt(hi) + "]");
        return def;
    }
    std::vector<double> xs = numbers(key, *v);
    if (xs.size() != 1 && xs.size() != 3)
        spec_error(where(key) + "expected a scalar or r,g,b triple, got " + std::to_string(xs.size()) + " numbers");
    for (double x : xs) check_range(key, x, lo, hi);
    return xs.size() == 1 ? Rgb(xs[0]) : Rgb(xs[0], xs[1], xs[2]);
}

std::string SpecArgs::word(const std::string& key, const std::string& def, const std::vector<std::string>& allowed) {
    const std::string* v = one(key);
    if (!v) return def;
    for (auto& a : allowed)
        if (*v == a) return a;
    std::string list;
    for (auto& a : allowed) list += (list.empty() ? "" : "|") + a;
    spec_error(where(key) + "unknown value '" + *v + "', expected " + list);
}

std::vector<double> SpecArgs::numbers(const std::string& key, const std::string& v) const {
    std::vector<double> out;
    std::string item;
    std::istringstream s(v);
    while (std::getline(s, item, ',')) out.push_back(parse_number(key, item));
    if (v.empty() || v.back() == ',') spec_error(where(key) + "empty number in '" + v + "'");
    return out;
}

void SpecArgs::check_sum(const char* ka, const Rgb& a, const char* kb, const Rgb& b) const {
    for (int c = 0; c < 3; ++c)
        if (a[c] + b[c] > 1.0 + 1e-12)
            spec_error(where(std::string(ka) + "+" + kb) + "sum " + detail::fmt(a[c] + b[c]) +
                       " exceeds 1 (energy conservation)");
}

void SpecArgs::forbid(const std::vector<std::string>& keys, const std::string& why) const {
    for (auto& k : keys)
        if (has(k)) spec_error(where(k) + why);
}

void SpecArgs::finish() const {
    for (auto& p : kv_)
        if (!used_.count(p.first)) spec_error(model_ + ": unknown key '" + p.first + "' (see model_help())");
}

double SpecArgs::parse_number(const std::string& key, const std::string& text) const {
    const char* b = text.c_str();
    char* e = nullptr;
    double x = std::strtod(b, &e);
    if (text.empty() || e == b || *e != '\0') spec_error(where(key) + "not a number: '" + text + "'");
    if (!std::isfinite(x)) spec_error(where(key) + "not finite: '" + text + "'");
    return x;
}

void SpecArgs::check_range(const std::string& key, double x, double lo, double hi) const {
    if (!(x >= lo && x <= hi))
        spec_error(where(key) + "value " + detail::fmt(x) + " out of range [" + detail::fmt(lo) + ", " + detail::fmt(hi) + "]");
}

// ---------------------------------------------------------------- SpecWriter

std::string SpecWriter::text(double v) const {
    if (digits_ > 0) return detail::fmt(v, digits_);
    // From 6 digits up, so a number that has at most 6 reads as detail::fmt writes it.
    for (int d = 6; d < 17; ++d) {
        std::string s = detail::fmt(v, d);
        if (std::strtod(s.c_str(), nullptr) == v) return s;
    }
    return detail::fmt(v, 17);  // 17 significant digits round-trip every double
}

SpecWriter& SpecWriter::put(const char* key, const std::string& value) {
    s_ += (s_.empty() ? "" : " ") + std::string(key) + "=" + value;
    return *this;
}

SpecWriter& SpecWriter::model(const char* name) {
    s_ += (s_.empty() ? "" : " ") + std::string(name);
    return *this;
}
SpecWriter& SpecWriter::word(const char* key, const char* value) { return put(key, value); }
SpecWriter& SpecWriter::number(const char* key, double v) { return put(key, text(v)); }
SpecWriter& SpecWriter::rgb(const char* key, const Rgb& v) {
    if (v.r == v.g && v.g == v.b) return put(key, text(v.r));
    return put(key, text(v.r) + "," + text(v.g) + "," + text(v.b));
}
SpecWriter& SpecWriter::list(const char* key, std::initializer_list<double> values) {
    std::string s;
    for (double v : values) s += (s.empty() ? "" : ",") + text(v);
    return put(key, s);
}

}  // namespace shading
