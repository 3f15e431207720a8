"""Infrastructure every other package builds on; imports nothing above it.

* :mod:`~harness.core.paths`     repository root, fork/stock binary discovery, include path;
* :mod:`~harness.core.scenes`    scene dataclasses, the single source of a scene's numbers;
* :mod:`~harness.core.povwriter` scene → ``.pov`` text (finishes from dicts);
* :mod:`~harness.core.runner`    run POV-Ray, read the EXR and POV's statistics;
* :mod:`~harness.core.exr`       EXR read/write, PNG previews;
* :mod:`~harness.core.compare`   error statistics and error-map PNGs;
* :mod:`~harness.core.brdf_io`   ``.brdf`` tables in numpy;
* :mod:`~harness.core.tables`    ``brdftool`` runs and the tables they make, cached;
* :mod:`~harness.core.sstool`    ``sstool`` runs: exact subsurface profile tables and the library's Monte Carlo.
"""
