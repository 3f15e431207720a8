"""Polar plots of a tabulated BRDF in the plane of incidence, with fitted models on top.

    python -m harness.tools.brdfplot TABLE.brdf -o plot.png [--theta-i 0,30,60,75]
           [--model SPEC ...] [--fit [FAMILY]] [--log] [--channel r|g|b|all]

One polar panel per incidence angle, like the survey's figures: the angle is the viewing
angle theta_r in the plane of incidence (backward scattering, phi = 0 deg, on the left;
forward, phi = 180 deg, where the mirror lobe lies, on the right), the radius the BRDF in 1/sr on
labelled rings (linear, or log10 with ``--log``). The table's nodes are drawn as markers per
colour channel; each ``--model`` spec (``brdftool tabulate --help`` lists them) is evaluated
in numpy (:mod:`harness.reference.models`, the harness's independent re-derivation) and drawn
as a line; ``--fit`` runs ``brdftool fit`` on the table and overlays its best model. The
incident direction is marked with an arrow.

An anisotropic table (layout 2) is plotted in its phi_i = 0 slice. A half/difference table
(layout 3) has no nodes in that plane: it is drawn from its own interpolation
(:func:`harness.core.brdf_io.halfdiff_lookup`) every 0.5 deg, at the angles asked for.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from harness.core import brdf_io, plotting
from harness.core.paths import brdftool
from harness.reference import models

CHANNELS = (("R", "tab:red"), ("G", "tab:green"), ("B", "tab:blue"))


@dataclass(frozen=True)
class Slice:
    """The table in the plane of incidence at one theta_i node: signed viewing angles (deg,
    negative: backward, phi = 180) and values (n, C) in 1/sr, NaN where the table has no data."""

    theta_i: float
    theta_r: np.ndarray
    values: np.ndarray


def incidence_plane(f: np.ndarray, theta_i_deg: float) -> Slice:
    """The slice of an isotropic (theta_i, theta_r, phi, C) or anisotropic (theta_i, phi_i,
    theta_r, phi_r, C) table at the theta_i node nearest ``theta_i_deg``."""
    if f.ndim == 5:  # anisotropic: phi_i = 0, phi_r = 0 (forward) and 180 deg (backward)
        nt, nphi = f.shape[0], f.shape[3]
        i = int(round(theta_i_deg / 90.0 * (nt - 1)))
        step_r = 90.0 / (f.shape[2] - 1)
        back = f[i, 0, :, 0]                  # phi_r = phi_i: the light's side
        fwd = f[i, 0, :, nphi // 2]           # phi_r = 180 deg (n nodes on [0, 360))
    else:
        nt, nphi = f.shape[0], f.shape[2]
        i = int(round(theta_i_deg / 90.0 * (nt - 1)))
        step_r = 90.0 / (f.shape[1] - 1)
        back, fwd = f[i, :, 0], f[i, :, nphi - 1]  # phi = 0: back-scatter side; 180: mirror side
    tr = np.arange(f.shape[-3] if f.ndim == 4 else f.shape[2]) * step_r
    theta = np.concatenate([-tr[:0:-1], tr])
    values = np.concatenate([back[:0:-1], fwd]).astype(np.float64)
    values = np.where(values < 0, np.nan, values)  # negative cells mark "no data"
    return Slice(i * 90.0 / (nt - 1), theta, values)


def halfdiff_plane(f: np.ndarray, theta_i_deg: float, n: int = 359) -> Slice:
    """The plane of incidence of a half/difference table (theta_h, theta_d, phi_d, C), looked up
    (trilinear, as the renderer does) at ``n`` viewing angles in (-90, 90) deg."""
    tr = np.linspace(-89.5, 89.5, n)
    ti = math.radians(theta_i_deg)
    wi = np.broadcast_to(np.array([-math.sin(ti), 0.0, math.cos(ti)]), (n, 3))  # light on the back side
    r = np.radians(tr)
    wo = np.stack([np.sin(r), np.zeros(n), np.cos(r)], axis=-1)
    return Slice(theta_i_deg, tr, brdf_io.halfdiff_lookup(f, wi, wo))


def model_plane(spec: str, theta_i_deg: float, n: int = 361) -> tuple[np.ndarray, np.ndarray]:
    """A model (numpy reference) in the plane of incidence: signed theta_r (deg), f (n, 3)."""
    model = models.parse(spec)
    tr = np.linspace(-89.5, 89.5, n)
    ti = math.radians(theta_i_deg)
    wi = np.broadcast_to(np.array([-math.sin(ti), 0.0, math.cos(ti)]), (n, 3))  # light on the back side
    r = np.radians(tr)
    wo = np.stack([np.sin(r), np.zeros(n), np.cos(r)], axis=-1)
    val = np.asarray(model.f(wo, wi), dtype=np.float64)
    return tr, (val if val.ndim == 2 else np.repeat(val[:, None], 3, axis=1))


def fitted_spec(table: Path, family: str = "all") -> tuple[str, float]:
    """The best fit ``brdftool fit --tsv`` finds: (spec, error)."""
    p = subprocess.run([str(brdftool()), "fit", str(table), "--model", family, "--tsv", "--quiet"],
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"brdftool fit {table} failed: {p.stderr.strip()}")
    best: Optional[tuple[str, float]] = None
    for line in p.stdout.splitlines():
        cols = line.split("\t")
        if len(cols) < 5 or cols[0] == "family":
            continue
        try:
            err = float(cols[1])
        except ValueError:
            continue
        if best is None or err < best[1]:
            best = (cols[-1], err)
    if best is None:
        raise RuntimeError(f"brdftool fit {table}: no fit in its output")
    return best


def plot(table: Path, out: Path, theta_i: Sequence[float] = (0, 30, 60, 75),
         overlays: Sequence[tuple[str, str]] = (), log: bool = False, channels: str = "all",
         title: Optional[str] = None, shared_scale: bool = False) -> Path:
    """Write the figure; ``overlays`` are (label, spec) pairs drawn as lines. Each panel has
    its own rings unless ``shared_scale``."""
    tab = brdf_io.read_table(table)
    f, description = tab.f, tab.description
    chans = [c for c in range(f.shape[-1])] if channels == "all" else ["rgb".index(channels)]
    if f.shape[-1] == 1:
        chans = [0]
    hd = tab.layout == brdf_io.HALFDIFF
    slices = [halfdiff_plane(f, t) if hd else incidence_plane(f, t) for t in theta_i]
    curves = {(label, s.theta_i): model_plane(spec, s.theta_i) for label, spec in overlays for s in slices}

    def scale_of(vals: list[np.ndarray]):
        allv = np.concatenate([np.ravel(v) for v in vals]) if vals else np.array([1.0])
        allv = allv[np.isfinite(allv) & (allv > 0)]
        vmax = float(allv.max()) if allv.size else 1.0
        if log:
            vmin = max(float(np.percentile(allv, 1)) if allv.size else vmax * 1e-3, vmax * 1e-6)
            lo, hi = math.floor(math.log10(vmin)), math.ceil(math.log10(vmax))
            every = max(1, math.ceil((hi - lo) / 4))
            ticks = np.arange(every, hi - lo + 1, every)
            return ((lambda v, lo=lo: _log_radius(v, lo)), float(hi - lo), ticks,
                    [f"1e{lo + int(t)}" for t in ticks])
        ticks = _nice_ticks(vmax * 1.05)
        return (lambda v: v), vmax * 1.05, ticks, [f"{t:g}" for t in ticks]

    def values_of(s: Slice) -> list[np.ndarray]:
        return [s.values[:, chans]] + [curves[(label, s.theta_i)][1][:, chans] for label, _ in overlays]

    shared = scale_of([v for s in slices for v in values_of(s)]) if shared_scale else None

    plt = plotting.pyplot()
    fig, axes = plt.subplots(1, len(slices), subplot_kw={"projection": "polar"},
                             figsize=(3.3 * len(slices), 3.6), squeeze=False)
    styles = ["-", "--", ":", "-."]
    for ax, s in zip(axes[0], slices):
        radius, rmax, ticks, labels = shared or scale_of(values_of(s))
        ax.set_theta_zero_location("N")
        ax.set_theta_direction(-1)
        ax.set_thetamin(-90)
        ax.set_thetamax(90)
        ax.set_rlim(0, rmax)
        ax.set_rticks(ticks)
        ax.set_yticklabels(labels, fontsize=plotting.SMALL_PT)
        ax.set_rlabel_position(-45)
        for c in chans:
            name, colour = CHANNELS[c] if f.shape[-1] == 3 else ("table", "black")
            ax.plot(np.radians(s.theta_r), radius(s.values[:, c]), "-" if hd else ".", ms=2.5, lw=0.8,
                    color=colour, label=("table (interpolated) " if hd else "table ") + name if f.shape[-1] == 3
                    else "table")
        for k, (label, _) in enumerate(overlays):
            x, v = curves[(label, s.theta_i)]
            for c in chans:
                colour = CHANNELS[c][1] if f.shape[-1] == 3 else "black"
                ax.plot(np.radians(x), radius(v[:, c]), styles[k % len(styles)], lw=1.0, color=colour,
                        alpha=0.8, label=label if c == chans[0] else None)
        ax.annotate("", xy=(0, 0), xytext=(math.radians(-s.theta_i), rmax * 0.95),
                    arrowprops={"arrowstyle": "->", "color": "0.35", "lw": 1.0})
        ax.set_title(f"θi = {s.theta_i:g}°", pad=2)
        ax.text(0.5, -0.02, "BRDF (1/sr)" + (", log scale" if log else ""), transform=ax.transAxes,
                ha="center", va="top", fontsize=plotting.SMALL_PT)
    handles, labels_ = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels_, loc="lower center", ncol=min(6, len(labels_)), fontsize=plotting.SMALL_PT)
    heading = title or f"{table.name}: plane of incidence (left: backward, right: forward)"
    lines = heading_lines(heading, description if title is None else "", fig.get_figwidth() * fig.dpi, TITLE_PT)
    # The figure grows by the heading's extra lines, so the panels keep their size and no line is cut.
    line_in = TITLE_PT * 1.35 / 72
    extra = max(0, len(lines) - 2) * line_in
    fig.set_figheight(fig.get_figheight() + extra)
    fig.suptitle("\n".join(lines), fontsize=TITLE_PT)
    top = 1 - (len(lines) * line_in + 0.12) / fig.get_figheight()
    fig.tight_layout(rect=(0, 0.3 / fig.get_figheight(), 1, top))
    return plotting.save(fig, out)


#: The heading's point size.
TITLE_PT = 9


def heading_lines(heading: str, description: str, width_px: float, pt: float) -> list[str]:
    """The heading and the table's description, wrapped (never cut) to ``width_px`` at ``pt``
    points: a line holds about width / (0.55 em) characters, less a margin."""
    em_px = pt * 100 / 72  # plotting.DPI
    chars = max(20, int(width_px * 0.92 / (0.55 * em_px)))
    lines = textwrap.wrap(heading, chars) or [""]
    if description:
        lines += textwrap.wrap(description, chars, break_long_words=True, break_on_hyphens=False)
    return lines


def _log_radius(v: np.ndarray, lo: int) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.clip(np.log10(v) - lo, 0, None)


def _nice_ticks(top: float, count: int = 4) -> np.ndarray:
    """About ``count`` round ring values in (0, top]."""
    raw = top / count
    mag = 10 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=raw)
    return np.arange(1, int(top / step) + 1) * step


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="brdf-plot", description=__doc__.split("\n\n")[0])
    ap.add_argument("table", type=Path, help="a .brdf table")
    ap.add_argument("-o", "--out", type=Path, required=True, help="the PNG (or .svg/.pdf) to write")
    ap.add_argument("--theta-i", default="0,30,60,75", help="incidence angles in degrees (nearest node)")
    ap.add_argument("--model", action="append", default=[], metavar="SPEC", help="a model to overlay (repeatable)")
    ap.add_argument("--fit", nargs="?", const="all", default=None, metavar="FAMILY",
                    help="overlay brdftool fit's best model (of FAMILY; default all families)")
    ap.add_argument("--log", action="store_true", help="log10 radius")
    ap.add_argument("--shared-scale", action="store_true", help="the same rings in every panel")
    ap.add_argument("--channel", default="all", choices=["all", "r", "g", "b"])
    a = ap.parse_args(argv)
    try:
        angles = [float(x) for x in a.theta_i.split(",") if x.strip()]
        if not angles or any(not 0 <= t <= 90 for t in angles):
            raise ValueError(f"--theta-i: angles in [0, 90] degrees, got {a.theta_i!r}")
        overlays = [(spec, spec) for spec in a.model]
        for spec in a.model:
            models.parse(spec)  # a bad spec fails here, with its message
        if a.fit is not None:
            spec, err = fitted_spec(a.table, a.fit)
            print(f"brdf-plot: best fit {spec} (error {err:.4g})")
            overlays.append((f"fit: {spec} (error {err:.3g})", spec))
        out = plot(a.table, a.out, angles, overlays, log=a.log, channels=a.channel,
                   shared_scale=a.shared_scale)
    except (OSError, ValueError, KeyError, RuntimeError) as e:
        print(f"brdf-plot: {e}", file=sys.stderr)
        return 2
    print(f"brdf-plot: wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
