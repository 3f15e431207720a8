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
from harness.tools import sphere_photo


@dataclass
class Samples:
    """BRDF samples: angles in degrees (N,), values f in 1/sr (N, 3)."""

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi: np.ndarray
    f: np.ndarray


def samples_from_pixels(normals: np.ndarray, views: np.ndarray, pixels: np.ndarray, light_dir: Sequence[float],
                        light_colour=1.0, min_cos: float = 0.02, scale: float = math.pi) -> Samples:
    """BRDF samples from pixels (N, 3): unit ``normals``, unit ``views`` (towards the camera),
    ``pixels`` = ``scale`` f cos(theta_i) E (scale pi in POV units, 1 for radiance). Pixels
    with cos(theta_i) or cos(theta_r) at or below ``min_cos`` are dropped."""
    l = np.asarray(light_dir, dtype=np.float64)
    l = l / np.linalg.norm(l)
    n = np.asarray(normals, dtype=np.float64)
    v = np.asarray(views, dtype=np.float64)
    px = np.asarray(pixels, dtype=np.float64)
    ci, co = n @ l, np.einsum("ij,ij->i", n, v)
    keep = (ci > min_cos) & (co > min_cos)
    n, v, px, ci, co = n[keep], v[keep], px[keep], ci[keep], co[keep]
    lt = l[None, :] - ci[:, None] * n        # projections on the tangent plane
    vt = v - co[:, None] * n
    ln, vn = np.linalg.norm(lt, axis=1), np.linalg.norm(vt, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cphi = np.einsum("ij,ij->i", lt, vt) / (ln * vn)
    cphi = np.where((ln > 1e-9) & (vn > 1e-9), cphi, 1.0)  # at a pole phi is undefined: 0
    e = np.asarray(rgb(light_colour) if not isinstance(light_colour, np.ndarray) else light_colour, dtype=np.float64)
    f = px / (scale * ci[:, None] * e[None, :])
    return Samples(np.degrees(np.arccos(np.clip(ci, -1, 1))), np.degrees(np.arccos(np.clip(co, -1, 1))),
                   np.degrees(np.arccos(np.clip(cphi, -1, 1))), f)


def extract_samples(image: np.ndarray, normals: np.ndarray, mask: np.ndarray, light_dir: Sequence[float],
                    view_dir: Sequence[float], light_colour=1.0, min_cos: float = 0.02) -> Samples:
    """BRDF samples from one POV-units image: ``normals`` (H, W, 3) unit, ``mask`` (H, W) the
    sphere, ``light_dir``/``view_dir`` unit world vectors towards the light / the camera."""
    v = np.asarray(view_dir, dtype=np.float64)
    v = v / np.linalg.norm(v)
    n = normals[mask]
    return samples_from_pixels(n, np.broadcast_to(v, n.shape), image[mask], light_dir, light_colour, min_cos)


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


# ---------------------------------------------------------------- photographs

@dataclass
class PhotoStats:
    """What one photograph gave: pixels whose centre sees the sphere, and where they went."""

    path: Path
    on_sphere: int
    limb: int          # a corner off the sphere
    masked: int
    bad: int           # NaN, Inf or negative values
    grazing: int       # cos(theta_i) or cos(theta_r) <= min_cos (unlit or edge-on)
    used: int


def photo_samples(desc: sphere_photo.Description, photo: sphere_photo.Photo,
                  min_cos: float = 0.02) -> tuple[Samples, PhotoStats]:
    """The samples of one photograph described by ``desc`` (see :mod:`harness.tools.sphere_photo`)."""
    img = sphere_photo.read_image(photo.path)
    sphere_photo.check_size(desc, photo.path, img)
    h, w = img.shape[:2]
    geo = sphere_photo.sphere_geometry(desc, w, h)
    if geo.covered == 0:
        raise sphere_photo.PhotoError(
            f"{photo.path}: the sphere of {desc.path} covers no pixel of this {w}x{h} photograph: check [sphere] "
            "(centre, radius) and [camera] (position, look, width or fov)")
    use = geo.inside.copy()
    limb = geo.covered - int(use.sum())
    mask = sphere_photo.load_mask(desc, w, h, photo.path)
    masked = 0
    if mask is not None:
        masked = int((use & ~mask).sum())
        use &= mask
    finite = np.isfinite(img).all(axis=-1) & (img >= 0).all(axis=-1)
    bad = int((use & ~finite).sum())
    use &= finite
    s = samples_from_pixels(geo.normal[use], geo.view[use], img[use], photo.light.direction,
                            photo.light.irradiance, min_cos, desc.pixel_scale())
    stats = PhotoStats(photo.path, geo.covered, limb, masked, bad, int(use.sum()) - len(s.f), len(s.f))
    return s, stats


def _unlit(st: PhotoStats, desc: sphere_photo.Description, min_cos: float) -> str:
    return (f"{st.path}: no lit pixel: {st.on_sphere} pixels see the sphere, {st.used + st.grazing} of them whole "
            f"and unmasked, none both lit and seen (cos theta_i and cos theta_r > {min_cos:g}); check [light] "
            f"direction (towards the light) and [sphere] in {desc.path}")


@dataclass
class PhotoTable:
    samples: int
    coverage: float          # fraction of nodes with data (theta_i, theta_r < 90)
    stats: list[PhotoStats]
    sparse: Path
    filled: Path


def table_from_photos(desc: sphere_photo.Description, out: Path, step: float = 5.0,
                      min_cos: float = 0.02) -> PhotoTable:
    """Samples of every photograph of ``desc`` binned into a ``step`` table: the sparse table
    (``OUT-sparse.brdf``, no-data where no photograph saw a node) and, holes filled by
    ``brdftool fill``, ``out``."""
    out = Path(out)
    got = [photo_samples(desc, p, min_cos) for p in desc.photos]
    unlit = [st for _, st in got if st.used == 0]
    if len(unlit) == len(got):  # one photograph, or all of them: the description is wrong
        raise sphere_photo.PhotoError("\n".join(_unlit(st, desc, min_cos) for st in unlit))
    for st in unlit:  # in a set, a photograph lit from behind may see nothing usable
        print(f"brdf-sphere-sampling: warning: {st.path.name}: no pixel both lit and seen (cos theta_i and "
              f"cos theta_r > {min_cos:g}): it adds nothing", file=sys.stderr)
    s = concat([g[0] for g in got])
    sparse, cov = bin_samples(s, step)
    n, m = cov.shape[0], cov.shape[2]
    covered = float((cov > 0)[theta_mask(n, m, 90.0)].mean())
    names = ", ".join(p.path.name for p in desc.photos)
    sparse_path = write_brdf(out.with_name(out.stem + "-sparse.brdf"), sparse,
                             f"sphere photographs {names} ({desc.path.name}): {len(s.f)} samples, step {step:g}, "
                             f"{int((cov > 0).sum())} nodes covered")
    fill_table(sparse_path, out)
    return PhotoTable(len(s.f), covered, [g[1] for g in got], sparse_path, out)


def compare_tables(table: Path, sparse: Path, reference: Path, step: float) -> dict[str, float]:
    """Cos-weighted rel-RMSE of a recovered table against a known one: over the nodes the
    photographs covered and over every node after filling, for theta < 90 and theta <= 80."""
    ref = model_nodes(reference, step)
    sp, _ = read_brdf(sparse, nodata="keep")
    fl, _ = read_brdf(table)
    sp, fl = sp.astype(np.float64), fl.astype(np.float64)
    n, m = sp.shape[0], sp.shape[2]
    covered = np.isfinite(sp).all(axis=-1)
    b90, b80 = theta_mask(n, m, 90.0), theta_mask(n, m, 80.0)
    return {"covered": cos_weighted_rel_rmse(np.nan_to_num(sp), ref, covered & b90),
            "covered_80": cos_weighted_rel_rmse(np.nan_to_num(sp), ref, covered & b80),
            "filled": cos_weighted_rel_rmse(fl, ref, b90), "filled_80": cos_weighted_rel_rmse(fl, ref, b80)}


def _photo_main(args: argparse.Namespace) -> int:
    if args.output is None:
        raise sphere_photo.PhotoError("-o OUT.brdf is required: where to write the recovered table")
    desc = sphere_photo.load_description(args.describe, args.photos)
    rt = table_from_photos(desc, args.output, args.step, args.min_cos)
    for st in rt.stats:
        print(f"{st.path.name}: {st.on_sphere} pixels on the sphere, {st.used} used ({st.limb} on the limb, "
              f"{st.masked} masked, {st.grazing} unlit or edge-on, {st.bad} not finite or negative)")
    print(f"samples:  {rt.samples} from {len(rt.stats)} photograph(s)\n"
          f"coverage: {100 * rt.coverage:.1f} % of the nodes (theta_i, theta_r < 90 deg) at {args.step:g} deg\n"
          f"sparse:   {rt.sparse} (no-data where no photograph saw the node)\n"
          f"table:    {rt.filled} (holes filled by brdftool fill; f in 1/sr)")
    if args.reference:
        e = compare_tables(rt.filled, rt.sparse, args.reference, args.step)
        print(f"error against {args.reference} (rel-RMSE of f, cos theta_i weighted):\n"
              f"                           theta < 90   theta <= 80\n"
              f"  covered nodes            {e['covered']:9.4f}   {e['covered_80']:9.4f}\n"
              f"  all nodes after filling  {e['filled']:9.4f}   {e['filled_80']:9.4f}")
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="brdf-sphere-sampling", description=__doc__.split("\n\n")[0],
        epilog="From photographs: brdf-sphere-sampling PHOTO.exr... --describe PHOTO.toml -o TABLE.brdf "
               "(the description's format: python -m pydoc harness.tools.sphere_photo, docs/fitting.md). "
               "Round trip of a known table: --table T.brdf or --spec SPEC.")
    ap.add_argument("photos", nargs="*", type=Path, help="photographs of the sphere (linear EXR), with --describe")
    ap.add_argument("--describe", type=Path, metavar="TOML",
                    help="how the photographs were taken: camera, sphere, light, optional mask")
    ap.add_argument("--reference", type=Path, metavar="KNOWN.brdf",
                    help="with --describe: also print the recovered table's error against this table")
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--table", type=Path, help="round trip: a known .brdf table to render")
    src.add_argument("--spec", help="round trip: an analytic spec, tabulated at 1 deg as the known table")
    ap.add_argument("--step", type=float, default=5.0, help="recovered table step, degrees (default 5)")
    ap.add_argument("--min-cos", type=float, default=0.02,
                    help="drop pixels with cos(theta_i) or cos(theta_r) at or below this (default 0.02)")
    ap.add_argument("--size", type=int, default=128, help="round trip: image size (default 128)")
    ap.add_argument("--thetas", default=",".join(f"{t:g}" for t in DEFAULT_THETAS),
                    help="round trip: light angles from the view axis, degrees (default 0,5,...,175: gaps in this "
                         "angle leave the grazing mirror region unsampled)")
    ap.add_argument("-o", "--output", type=Path, help="the recovered (filled) table")
    args = ap.parse_args(argv)
    if args.describe is not None:
        if args.table or args.spec:
            ap.error("--describe (photographs) and --table/--spec (round trip) exclude each other")
        try:
            return _photo_main(args)
        except (sphere_photo.PhotoError, RuntimeError) as e:
            print(f"brdf-sphere-sampling: {e}", file=sys.stderr)
            return 2
    if args.photos:
        ap.error("photographs need --describe PHOTO.toml (how they were taken)")
    if not (args.table or args.spec):
        ap.error("give photographs with --describe, or --table/--spec for a round trip")
    known = args.table or tables.tabulated(args.spec, step=1.0)
    rt = round_trip(known, [float(t) for t in args.thetas.split(",")], args.step, args.size, min_cos=args.min_cos)
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
