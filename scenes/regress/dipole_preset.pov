// regress: dipole subsurface, presets. Left: F_Dipole_Marble from dipole_media.inc
// (Dipole_MM_Per_Unit 10: the balls are 2 cm across). Middle: `dipole { "Skimmilk" }`
// written directly, with mm_per_unit 5. Right: the Dipole_Finish("Ketchup") macro. Back
// light from behind the balls, so the light through the edges shows.
#version 3.7;
global_settings { assumed_gamma 1.0 }
#declare Dipole_MM_Per_Unit = 10;
#include "dipole_media.inc"
camera { location <0, 1.2, -6> look_at <0, 0.8, 0> angle 45 right x * image_width / image_height }
light_source { <-3, 5, -4> rgb 0.8 }
light_source { <1, 3, 5> rgb 0.8 }
plane { y, 0 pigment { rgb 0.3 } finish { diffuse 0.8 } }
sphere { <-1.8, 0.8, 0>, 0.8 finish { F_Dipole_Marble } }
sphere { < 0.0, 0.8, 0>, 0.8 finish { dipole { "Skimmilk" mm_per_unit 5 } } }
sphere { < 1.8, 0.8, 0>, 0.8 Dipole_Finish("Ketchup") }
