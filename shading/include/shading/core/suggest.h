// "Did you mean ...?" for a misspelt name: the closest of the names a user could have meant.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace shading {

// Edits (insert, delete, replace, swap two neighbours) between a and b, letters compared
// without case (the optimal string alignment distance).
int edit_distance(std::string_view a, std::string_view b);

// The name in `names` closest to `word`, when it is close enough to be what was meant: at most
// one edit for words of up to four letters, two up to eight, three beyond. Empty when none is,
// or when `word` itself is one of the names. Ties go to the name listed first.
std::string closest_name(std::string_view word, const std::vector<std::string>& names);

}  // namespace shading
