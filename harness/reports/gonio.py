"""Gonioreflectometer round trip: render a ``.brdf`` table on the virtual gonioreflectometer
(:class:`harness.core.scenes.FlatSampleScene`) at a grid of (theta_i, theta_r, phi) and recover
the table's values from the pixels.

The table (``brdftool tabulate``, unfolded, 5 deg, RGB) is a Beckmann conductor lobe on a small
Lambertian base, so values span three decades. Every pixel of a flat-sample render sees one
direction pair, and ``f = pixel / (pi cos(theta_i) E)`` (:func:`harness.reference.expect.measured_brdf`).

* **on-node** angles (multiples of the step) must give the stored values;
* **off-node** angles (cell centres: 12.5, 37.5, ... deg) must give the trilinear interpolation
  of the stored values (:func:`table_lookup`, the lookup of ``brdf_data/README.md``);
* the table itself differs from the model it tabulates between nodes: ``table vs model``
  (interpolation error at 5 deg), printed for scale, never asserted here.

    python -m harness.reports.gonio            # the quick grid
    python -m harness.reports.gonio --full     # the report's grid

``tests/test_gonio_roundtrip.py`` asserts the quick grid; ``harness.reports.report`` shows the full one.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from harness.core import brdf_io, plotting, runner, tables
from harness.reference import models
from harness.reference.expect import measured_brdf
from harness.core.scenes import FlatSampleScene

SPEC = "microfacet d=beckmann m=0.3 f=conductor n=0.143,0.374,1.442 k=3.983,2.385,1.603 kd=0.05 rho_s=0.95"
STEP = 5.0
#: Light colour: unequal channels, so a channel mix-up shows.
LIGHT = (1.0, 0.7, 0.4)


@dataclass(frozen=True)
class Grid:
    """Angles in degrees; on-node values must be multiples of :data:`STEP`."""

    nodes_theta: tuple[float, ...]
    nodes_phi: tuple[float, ...]
    off_theta: tuple[float, ...]
    off_phi: tuple[float, ...]

    def geometries(self) -> list[tuple[float, float, float, bool]]:
        """(theta_i, theta_r, phi, on_node); one azimuth only where a direction is the pole."""
        out = []
        for thetas, phis, on in ((self.nodes_theta, self.nodes_phi, True), (self.off_theta, self.off_phi, False)):
            for ti, tr in itertools.product(thetas, thetas):
                for phi in (phis[:1] if (ti == 0.0 or tr == 0.0) else phis):
                    out.append((ti, tr, phi, on))
        return out


QUICK = Grid((0.0, 30.0, 85.0), (0.0, 90.0, 180.0), (12.5, 62.5), (32.5, 167.5))
FULL = Grid((0.0, 20.0, 45.0, 70.0, 85.0), (0.0, 60.0, 120.0, 180.0),
            (12.5, 37.5, 62.5, 82.5), (32.5, 167.5))


@dataclass
class Point:
    theta_i: float
    theta_r: float
    phi: float
    on_node: bool
    measured: np.ndarray  # RGB, 1/sr
    table: np.ndarray     # the table's (interpolated) value
    model: np.ndarray     # the analytic model it tabulates

    @property
    def rel_error(self) -> float:
        """max over channels of |measured / table - 1|."""
        return float(np.max(np.abs(self.measured / self.table - 1.0)))

    @property
    def table_vs_model(self) -> float:
        return float(np.max(np.abs(self.table / self.model - 1.0)))


def table_path() -> Path:
    return tables.tabulated(SPEC, step=STEP, fold=False)


def table_lookup(f: np.ndarray, theta_i: float, theta_r: float, phi: float) -> np.ndarray:
    """Trilinear lookup of an unfolded isotropic table (n, n, 2n - 1, C) at angles in degrees."""
    n0, n1, n2, _ = f.shape
    phi = abs(phi) % 360.0
    phi = 360.0 - phi if phi > 180.0 else phi
    coords = []
    for a, n, span in ((theta_i, n0, 90.0), (theta_r, n1, 90.0), (phi, n2, 180.0)):
        u = min(max(a, 0.0), span) / (span / (n - 1))
        k = min(int(math.floor(u)), n - 2)
        coords.append((k, u - k))
    (i, ti), (r, tr), (p, tp) = coords
    out = 0.0
    for di, dr, dp in itertools.product((0, 1), repeat=3):
        w = (ti if di else 1 - ti) * (tr if dr else 1 - tr) * (tp if dp else 1 - tp)
        out = out + w * f[i + di, r + dr, p + dp].astype(np.float64)
    return np.asarray(out)


def measure(grid: Grid = QUICK, workers: int = 2, progress: bool = False) -> list[Point]:
    """Render every geometry of ``grid`` (fork, float EXR, 2 x 2 pixels) and recover f
    (``progress``: a bar of the renders on stderr)."""
    path = table_path()
    f, _ = brdf_io.read_brdf(path)
    model = models.parse(SPEC)
    geos = grid.geometries()
    scenes = [FlatSampleScene(theta_i_deg=ti, theta_r_deg=tr, phi_deg=phi, light_colour=LIGHT,
                              finish={"brdf_table": {"file": "t.brdf"}}, width=2, height=2)
              for ti, tr, phi, _ in geos]
    results = runner.render_many(scenes, binary="fork", float_exr=True, files={"t.brdf": path},
                                 max_workers=workers, progress=progress, progress_label="gonio")
    points = []
    for (ti, tr, phi, on), s, res in zip(geos, scenes, results):
        if not np.all(res.image == res.image[0, 0]):
            raise AssertionError(f"pixels differ at {ti}, {tr}, {phi}: the sample is not seen uniformly")
        fm = model.f(s.wo()[None, :], s.wi()[None, :])[0]
        points.append(Point(ti, tr, phi, on, measured_brdf(res.image, s), table_lookup(f, ti, tr, phi), fm))
    return points


def summary(points: Sequence[Point]) -> list[dict]:
    """One row per kind (on-node, off-node): count, max and rms relative error, table vs model."""
    rows = []
    for on, label in ((True, "on-node (stored values)"), (False, "off-node (trilinear between nodes)")):
        pts = [p for p in points if p.on_node == on]
        if not pts:
            continue
        e = np.array([p.rel_error for p in pts])
        m = np.array([p.table_vs_model for p in pts])
        rows.append({"angles": label, "points": len(pts), "max rel. error": float(e.max()),
                     "rms rel. error": float(np.sqrt(np.mean(e ** 2))),
                     "table vs model, max rel.": float(m.max())})
    return rows


def markdown(points: Sequence[Point]) -> str:
    lines = ["| angles | points | max rel. error | rms rel. error | table vs model, max rel. |", "|---|---|---|---|---|"]
    for r in summary(points):
        lines.append(f"| {r['angles']} | {r['points']} | {r['max rel. error']:.1e} | {r['rms rel. error']:.1e} | "
                     f"{r['table vs model, max rel.']:.1e} |")
    return "\n".join(lines)


def plot(points: Sequence[Point], path: Path, tol: float = 1e-6) -> Path:
    """Left: re-measured against stored/interpolated values (log-log); right: the relative
    error of each geometry, with the table's own error against its model for scale."""
    plt = plotting.pyplot()

    fig, (a, b) = plt.subplots(1, 2, figsize=(10.5, 4), dpi=100)
    pts = sorted(points, key=lambda p: (not p.on_node, p.theta_i, p.theta_r, p.phi))
    lo = min(float(p.table.min()) for p in pts)
    hi = max(float(p.table.max()) for p in pts)
    a.plot([lo / 2, hi * 2], [lo / 2, hi * 2], color="0.7", lw=1, zorder=0)
    for c, colour in enumerate(("tab:red", "tab:green", "tab:blue")):
        for on, marker in ((True, "o"), (False, "s")):
            sel = [p for p in pts if p.on_node == on]
            a.scatter([p.table[c] for p in sel], [p.measured[c] for p in sel], s=12, marker=marker,
                      facecolors=colour if on else "none", edgecolors=colour,
                      label=f"{'RGB'[c]}, {'on' if on else 'off'}-node")
    a.set(xscale="log", yscale="log", xlabel="table value (stored or trilinear), 1/sr",
          ylabel="re-measured f = pixel / (π cos θi E), 1/sr", title="Round trip: table → render → f")
    a.legend(fontsize=plotting.SMALL_PT, ncol=2)
    a.grid(True, which="major", alpha=0.3)
    idx = np.arange(len(pts))
    on = np.array([p.on_node for p in pts])
    rt = np.array([max(p.rel_error, 1e-10) for p in pts])
    tm = np.array([max(p.table_vs_model, 1e-10) for p in pts])
    b.scatter(idx[on], rt[on], s=14, c="tab:blue", label="|re-measured / table − 1|, on-node")
    b.scatter(idx[~on], rt[~on], s=14, c="tab:orange", label="|re-measured / table − 1|, off-node")
    b.scatter(idx, tm, s=18, marker="x", c="0.45", label=f"|table / model − 1| ({STEP:g}° table)")
    b.axhline(tol, color="tab:red", lw=1, ls="--", label=f"test tolerance {tol:g}")
    b.set(yscale="log", xlabel="geometry (on-node first, by θi, θr, φ)", ylabel="relative error, max over RGB",
          title="Relative error per geometry")
    b.set_ylim(1e-10, 1.0)
    b.legend(fontsize=plotting.SMALL_PT, loc="center right")
    b.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    plotting.save(fig, path)
    return Path(path)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.gonio", description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help="the report's grid (105 renders)")
    args = ap.parse_args(argv)
    print(markdown(measure(FULL if args.full else QUICK)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
