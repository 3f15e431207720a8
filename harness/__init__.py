"""povray-brdf test harness: render reference scenes and compare them with closed forms.

One job per module:

* :mod:`harness.paths`     repository root, fork/stock binary discovery, include path;
* :mod:`harness.scenes`    scene dataclasses, the single source of a scene's numbers;
* :mod:`harness.povwriter` scene → ``.pov`` text (finishes from dicts);
* :mod:`harness.runner`    run POV-Ray, read the EXR and POV's statistics;
* :mod:`harness.exr`       EXR read/write, PNG previews;
* :mod:`harness.expect`    analytic expected pixels (pure numpy);
* :mod:`harness.compare`   error statistics and error-map PNGs;
* :mod:`harness.report`    a single HTML page.

Submodules are imported on use (``from harness import runner``) so that importing the
package stays cheap.
"""

__all__ = ["paths", "scenes", "povwriter", "runner", "exr", "expect", "compare", "report"]
