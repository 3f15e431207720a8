"""Image-based BRDF sampling: BRDF tables from float images of a sphere.

A sphere photographed (here: rendered by the fork into float32 EXR) by an orthographic camera
under one distant light of known direction and colour E gives one BRDF sample per pixel:
with the pixel's unit normal n, the direction to the viewer v and to the light l,

    f(wo, wi) = pixel / (pi cos(theta_i) E)          (POV units: pixel = pi f cos_i E)

with theta_i = angle(n, l), theta_r = angle(n, v), and phi the angle between the projections
of l and v on the tangent plane (phi = 180 deg is the mirror side, as in the .brdf format).
Every pixel of one image has the same angle between l and v, so one light direction samples
a 2-D slice of the isotropic (theta_i, theta_r, phi) domain; several light directions fill it.

Binning (``bin_samples``): each sample goes to the nearest node of an isotropic grid of step
``step`` degrees, and (reciprocity, on by default) also to the node with theta_i and theta_r
swapped; a node's value is the mean of its samples per channel, and the number of samples
is its coverage. Pixels with cos(theta_i) or cos(theta_r) below ``min_cos`` are dropped
(grazing pixels divide by a vanishing cosine and cover a sliver of the sphere). Empty nodes
hold NaN (no data) in the sparse table.

Hole filling (``fill_table``): ``brdftool fill`` applies the .brdf format's documented rule:
per channel, linear interpolation in node distance between the nearest valid nodes along
phi, then along theta_r, then theta_i (a copy of the one valid side at an edge); pole rows
are then averaged over phi. ``brdftool fit`` can also fit the sparse table directly (no-data
cells are excluded).

    python -m harness.tools.sphere_sampling --spec "microfacet d=beckmann m=0.35 kd=0.4 rho_s=0.5" \\
        --step 5 -o recovered.brdf        # render, recover, fill, report the round-trip error
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from harness.core import runner, tables
from harness.core.brdf_io import read_brdf, write_brdf
from harness.reference.expect import surface_samples
from harness.core.paths import brdftool
from harness.core.scenes import DistantLight, SphereScene, rgb


@dataclass
class Samples:
    """BRDF samples: angles in degrees (N,), values f in 1/sr (N, 3)."""

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi: np.ndarray
    f: np.ndarray


def extract_samples(image: np.ndarray, normals: np.ndarray, mask: np.ndarray, light_dir: Sequence[float],
                    view_dir: Sequence[float], light_colour=1.0, min_cos: float = 0.02) -> Samples:
    """BRDF samples from one image: ``normals`` (H, W, 3) unit, ``mask`` (H, W) the sphere,
    ``light_dir``/``view_dir`` unit world vectors towards the light / the camera."""
    l = np.asarray(light_dir, dtype=np.float64)
    l = l / np.linalg.norm(l)
    v = np.asarray(view_dir, dtype=np.float64)
    v = v / np.linalg.norm(v)
    n = normals[mask].astype(np.float64)
    px = image[mask].astype(np.float64)
    ci, co = n @ l, n @ v
    keep = (ci > min_cos) & (co > min_cos)
    n, px, ci, co = n[keep], px[keep], ci[keep], co[keep]
    lt = l[None, :] - ci[:, None] * n        # projections on the tangent plane
    vt = v[None, :] - co[:, None] * n
    ln, vn = np.linalg.norm(lt, axis=1), np.linalg.norm(vt, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cphi = np.einsum("ij,ij->i", lt, vt) / (ln * vn)
    cphi = np.where((ln > 1e-9) & (vn > 1e-9), cphi, 1.0)  # at a pole phi is undefined: 0
    e = np.asarray(rgb(light_colour))
    f = px / (math.pi * ci[:, None] * e[None, :])
    return Samples(np.degrees(np.arccos(np.clip(ci, -1, 1))), np.degrees(np.arccos(np.clip(co, -1, 1))),
                   np.degrees(np.arccos(np.clip(cphi, -1, 1))), f)


def concat(samples: Sequence[Samples]) -> Samples:
    return Samples(*(np.concatenate([getattr(s, k) for s in samples]) for k in ("theta_i", "theta_r", "phi", "f")))


def bin_samples(s: Samples, step: float = 5.0, reciprocal: bool = True, linear: bool = True,
                ridge: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Sparse table (n, n, 2n-1, 3) with NaN where empty, and its coverage counts (n, n, 2n-1).

    Each sample goes to its nearest node. With ``linear`` (default) a node's value is the
    intercept of a least-squares plane f = a + b dtheta_i + c dtheta_r + d dphi through its
    samples (offsets from the node, degrees), the slopes shrunk by a ridge of
    ``ridge`` x count (so a node whose samples do not span its cell falls back towards
    their mean); without it, the mean of its samples. The plane removes the bias of a mean
    taken off-centre where f is steep (near grazing and in narrow lobes).
    """
    n = int(round(90.0 / step)) + 1
    if abs((n - 1) * step - 90.0) > 1e-9:
        raise ValueError(f"step {step} must divide 90")
    m = 2 * n - 1
    ti, tr, ph, f = s.theta_i, s.theta_r, s.phi, s.f
    if reciprocal:
        ti, tr, ph, f = np.concatenate([ti, tr]), np.concatenate([tr, ti]), np.concatenate([ph, ph]), np.concatenate([f, f])
    i = np.clip(np.rint(ti / step).astype(int), 0, n - 1)
    r = np.clip(np.rint(tr / step).astype(int), 0, n - 1)
    p = np.clip(np.rint(ph / step).astype(int), 0, m - 1)
    flat = (i * n + r) * m + p
    cells = n * n * m
    count = np.bincount(flat, minlength=cells).astype(np.float64)
    have = count > 0
    table = np.full((cells, 3), np.nan)
    if not linear:
        for c in range(3):
            table[have, c] = np.bincount(flat, weights=f[:, c], minlength=cells)[have] / count[have]
        return table.reshape(n, n, m, 3), count.reshape(n, n, m)
    x = np.stack([np.ones_like(ti), ti - i * step, tr - r * step, ph - p * step], axis=1)
    M = np.zeros((cells, 4, 4))
    for a in range(4):
        for b in range(a, 4):
            M[:, a, b] = M[:, b, a] = np.bincount(flat, weights=x[:, a] * x[:, b], minlength=cells)
    Y = np.zeros((cells, 4, 3))
    for a in range(4):
        for c in range(3):
            Y[:, a, c] = np.bincount(flat, weights=x[:, a] * f[:, c], minlength=cells)
    reg = np.zeros((cells, 4, 4))
    for a in range(1, 4):
        reg[:, a, a] = ridge * count
    sol = np.linalg.solve(M[have] + reg[have] + 1e-12 * np.eye(4), Y[have])
    table[have] = sol[:, 0, :]
    # A plane can extrapolate below zero at a cell's edge: keep the mean there.
    mean = np.stack([np.bincount(flat, weights=f[:, c], minlength=cells)[have] / count[have] for c in range(3)], axis=1)
    table[have] = np.where(table[have] >= 0, table[have], mean)
    return table.reshape(n, n, m, 3), count.reshape(n, n, m)


