// Named scattering media from the literature, compiled in:
//  * the 12 materials of Jensen, Marschner, Levoy, Hanrahan 2001, Table 2 (sigma_s', sigma_a, eta);
//  * the 35 media of Narasimhan, Gupta, Donner, Ramamoorthi, Nayar, Jensen 2006, Table 1
//    (sigma_s, sigma_a, Henyey-Greenstein g; eta = 1.33).
// The table is generated from data/media_presets.csv by shading/tools/gen_presets.py; how the
// transcription conflicts listed in that CSV are resolved is in shading/DIPOLE.md ("Presets")
// and in each preset's `note`.
#pragma once

#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "shading/subsurface/dipole.h"

namespace shading {

struct MediumPreset {
    const char* name;    // as printed in the source, e.g. "Wholemilk", "Regular Milk"
    const char* paper;   // "Jensen2001" or "Narasimhan2006"
    Rgb sigma_s_prime;   // reduced scattering, 1/mm (the dipole's input, pbrt-v4 transcription)
    Rgb sigma_a;         // absorption, 1/mm
    Rgb g;               // HG asymmetry; 0 for Jensen rows (that table gives sigma_s' only)
    Rgb sigma_s;         // scattering, 1/mm, = sigma_s' / (1 - g) (= sigma_s' where g = 0)
    double eta;          // relative index of refraction
    // Jensen 2001 Table 2 total Rd; NaN for Narasimhan rows.
    Rgb rd_paper = Rgb(std::numeric_limits<double>::quiet_NaN());
    // The CSV's recomputed closed-form Rd; NaN where the CSV has none.
    Rgb rd_dipole_check = Rgb(std::numeric_limits<double>::quiet_NaN());
    const char* note = "";  // transcription conflict and how it was resolved ("" if none)

    // The preset as a Medium (sigma_s, sigma_a, g, eta) with the given scene unit.
    Medium medium(double mm_per_unit = 1.0) const;
};

// All presets, Jensen rows first, in the CSV's order.
const std::vector<MediumPreset>& media_presets();
// Lookup key: lower case, runs of spaces, underscores and hyphens folded to one '_', trimmed.
// "Regular Milk", "regular_milk" and "REGULAR-milk" are the same preset.
std::string media_preset_key(std::string_view name);
// nullptr when no preset has that key.
const MediumPreset* find_media_preset(std::string_view name);
// Throws std::invalid_argument naming the unknown medium and listing the known names.
Medium media_preset(std::string_view name, double mm_per_unit = 1.0);
// Names as printed in the sources, in table order.
std::vector<std::string> media_preset_names();

}  // namespace shading
