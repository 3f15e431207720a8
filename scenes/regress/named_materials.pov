// regress: the named finishes of scenes/include. From the left: F_BRDF_Gold_Polished,
// F_BRDF_Copper_Rough, BRDF_Conductor_Finish with aluminium's n, k at m 0.15,
// F_BRDF_Ward_Brushed_Aluminium (anisotropic, grain along x), F_BRDF_Lafortune_Blue_Paint.
#version 3.7;
global_settings { assumed_gamma 1.0 }
#include "brdf_metals.inc"
#include "brdf_fits.inc"
camera { orthographic location <0, 0, -10> direction z right x * 12 up y * 2.4 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { rgb 0.04 } finish { ambient 0 diffuse 1 } }
sphere { <-4.8, 0, 0>, 1.05 finish { F_BRDF_Gold_Polished } }
sphere { <-2.4, 0, 0>, 1.05 finish { F_BRDF_Copper_Rough } }
sphere { < 0.0, 0, 0>, 1.05 BRDF_Conductor_Finish(BRDF_Aluminium_N, BRDF_Aluminium_K, 0.15) }
sphere { < 2.4, 0, 0>, 1.05 finish { F_BRDF_Ward_Brushed_Aluminium } }
sphere { < 4.8, 0, 0>, 1.05 finish { F_BRDF_Lafortune_Blue_Paint } }
