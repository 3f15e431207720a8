// povray-brdf demo: one sphere per material on a grey floor, left to right:
//   POV's own phong | red plastic table (1 deg) | the same plastic "measured" (noise,
//   missing cells filled) | gold table | rough copper table | Ward anisotropic model.
// `make demo` generates the tables (make brdf-data) and renders this to out/demo.png.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 }

camera { location <0, 2.6, -10.5> look_at <0, 0.6, 0> angle 56 right x * image_width / image_height }
light_source { <-5, 8, -6> rgb 1.0 area_light x * 1.5, z * 1.5, 4, 4 adaptive 1 circular orient }
light_source { <6, 4, -3> rgb <0.25, 0.28, 0.32> }
sky_sphere { pigment { gradient y color_map { [0 rgb <0.55, 0.6, 0.7>] [1 rgb <0.15, 0.2, 0.35>] } } }

plane { y, 0 pigment { checker rgb 0.6 rgb 0.45 scale 0.8 } finish { diffuse 0.8 } }

#declare R = 0.7;
#declare S = 1.75;
sphere { <-2.5 * S, R, 0> R pigment { rgb <0.5, 0.06, 0.04> } finish { diffuse 1 phong 0.5 phong_size 40 } }
sphere { <-1.5 * S, R, 0> R finish { brdf_table { "red-plastic.brdf" } } }
sphere { <-0.5 * S, R, 0> R finish { brdf_table { "red-plastic-measured.brdf" } } }
sphere { < 0.5 * S, R, 0> R finish { brdf_table { "gold.brdf" } reflection { 0.3 metallic } } pigment { rgb <1, 0.8, 0.4> } }
sphere { < 1.5 * S, R, 0> R finish { brdf_table { "copper-rough.brdf" } } }
sphere { < 2.5 * S, R, 0> R
  finish { brdf_model { "ward ax=0.05 ay=0.3 rho_d=0.1,0.1,0.12 rho_s=0.25" direction y } } }
