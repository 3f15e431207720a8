"""What a user runs on their own data (each module has a ``python -m`` command line and a
console script of the installed package, see ``pyproject.toml``).

* :mod:`~harness.tools.sphere_sampling` BRDF tables from float images of a sphere;
* :mod:`~harness.tools.scatter_fit`     sigma_a and sigma_s' from a radial glow profile;
* :mod:`~harness.tools.cost`            render cost of each model family vs stock phong;
* :mod:`~harness.tools.recommend`       the cheapest model within tolerance, checked in a render;
* :mod:`~harness.tools.merl_synth`      a synthetic MERL ``.binary`` file.
"""
