// povray-brdf demo: a still life of the fork's materials under one area light.
//   back row, left to right: POV's own phong | red plastic, measured-like 1 deg table |
//     gold, Cook-Torrance with measured n + ik, reflecting the scene through its lobe |
//     brushed aluminium, anisotropic Ward (Ward 1992's fit) | an egg of rough copper (table)
//   front: a marble egg and a glass of whole milk (dipole subsurface, Jensen 2001 media)
// `make demo` generates the tables (make brdf-data) and renders this to out/demo.png.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 mm_per_unit 12 }  // one unit is 12 mm: the spheres are ~17 mm across
#include "brdf_metals.inc"
#include "brdf_fits.inc"
#include "dipole_media.inc"

camera { location <0, 4.6, -10.5> look_at <0, 0.35, 0> angle 50 right x * image_width / image_height }
light_source { <-5, 8, -6> rgb 1.0 area_light x * 1.5, z * 1.5, 4, 4 adaptive 1 circular orient area_illumination on }
light_source { <6, 4, -3> rgb <0.25, 0.28, 0.32> }
sky_sphere { pigment { gradient y color_map { [0 rgb <0.55, 0.6, 0.7>] [1 rgb <0.15, 0.2, 0.35>] } } }

plane { y, 0 pigment { checker rgb 0.6 rgb 0.45 scale 0.8 } finish { diffuse 0.8 } }

#declare R = 0.7;
#declare S = 1.75;
sphere { <-2.0 * S, R, 1> R pigment { rgb <0.5, 0.06, 0.04> } finish { diffuse 1 phong 0.5 phong_size 40 } }
sphere { <-1.0 * S, R, 1> R finish { brdf_table { "red-plastic-measured.brdf" } } }
sphere { < 0.0 * S, R, 1> R BRDF_Conductor_Glossy(BRDF_Gold_N, BRDF_Gold_K, 0.08, 16) }
sphere { < 1.0 * S, R, 1> R finish { F_BRDF_Ward_Brushed_Aluminium } }
sphere { 0, 1 scale <0.55, 0.75, 0.55> translate <2.0 * S, 0.75, 1> finish { brdf_table { "copper-rough.brdf" } } }

// front row: translucent media
sphere { 0, 0.55 scale <1, 1.3, 1> translate <-0.9, 0.55 * 1.3, -1.7> finish { F_Dipole_Marble specular 0.4 roughness 0.01 } }
cylinder { <0.9, 0, -1.7>, <0.9, 1.1, -1.7>, 0.45 finish { F_Dipole_Wholemilk specular 0.3 roughness 0.02 } }
