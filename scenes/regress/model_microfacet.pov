// regress: microfacet variants at one roughness (m 0.25). Top: d = blinn, gaussian, tr,
// beckmann (dielectric Fresnel, Smith G). Bottom: conductor (gold n, k), schlick f0 0.9,
// survey form, V-cavity G.
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -10> direction z right x * 9.6 up y * 4.8 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { rgb 0.04 } finish { ambient 0 diffuse 1 } }
#declare Spec = array[8] {
  "microfacet d=blinn m=0.25 f=dielectric eta=1.5 kd=0.3,0.3,0.4 rho_s=0.6",
  "microfacet d=gaussian m=0.25 f=dielectric eta=1.5 kd=0.3,0.3,0.4 rho_s=0.6",
  "microfacet d=tr m=0.25 f=dielectric eta=1.5 kd=0.3,0.3,0.4 rho_s=0.6",
  "microfacet d=beckmann m=0.25 f=dielectric eta=1.5 kd=0.3,0.3,0.4 rho_s=0.6",
  "microfacet d=beckmann m=0.25 f=conductor n=0.156,0.424,1.383 k=3.602,2.472,1.915",
  "microfacet d=tr m=0.25 f=schlick f0=0.9,0.6,0.5",
  "microfacet form=survey d=beckmann m=0.25 f=dielectric eta=1.5 rho_s=0.7 kd=0.3",
  "microfacet d=beckmann m=0.25 g=vcavity f=dielectric eta=1.5 kd=0.3,0.3,0.4 rho_s=0.6" }
#for (I, 0, 7)
  sphere { <-3.6 + 2.4 * mod(I, 4), 1.2 - 2.4 * floor(I / 4), 0>, 1.05 finish { brdf_model { Spec[I] } } }
#end
