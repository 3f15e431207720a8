// regress: brdf_model options. From the left: anisotropic Ward (ax 0.04, ay 0.25) with
// `direction x`; the same with `direction y`; a Lambert model with `use_color on` under a
// blue pigment and `scale <1, 0.8, 0.6>`; a microfacet lobe with a written `diffuse 0.4`
// (added to the model) and POV's own `reflection 0.2` (kept), `phong 1` (dropped).
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 4 }
camera { orthographic location <0, 0, -10> direction z right x * 9.6 up y * 2.4 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { checker rgb 0.02 rgb 0.25 scale 0.6 } finish { ambient 0 diffuse 1 } }
sphere { <-3.6, 0, 0>, 1.05 finish { brdf_model { "ward rho_d=0.2 rho_s=0.35 ax=0.04 ay=0.25" direction x } } }
sphere { <-1.2, 0, 0>, 1.05 finish { brdf_model { "ward rho_d=0.2 rho_s=0.35 ax=0.04 ay=0.25" direction y } } }
sphere { < 1.2, 0, 0>, 1.05 pigment { rgb <0.2, 0.4, 0.9> } finish { brdf_model { "lambert rho=0.9" use_color on scale <1, 0.8, 0.6> } } }
sphere { < 3.6, 0, 0>, 1.05 pigment { rgb <0.6, 0.5, 0.2> } finish { brdf_model { "microfacet d=tr m=0.15 f=dielectric eta=1.5 rho_s=0.5" } diffuse 0.4 reflection 0.2 phong 1 } }
