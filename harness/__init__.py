"""povray-brdf harness: render reference scenes, compare them with closed forms, and the
user tools that turn measurements into materials.

Four packages, each importing only the ones below it (``tests/test_harness_layers.py``
checks the contract with import-linter; ``.importlinter`` states it):

* :mod:`harness.reports`    benchmarks, reports and pages: ``make bench/report/regress/study``;
* :mod:`harness.tools`      what a user runs on their own data: sphere sampling, scattering
                            fit, render cost, model recommendation, MERL synthesis, BRDF plots;
* :mod:`harness.reference`  independent mathematics: closed-form pixels, the models in numpy,
                            the dipole in numpy, Monte Carlo transport;
* :mod:`harness.core`       infrastructure: paths, scenes, the ``.pov`` writer, the renderer
                            runner, EXR, image comparison, ``.brdf`` I/O, ``brdftool``, plots,
                            the page writer.

Submodules are imported on use (``from harness.core import runner``) so that importing a
package stays cheap.
"""

__all__ = ["core", "reference", "tools", "reports"]
