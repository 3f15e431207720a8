// povray-brdf demo: a row of spheres, one material each, on a grey floor.
// `make demo` renders it to out/demo.png. Plain POV-Ray 3.7 keywords only until the
// BRDF finishes land; then the middle spheres switch to tabulated and analytic finishes.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 }

camera { location <0, 2.6, -9> look_at <0, 0.7, 0> angle 50 right x * image_width / image_height }
light_source { <-5, 8, -6> rgb 1.0 area_light x * 1.5, z * 1.5, 4, 4 adaptive 1 circular orient }
light_source { <6, 4, -3> rgb <0.25, 0.28, 0.32> shadowless }
sky_sphere { pigment { gradient y color_map { [0 rgb <0.55, 0.6, 0.7>] [1 rgb <0.15, 0.2, 0.35>] } } }

plane { y, 0 pigment { checker rgb 0.6 rgb 0.45 scale 0.8 } finish { diffuse 0.8 } }

#declare R = 0.75;
sphere { <-3.3, R, 0> R pigment { rgb <0.7, 0.15, 0.1> } finish { diffuse 0.7 } }
sphere { <-1.1, R, 0> R pigment { rgb <0.1, 0.3, 0.7> } finish { diffuse 0.6 phong 0.7 phong_size 60 } }
sphere { < 1.1, R, 0> R pigment { rgb <1.0, 0.78, 0.34> }
         finish { ambient 0 diffuse 0.1 specular 0.8 roughness 0.01 metallic reflection { 0.6 metallic } } }
sphere { < 3.3, R, 0> R pigment { rgb <0.95, 0.9, 0.8> } finish { diffuse 0.8 specular 0.2 roughness 0.05 } }
