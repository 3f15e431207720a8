// regress: brdf_table `scale` and `use_color`. Left: the white Lambert table with
// `use_color on` under a red pigment (renders like `diffuse 0.8` in red). Middle: the red
// plastic with `scale <0.5, 1, 2>`. Right: the measured-like red plastic with `use_color off`
// (default: the green pigment is ignored) and `scale 1.5`, plus a written `diffuse 0.1`
// (added to the table) and `ambient 0.05`.
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -10> direction z right x * 7.2 up y * 2.4 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { rgb 0.04 } finish { ambient 0 diffuse 1 } }
sphere { <-2.4, 0, 0>, 1.05 pigment { rgb <0.9, 0.2, 0.1> } finish { brdf_table { "lambert-white.brdf" use_color on } } }
sphere { < 0.0, 0, 0>, 1.05 finish { brdf_table { "red-plastic.brdf" scale <0.5, 1, 2> } } }
sphere { < 2.4, 0, 0>, 1.05 pigment { rgb <0.1, 0.9, 0.1> } finish { brdf_table { "red-plastic-measured.brdf" use_color off scale 1.5 } diffuse 0.1 ambient 0.05 } }
