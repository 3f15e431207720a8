// regress: stock guard -- no keyword of the fork. phong, specular/roughness, metallic
// reflection, refraction with ior, a bump normal, an area light (no jitter), checker floor.
// The fork must render stock scenes exactly as before; `make regress` also renders this one
// with Debian's stock POV-Ray and compares the two.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 5 }
camera { location <0, 2.2, -6> look_at <0, 0.6, 0> angle 50 right x * image_width / image_height }
light_source { <-4, 6, -5> rgb 1 area_light x * 1, z * 1, 3, 3 orient circular }
light_source { <5, 3, -4> rgb <0.25, 0.27, 0.3> }
sky_sphere { pigment { gradient y color_map { [0 rgb <0.6, 0.65, 0.75>] [1 rgb <0.15, 0.2, 0.35>] } } }
plane { y, 0 pigment { checker rgb 0.7 rgb 0.3 } finish { diffuse 0.8 reflection 0.15 } }
sphere { <-1.9, 0.7, 0.5>, 0.7 pigment { rgb <0.7, 0.1, 0.05> } finish { diffuse 0.9 phong 0.6 phong_size 60 } }
sphere { <0, 0.7, 0.8>, 0.7 pigment { rgb <0.9, 0.75, 0.3> } finish { ambient 0 diffuse 0.2 specular 0.8 roughness 0.02 metallic reflection { 0.6 metallic } } }
sphere { <1.9, 0.7, 0.5>, 0.7 pigment { rgbf <0.95, 1, 0.95, 0.9> } finish { ambient 0 diffuse 0.05 phong 0.8 phong_size 200 reflection 0.05 } interior { ior 1.5 } }
box { <-0.5, 0, -1.5>, <0.5, 0.5, -0.9> rotate y * 25 pigment { rgb <0.2, 0.4, 0.8> } normal { bumps 0.4 scale 0.1 } finish { diffuse 0.8 specular 0.3 } }
