#include "shading/core/suggest.h"

#include <algorithm>
#include <cctype>

namespace shading {

int edit_distance(std::string_view a, std::string_view b) {
    const size_t n = a.size(), m = b.size();
    auto same = [&](size_t i, size_t j) {
        return std::tolower(static_cast<unsigned char>(a[i])) == std::tolower(static_cast<unsigned char>(b[j]));
    };
    // Three rows of the dynamic programme: i - 2, i - 1, i.
    std::vector<int> prev2(m + 1), prev(m + 1), cur(m + 1);
    for (size_t j = 0; j <= m; ++j) prev[j] = int(j);
    for (size_t i = 1; i <= n; ++i) {
        cur[0] = int(i);
        for (size_t j = 1; j <= m; ++j) {
            int d = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (same(i - 1, j - 1) ? 0 : 1)});
            if (i > 1 && j > 1 && same(i - 1, j - 2) && same(i - 2, j - 1)) d = std::min(d, prev2[j - 2] + 1);
            cur[j] = d;
        }
        std::swap(prev2, prev);
        std::swap(prev, cur);
    }
    return prev[m];
}

std::string closest_name(std::string_view word, const std::vector<std::string>& names) {
    const int allowed = word.size() <= 4 ? 1 : word.size() <= 8 ? 2 : 3;
    int best = allowed + 1;
    const std::string* found = nullptr;
    for (const std::string& name : names) {
        if (name == word) return std::string();
        // a length difference alone costs that many edits: skip names that cannot be close
        const int gap = int(name.size() > word.size() ? name.size() - word.size() : word.size() - name.size());
        if (gap >= best) continue;
        const int d = edit_distance(word, name);
        if (d < best) {
            best = d;
            found = &name;
        }
    }
    return found ? *found : std::string();
}

}  // namespace shading
