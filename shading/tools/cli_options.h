// Command-line options shared by the tools (brdftool, sstool): positional arguments, option
// values, numbers and comma-separated lists, with one wording for what is wrong in them.
#pragma once

#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace shading_tools {

// A mistake on the command line: the tool prints it with its usage and exits with status 2.
struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// `text` as a number; infinity ("inf") only where `allow_inf`, never NaN.
inline bool parse_number(const std::string& text, bool allow_inf, double* v) {
    char* end = nullptr;
    *v = std::strtod(text.c_str(), &end);
    return !text.empty() && *end == '\0' && (allow_inf ? !std::isnan(*v) : std::isfinite(*v));
}

struct Options {
    std::vector<std::string> pos;
    std::map<std::string, std::string> opt;
    bool allow_inf = false;  // sstool: a thickness of inf is the half-space

    std::string str(const std::string& k, const std::string& def = "") const {
        auto it = opt.find(k);
        return it == opt.end() ? def : it->second;
    }
    double number(const std::string& k, double def) const {
        auto it = opt.find(k);
        if (it == opt.end()) return def;
        double v;
        if (!parse_number(it->second, allow_inf, &v)) throw UsageError(k + ": not a number: '" + it->second + "'");
        return v;
    }
    std::vector<double> list(const std::string& k, const std::vector<double>& def) const {
        auto it = opt.find(k);
        if (it == opt.end()) return def;
        std::vector<double> out;
        std::stringstream ss(it->second);
        std::string item;
        while (std::getline(ss, item, ',')) {
            double v;
            if (!parse_number(item, allow_inf, &v))
                throw UsageError(k + ": not a comma-separated list of numbers: '" + it->second + "'");
            out.push_back(v);
        }
        if (out.empty()) throw UsageError(k + ": empty list");
        return out;
    }
};

}  // namespace shading_tools
