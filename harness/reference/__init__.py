"""Independent mathematics: what the fork's images and the shading library should give.

Nothing here shares code with the C++ library; each module re-derives its results from the
published formulas or from another method (Monte Carlo).

* :mod:`~harness.reference.terms`         shading inputs, local frames, POV's ``pi f cos``;
* :mod:`~harness.reference.models`        every analytic model of the library in numpy;
* :mod:`~harness.reference.expect`        closed-form expected pixels per scene;
* :mod:`~harness.reference.dipole_ref`    the dipole's formulas and exact transport results;
* :mod:`~harness.reference.mc_subsurface` Monte Carlo photon migration;
* :mod:`~harness.reference.volume_ref`    exact volumetric Monte Carlo in scene geometries (shadow
  edge, lit sheet, sphere), the reference of the random-walk and profile modes;
* :mod:`~harness.reference.table_albedo`  directional albedo of a tabulated BRDF from its nodes.
"""
