// regress: glossy reflection (`samples`). The scene (checker floor, gradient sky, a red
// ball) is reflected through each lobe: left, polished gold (microfacet conductor, m 0.08,
// samples 16, via brdf_metals.inc's BRDF_Conductor_Glossy); middle, the ready gold table
// with `samples 8`; right, a rough red plastic (tr m 0.2, kd 0.4) with `samples 4`.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 4 }
#include "brdf_metals.inc"
camera { location <0, 1.6, -6.5> look_at <0, 0.6, 0> angle 50 right x * image_width / image_height }
light_source { <-4, 6, -5> rgb 1 }
sky_sphere { pigment { gradient y color_map { [0 rgb <0.7, 0.7, 0.75>] [1 rgb <0.1, 0.2, 0.5>] } } }
plane { y, 0 pigment { checker rgb 0.8 rgb 0.1 scale 0.5 } finish { diffuse 0.9 } }
sphere { <0, 0.4, 2.5>, 0.4 pigment { rgb <0.8, 0.1, 0.1> } finish { diffuse 0.9 } }
sphere { <-2.1, 0.75, 0>, 0.75 BRDF_Conductor_Glossy(BRDF_Gold_N, BRDF_Gold_K, 0.08, 16) }
sphere { < 0.0, 0.75, 0>, 0.75 finish { brdf_table { "gold.brdf" samples 8 } } }
sphere { < 2.1, 0.75, 0>, 0.75 finish { brdf_model { "microfacet d=tr m=0.2 f=dielectric eta=1.5 kd=0.4,0.05,0.05 rho_s=0.5" samples 4 } } }
