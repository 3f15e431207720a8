// regress: brdf_table interpolation. Left: the ready 1-degree gold table (make brdf-data),
// trilinear by default. Middle: a 10-degree table of the red plastic, `interpolate 0`
// (nearest node: the highlight shows the 10-degree cells). Right: the same table,
// `interpolate 1` (trilinear).
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -10> direction z right x * 7.2 up y * 2.4 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { rgb 0.04 } finish { ambient 0 diffuse 1 } }
sphere { <-2.4, 0, 0>, 1.05 finish { brdf_table { "gold.brdf" } } }
sphere { < 0.0, 0, 0>, 1.05 finish { brdf_table { "plastic-10deg.brdf" interpolate 0 } } }
sphere { < 2.4, 0, 0>, 1.05 finish { brdf_table { "plastic-10deg.brdf" interpolate 1 } } }
