// povray-brdf: the named materials of scenes/include/brdf_metals.inc and brdf_fits.inc.
//   Rows 1-3: gold, silver, copper, aluminium, chromium, iron, nickel, titanium
//             (measured n + ik, Cook-Torrance), polished / satin / rough.
//   Row 4:    Ward 1992 Table 1 fits (six anisotropic, grain along world x, then four
//             isotropic) and the Lafortune 1997 blue paint.
// The finishes shape the reflection of the light sources only (no mirror images of the
// scene), so the key light is large: its reflection shows each lobe's size and colour.
// Render (about 10 s on 2 cores: ~3.5 s parsing the include files, ~5.5 s tracing):
//   build/bin/povray-brdf +Iscenes/materials.pov +Oout/materials.png +W640 +H360 +A0.1 +WT2
#version 3.7;
#include "brdf_metals.inc"
#include "brdf_fits.inc"

global_settings { assumed_gamma 1.0 max_trace_level 5 }

#declare W = 11.6;  // view width (scene units); 11 columns of 1 unit
camera {
  orthographic
  location <0, 0, -20>
  direction z
  right x * W
  up y * W * image_height / image_width
}

// Key: a large soft box up-left-front, lit from each of its samples (area_illumination),
// so its reflection is the patch on the polished metals; fill: a small dim light low right
// (the second, sharp highlight).
light_source {
  <-16, 18, -24> rgb 1.0
  area_light x * 28, y * 28, 11, 11 adaptive 1 circular orient area_illumination on
}
light_source { <14, -6, -16> rgb <0.30, 0.32, 0.36> }

// Dark neutral backdrop so highlights read against it.
plane { -z, -0.6 pigment { rgb 0.012 } finish { ambient 0 diffuse 1 } }

#declare R = 0.40;
#declare Row_Y = array[4] { 2.20, 0.80, -0.60, -2.05 };
#declare Lab_Font = "cyrvetic.ttf";

#macro Label(S, P)
  text { ttf Lab_Font S 0.01, 0 scale 0.14 translate P - x * 0.039 * strlen(S)
         pigment { rgb 0.75 } finish { ambient 1 diffuse 0 } no_shadow }
#end
#macro Ball(Fin, Col, RowI, Name)
  #local P = <-5 + Col, Row_Y[RowI], 0>;
  sphere { P, R finish { Fin } }
  Label(Name, P - y * (R + 0.2) - z * 0.5)
#end

// metals: columns 3..10 (0-based), row label in columns 0-2
#declare Metal_Names = array[8] { "gold", "silver", "copper", "aluminium", "chromium", "iron", "nickel", "titanium" }
#declare Metal_F = array[3][8] {
  { F_BRDF_Gold_Polished, F_BRDF_Silver_Polished, F_BRDF_Copper_Polished, F_BRDF_Aluminium_Polished,
    F_BRDF_Chromium_Polished, F_BRDF_Iron_Polished, F_BRDF_Nickel_Polished, F_BRDF_Titanium_Polished },
  { F_BRDF_Gold_Satin, F_BRDF_Silver_Satin, F_BRDF_Copper_Satin, F_BRDF_Aluminium_Satin,
    F_BRDF_Chromium_Satin, F_BRDF_Iron_Satin, F_BRDF_Nickel_Satin, F_BRDF_Titanium_Satin },
  { F_BRDF_Gold_Rough, F_BRDF_Silver_Rough, F_BRDF_Copper_Rough, F_BRDF_Aluminium_Rough,
    F_BRDF_Chromium_Rough, F_BRDF_Iron_Rough, F_BRDF_Nickel_Rough, F_BRDF_Titanium_Rough }
}
#declare Grade = array[3] { "polished m=0.05", "satin m=0.15", "rough m=0.35" }
#for (I, 0, 2)
  text { ttf Lab_Font Grade[I] 0.01, 0 scale 0.22 translate <-5.45, Row_Y[I] - 0.07, -0.5>
         pigment { rgb 0.9 } finish { ambient 1 diffuse 0 } no_shadow }
  #for (J, 0, 7)
    Ball(Metal_F[I][J], J + 3, I, Metal_Names[J])
  #end
#end

// fits: all 11 columns
#declare Fit_F = array[11] {
  F_BRDF_Ward_Rolled_Brass, F_BRDF_Ward_Rolled_Aluminium, F_BRDF_Ward_Brushed_Aluminium,
  F_BRDF_Ward_Varnished_Plywood, F_BRDF_Ward_Enamel_Metal, F_BRDF_Ward_Painted_Cardboard,
  F_BRDF_Ward_White_Ceramic_Tile, F_BRDF_Ward_Glossy_Grey_Paper, F_BRDF_Ward_Ivory_Plastic,
  F_BRDF_Ward_Plastic_Laminate, F_BRDF_Lafortune_Blue_Paint }
#declare Fit_Names = array[11] { "rolled brass", "rolled Al", "brushed Al", "plywood", "enamel",
  "cardboard", "ceramic tile", "grey paper", "ivory plastic", "laminate", "blue paint" }
#for (J, 0, 10)
  Ball(Fit_F[J], J, 3, Fit_Names[J])
#end
