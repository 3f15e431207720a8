// A "photograph" of a sphere for docs/fitting.md (photographs of a sphere): the sphere of
// radius 1 at the origin, finished with the table "known.brdf", seen by an orthographic
// camera from -z (2.2 units across), lit by one distant light of colour (irradiance) 1.
// Rendered as an animation, frame K has the light at GAMMA = 5 K degrees from the view
// axis, turned about it by 20 + 37 K degrees, so 35 frames (0 to 170 degrees) fill the
// (theta_i, theta_r, phi)
// domain; photos.py lists the same directions in photos.toml.
//   povray-brdf +Iball.pov +Oball.exr +FE32 +W200 +H200 -A -D +KFI0 +KFF34
#version 3.7;
global_settings { assumed_gamma 1.0 }
#declare K = frame_number;
#declare GAMMA = radians(5 * K);
#declare TURN = radians(20 + 37 * K);
#declare TOWARDS_LIGHT = <sin(GAMMA) * cos(TURN), sin(GAMMA) * sin(TURN), -cos(GAMMA)>;
camera { orthographic location <0, 0, -10> direction <0, 0, 1> right <2.2, 0, 0> up <0, 2.2, 0> }
light_source { 1000 * TOWARDS_LIGHT rgb 1 parallel point_at <0, 0, 0> }
sphere { 0, 1 pigment { rgb 1 } finish { brdf_table { "known.brdf" } ambient 0 } }  // light of the one lamp only
