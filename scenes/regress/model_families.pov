// regress: brdf_model, one sphere per model family. Top: lambert, phong_pov, blinn_pov,
// phong_normalized. Bottom: microfacet (normalised Cook-Torrance, Beckmann, dielectric, with
// a Lambertian base), ward (GMD, isotropic), oren_nayar, lafortune (one lobe).
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -10> direction z right x * 9.6 up y * 4.8 }
light_source { <-6, 7, -10> rgb 1 }
light_source { <7, -2, -6> rgb 0.3 }
plane { -z, -1.2 pigment { rgb 0.04 } finish { ambient 0 diffuse 1 } }
#declare Spec = array[8] {
  "lambert rho=0.7,0.5,0.3",
  "phong_pov phong=0.6 phong_size=40 diffuse=0.5,0.3,0.2",
  "blinn_pov specular=0.6 roughness=0.03 diffuse=0.2,0.4,0.5",
  "phong_normalized kd=0.3,0.3,0.5 ks=0.4 n=60",
  "microfacet d=beckmann m=0.2 f=dielectric eta=1.5 kd=0.4,0.1,0.1 rho_s=0.5",
  "ward rho_d=0.3,0.35,0.2 rho_s=0.3 alpha=0.12",
  "oren_nayar rho=0.8,0.6,0.4 sigma=0.5",
  "lafortune kd=0.2,0.3,0.5 lobe=-1,-1,1,30,0.6" }
#for (I, 0, 7)
  sphere { <-3.6 + 2.4 * mod(I, 4), 1.2 - 2.4 * floor(I / 4), 0>, 1.05 finish { brdf_model { Spec[I] } } }
#end
