// Thin geometry of the dipole finish (shading/DIPOLE.md section 6a): three sheets of the same
// medium, 0.5, 2 and 8 mm thick, and a 40 mm block, lit from behind by a warm parallel light and
// from the front by a dim blue fill. Light diffusing through the thin sheets glows on their
// front faces (the transmission profile T of a slab of each one's thickness); through the block
// little comes (T under 0.5 % of its reflectance in red, far less in blue). `thin_geometry off` in Wax shows the half-space dipole.
//   build/bin/povray-brdf +Iscenes/thin_sheets.pov +W480 +H240 +Oout/thin_sheets.png
#version 3.7;
global_settings { assumed_gamma 1.0 mm_per_unit 1 }

// A pale wax-like medium: reduced scattering 1.2/mm, little absorption, more in blue.
#declare Wax = finish { ambient 0
  dipole { sigma_s_prime <1.2, 1.2, 1.2> sigma_a <0.004, 0.012, 0.05> ior 1.4 } }

camera { orthographic location <0, 0, 100> direction <0, 0, -1> right <140, 0, 0> up <0, 70, 0> }
light_source { <-30, 40, -1000> rgb <1.0, 0.85, 0.6> * 3 parallel point_at <0, 0, 0> }   // behind
light_source { <200, 300, 1000> rgb <0.25, 0.3, 0.4> parallel point_at <0, 0, 0> }        // front fill
background { rgb 0.02 }

box { <-64, -25, -0.5>, <-36, 25, 0> finish { Wax } }
box { <-30, -25, -2>, <-2, 25, 0> finish { Wax } }
box { <4, -25, -8>, <32, 25, 0> finish { Wax } }
box { <38, -25, -40>, <66, 25, 0> finish { Wax } }
