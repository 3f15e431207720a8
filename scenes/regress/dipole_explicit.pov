// regress: dipole subsurface with explicit coefficients (1/mm), all with `profile dipole`
// (Jensen 2001; the exact profile is dipole_preset's). Left: sigma_s_prime, sigma_a, ior 1.4,
// mm_per_unit 2, sample_spacing 0.05, error_bound 0.5, single_scatter off. Middle: sigma_s with
// anisotropy 0.8 (reduced to sigma_s (1 - g)), single_scatter on. Right: the left medium under
// a brdf_model coat (dielectric microfacet, m 0.1) in the same finish.
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 1.2, -6> look_at <0, 0.8, 0> angle 45 right x * image_width / image_height }
light_source { <-3, 5, -4> rgb 0.8 }
light_source { <1, 3, 5> rgb 0.8 }
plane { y, 0 pigment { rgb 0.3 } finish { diffuse 0.8 } }
sphere { <-1.8, 0.8, 0>, 0.8 finish { dipole { sigma_s_prime <1.2, 1.0, 0.7> sigma_a <0.002, 0.01, 0.05> ior 1.4 mm_per_unit 2
                                               sample_spacing 0.05 error_bound 0.5 single_scatter off profile dipole } } }
sphere { < 0.0, 0.8, 0>, 0.8 finish { dipole { sigma_s <2.0, 1.5, 1.0> anisotropy 0.8 sigma_a <0.01, 0.03, 0.1> mm_per_unit 3
                                               profile dipole single_scatter on } } }
sphere { < 1.8, 0.8, 0>, 0.8 finish { dipole { sigma_s_prime <1.2, 1.0, 0.7> sigma_a <0.002, 0.01, 0.05> ior 1.4 mm_per_unit 2
                                               sample_spacing 0.05 error_bound 0.5 single_scatter off profile dipole }
                                      brdf_model { "microfacet d=tr m=0.1 f=dielectric eta=1.5 rho_s=1" } } }