def fill_table(sparse_path: Path, out_path: Path) -> Path:
    """``brdftool fill``: the format's documented hole filling."""
    proc = subprocess.run([str(brdftool()), "fill", str(sparse_path), "-o", str(out_path)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"brdftool fill failed: {proc.stderr.strip()}")
    return out_path


def render_views(table: Path, light_thetas: Sequence[float], size: int = 128) -> list[tuple[SphereScene, np.ndarray]]:
    """The sphere with ``brdf_table`` of ``table`` under one light per angle (from the view axis)."""
    scenes = [SphereScene(lights=(DistantLight(t, 20.0 + 37.0 * k),), finish={"brdf_table": {"file": "t.brdf"}},
                          width=size, height=size) for k, t in enumerate(light_thetas)]
    res = runner.render_many(scenes, binary="fork", float_exr=True, files={"t.brdf": table}, progress=False)
    return [(sc, r.image) for sc, r in zip(scenes, res)]


def samples_from_views(views: Sequence[tuple[SphereScene, np.ndarray]], min_cos: float = 0.02) -> Samples:
    out = []
    for sc, img in views:
        ss = surface_samples(sc)
        view = -sc.camera().ray_direction()
        for lt in sc.world_lights():
            out.append(extract_samples(img, ss.normal, ss.mask, lt.direction, view, lt.colour, min_cos))
    return concat(out)


def model_nodes(spec_or_table: Path, step: float) -> np.ndarray:
    """Reference values at the nodes of a ``step`` grid: the known table resampled by brdftool."""
    out = Path(str(spec_or_table) + f".ref{step:g}.brdf")
    proc = subprocess.run([str(brdftool()), "resample", str(spec_or_table), "--step", repr(float(step)), "--unfold",
                           "-o", str(out)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr)
    f, _ = read_brdf(out)
    out.unlink()
    return f.astype(np.float64)


def cos_weighted_rel_rmse(a: np.ndarray, ref: np.ndarray, valid: np.ndarray) -> float:
    """brdftool's metric: sqrt(sum w (a - ref)^2 / sum w ref^2), w = cos(theta_i of the node)."""
    n = a.shape[0]
    w = np.cos(np.radians(np.linspace(0, 90, n)))[:, None, None] * np.ones(a.shape[:3])
    w[-1] = 0.0
    w = np.where(valid, w, 0.0)[..., None]
    d = np.where(valid[..., None], a - ref, 0.0)
    r = np.where(valid[..., None], ref, 0.0)
    return float(np.sqrt(np.sum(w * d * d) / np.sum(w * r * r)))


@dataclass
class RoundTrip:
    coverage: float          # fraction of nodes with data (theta_i, theta_r < 90)
    covered_error: float     # cos-weighted rel-RMSE over covered nodes with theta_i, theta_r < 90
    covered_error_80: float  # ... with theta_i, theta_r <= 80 deg
    filled_error: float      # over every node with theta_i, theta_r < 90 after filling
    filled_error_80: float
    samples: int
    sparse: Path
    filled: Path


def theta_mask(n: int, m: int, limit: float) -> np.ndarray:
    """Nodes (n, n, m) with theta_i and theta_r below ``limit`` degrees (strictly, for 90)."""
    ang = np.linspace(0.0, 90.0, n)
    ok = ang < limit if limit >= 90 else ang <= limit
    return np.broadcast_to(ok[:, None, None] & ok[None, :, None], (n, n, m)).copy()


def round_trip(known_table: Path, light_thetas: Sequence[float], step: float = 5.0, size: int = 128,
               out_dir: Optional[Path] = None, min_cos: float = 0.02) -> RoundTrip:
    """Render ``known_table`` on the sphere, recover a ``step`` table, compare with the known one.

    The 90 deg nodes are left out of the comparison: the known table holds the value half a
    table step inside there (brdftool's grazing rule), the sphere's samples at the limb are
    cut by ``min_cos``, and no render sees those nodes (cos = 0).
    """
    out_dir = Path(out_dir or tables.CACHE_DIR)
    out_dir.mkdir(parents=True, exist_ok=True)
    views = render_views(known_table, light_thetas, size)
    s = samples_from_views(views, min_cos)
    sparse, cov = bin_samples(s, step)
    stem = Path(known_table).stem
    sparse_path = write_brdf(out_dir / f"{stem}-sphere{step:g}-sparse.brdf", sparse,
                             f"sphere sampling of {Path(known_table).name}: {len(light_thetas)} views, {size}px, "
                             f"step {step:g}, {int((cov > 0).sum())} nodes covered")
    filled_path = fill_table(sparse_path, out_dir / f"{stem}-sphere{step:g}.brdf")
    ref = model_nodes(known_table, step)
    filled, _ = read_brdf(filled_path)
    filled = filled.astype(np.float64)
    n, m = cov.shape[0], cov.shape[2]
    below90, below80 = theta_mask(n, m, 90.0), theta_mask(n, m, 80.0)
    covered = cov > 0
    return RoundTrip(coverage=float(covered[below90].mean()),
                     covered_error=cos_weighted_rel_rmse(sparse, ref, covered & below90),
                     covered_error_80=cos_weighted_rel_rmse(sparse, ref, covered & below80),
                     filled_error=cos_weighted_rel_rmse(filled, ref, below90),
                     filled_error_80=cos_weighted_rel_rmse(filled, ref, below80),
                     samples=len(s.f), sparse=sparse_path, filled=filled_path)


DEFAULT_THETAS = tuple(float(t) for t in range(0, 176, 5))


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.tools.sphere_sampling", description=__doc__.split("\n\n")[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--table", type=Path, help="known .brdf table to render")
    src.add_argument("--spec", help="analytic spec, tabulated at 1 deg as the known table")
    ap.add_argument("--step", type=float, default=5.0, help="recovered table step, degrees (default 5)")
    ap.add_argument("--size", type=int, default=128, help="image size (default 128)")
    ap.add_argument("--thetas", default=",".join(f"{t:g}" for t in DEFAULT_THETAS),
                    help="light angles from the view axis, degrees (default 0,5,...,175: gaps in this angle leave the grazing mirror region unsampled)")
    ap.add_argument("-o", "--output", type=Path, help="copy the filled table here")
    args = ap.parse_args(argv)
    known = args.table or tables.tabulated(args.spec, step=1.0)
    rt = round_trip(known, [float(t) for t in args.thetas.split(",")], args.step, args.size)
    print(f"known table:   {known}\nsamples:       {rt.samples}\n"
          f"coverage:      {100 * rt.coverage:.1f} % of nodes (theta_i, theta_r < 90)\n"
          f"cos-weighted rel-RMSE     theta < 90   theta <= 80\n"
          f"  covered nodes            {rt.covered_error:9.4f}   {rt.covered_error_80:9.4f}\n"
          f"  all nodes after filling  {rt.filled_error:9.4f}   {rt.filled_error_80:9.4f}\n"
          f"sparse: {rt.sparse}\nfilled: {rt.filled}")
    if args.output:
        args.output.write_bytes(rt.filled.read_bytes())
        print(f"written: {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
