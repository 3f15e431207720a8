// The cost table of `brdftool recommend` (fit.h): the built-in rough order and the cost file
// grammar (harness/tools/cost.py reads the same).
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "shading/brdf/model_spec.h"
#include "shading/fit/fit.h"

namespace shading {

double CostTable::cost_of(const std::string& family) const {
    size_t best_len = 0;
    double cost = 1.0;
    for (const auto& e : entries)
        if (family.rfind(e.first, 0) == 0 && e.first.size() >= best_len) {
            best_len = e.first.size();
            cost = e.second;
        }
    return cost;
}

CostTable builtin_costs() {
    CostTable t;
    // Rough trace-time ratios vs stock phong on a shading-bound sphere, each model's own
    // (ModelEntry::costs); harness/tools/cost.py measures the real ones. Closed forms are
    // cheap; a table lookup costs about a Beckmann microfacet.
    for (const ModelEntry& m : registered_models())
        for (const auto& c : m.costs) t.entries.push_back(c);
    t.entries.push_back({"table", 1.25});
    return t;
}

namespace {

bool cost_space(unsigned char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// RATIO: [+] digits [. digits] [(e|E) [+|-] digits], at least one digit before the exponent.
bool decimal_word(const std::string& w) {
    size_t k = 0, digits = 0;
    if (k < w.size() && w[k] == '+') ++k;
    for (; k < w.size() && w[k] >= '0' && w[k] <= '9'; ++k) ++digits;
    if (k < w.size() && w[k] == '.')
        for (++k; k < w.size() && w[k] >= '0' && w[k] <= '9'; ++k) ++digits;
    if (digits == 0) return false;
    if (k < w.size() && (w[k] == 'e' || w[k] == 'E')) {
        ++k;
        if (k < w.size() && (w[k] == '+' || w[k] == '-')) ++k;
        size_t e = 0;
        for (; k < w.size() && w[k] >= '0' && w[k] <= '9'; ++k) ++e;
        if (e == 0) return false;
    }
    return k == w.size();
}

std::string shown(const std::string& w) {
    std::string s = "'";
    for (unsigned char c : w.substr(0, 40)) {
        if (c >= 0x20 && c < 0x7f && c != '\'' && c != '\\') {
            s += char(c);
        } else {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", c);
            s += buf;
        }
    }
    return s + (w.size() > 40 ? "...'" : "'");
}

}  // namespace

CostTable parse_costs(const std::string& text, const std::string& name) {
    CostTable t;
    t.source = name;
    auto fail = [&](size_t lineno, size_t offset, const std::string& expected, const std::string& found) {
        throw TableError(name + ": line " + std::to_string(lineno) + ", offset " + std::to_string(offset) +
                         ": expected " + expected + ", found " + found +
                         ". Each line is 'FAMILY RATIO' (e.g. 'microfacet d=tr 1.15'), '#' starts a comment; "
                         "`brdf-cost --force` writes the file again");
    };
    size_t lineno = 0;
    for (size_t start = 0; start <= text.size();) {
        size_t eol = text.find('\n', start);
        if (eol == std::string::npos) eol = text.size();
        ++lineno;
        const size_t end = size_t(std::find(text.begin() + long(start), text.begin() + long(eol), '#') - text.begin());
        // Words: runs of bytes between ASCII spaces; each remembers its offset.
        std::vector<std::pair<size_t, std::string>> w;
        for (size_t k = start; k < end;) {
            if (cost_space(static_cast<unsigned char>(text[k]))) {
                ++k;
                continue;
            }
            size_t b = k;
            while (k < end && !cost_space(static_cast<unsigned char>(text[k]))) ++k;
            w.push_back({b, text.substr(b, k - b)});
        }
        start = eol + 1;
        if (w.empty()) continue;
        if (w.size() < 2) fail(lineno, w[0].first, "'FAMILY RATIO' (two or more words)", shown(w[0].second) + " alone");
        std::string key;
        for (size_t k = 0; k + 1 < w.size(); ++k) {
            for (size_t c = 0; c < w[k].second.size(); ++c) {
                const unsigned char ch = static_cast<unsigned char>(w[k].second[c]);
                if (ch < 0x21 || ch > 0x7e)
                    fail(lineno, w[k].first + c, "a family name in printable ASCII", shown(std::string(1, char(ch))));
            }
            key += (k ? " " : "") + w[k].second;
        }
        const auto& [at, word] = w.back();
        if (!decimal_word(word)) fail(lineno, at, "RATIO, a decimal number", shown(word));
        const double v = std::strtod(word.c_str(), nullptr);  // the C locale: brdftool never sets another
        if (!(v >= kMinCostRatio && v <= kMaxCostRatio))
            fail(lineno, at, "RATIO in [1e-06, 1e+06]", shown(word));
        t.entries.push_back({key, v});
    }
    return t;
}

CostTable load_costs(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw TableError(path + ": cannot read the cost table: " + std::strerror(errno));
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw TableError(path + ": cannot read the cost table: a read error");
    return parse_costs(s.str(), path);
}

}  // namespace shading
