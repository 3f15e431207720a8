// regress: an anisotropic (4-D) table and `direction`. An anisotropic Ward lobe
// (ax 0.05, ay 0.3) tabulated with `brdftool tabulate --layout aniso` at 5 deg (theta) x
// 10 deg (phi); the tangent (`direction`) is x, y and <1, 1, 0> from left to right: the
// highlight stretches across the grain.
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -10> direction z right x * 7.2 up y * 2.4 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { rgb 0.04 } finish { ambient 0 diffuse 1 } }
sphere { <-2.4, 0, 0>, 1.05 finish { brdf_table { "ward-aniso.brdf" direction x } } }
sphere { < 0.0, 0, 0>, 1.05 finish { brdf_table { "ward-aniso.brdf" direction y } } }
sphere { < 2.4, 0, 0>, 1.05 finish { brdf_table { "ward-aniso.brdf" direction <1, 1, 0> } } }
