"""Side by side: the four microfacet D terms and two G terms at equal roughness.

Eight normalised Cook-Torrance finishes (D = Blinn, Gaussian, Trowbridge-Reitz, Beckmann ×
G = V-cavity, Smith), every D at the same Beckmann-equivalent roughness ``m`` through the
documented mapping (Blinn n = 2/m² − 2, Gaussian n2 = 1/m, TR α = m; MODELS.md "Equal
roughness"), F = 1 (no Fresnel) so that only D and G differ. Each is rendered by the fork on a
sphere under one distant light per angle, and

* the contact sheet ``dg.png`` puts them side by side (rows: G, columns: D; one sheet per light);
* the table gives, per finish: rel-RMSE against the numpy closed form (the render is right),
  rel-RMSE against Beckmann/Smith (how much the choice of D and G changes the picture), the
  peak pixel, and the directional albedo at 0°, 60° and 85° (energy: V-cavity vs Smith, and
  TR's long tail).

    python -m harness.reports.dg_compare [--m 0.3] [--out out/dg] [--size 200]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from harness.reference import models
from harness.core import plotting, runner
from harness.core.compare import rel_rmse
from harness.core.exr import to_display
from harness.reference.expect import expected_image, surface_samples
from harness.core.paths import out_dir
from harness.core.scenes import DistantLight, SphereScene

DS = ("blinn", "gaussian", "tr", "beckmann")
GS = ("vcavity", "smith")
LIGHT_ANGLES = (30.0, 75.0)


def spec(d: str, g: str, m: float) -> str:
    return f"microfacet d={d} m={m:g} g={g}"


def render_all(m: float, size: int) -> dict[tuple[str, str, float], tuple[np.ndarray, np.ndarray]]:
    """(d, g, light angle) → (fork image, numpy expectation)."""
    out = {}
    for th in LIGHT_ANGLES:
        for d in DS:
            for g in GS:
                scene = SphereScene(lights=(DistantLight(th, 0.0),), finish={"brdf_model": {"spec": spec(d, g, m)}},
                                    width=size, height=size)
                out[(d, g, th)] = (runner.render(scene, "fork", float_exr=True).image, expected_image(scene))
    return out


def table(images, m: float, size: int) -> str:
    mask = surface_samples(SphereScene(width=size, height=size)).mask
    lines = [f"Equal roughness m = {m:g} (Beckmann-equivalent); F = 1, rho_s = 1, no diffuse base.", "",
             "| D | native parameter | G | " + " | ".join(f"vs closed form {a:g}°" for a in LIGHT_ANGLES)
             + " | " + " | ".join(f"vs Beckmann/Smith {a:g}°" for a in LIGHT_ANGLES)
             + " | peak " + f"{LIGHT_ANGLES[0]:g}°" + " | albedo 0° | albedo 60° | albedo 85° |",
             "|" + "---|" * (7 + 2 * len(LIGHT_ANGLES))]
    for d in DS:
        for g in GS:
            model = models.parse(spec(d, g, m))
            native = models.native_from_m(d, m)
            cf = [rel_rmse(*images[(d, g, a)], mask) for a in LIGHT_ANGLES]
            vs = [rel_rmse(images[(d, g, a)][0], images[("beckmann", "smith", a)][0], mask) for a in LIGHT_ANGLES]
            peak = float(images[(d, g, LIGHT_ANGLES[0])][0][mask].max())
            alb = [float(model.albedo(t, n=500)[0]) for t in (0.0, 60.0, 85.0)]
            name = {"blinn": "n1", "gaussian": "n2", "tr": "α", "beckmann": "m"}[d]
            lines.append(f"| {d} | {name} = {native:.4g} | {g} | " + " | ".join(f"{e:.1e}" for e in cf) + " | "
                         + " | ".join(f"{e:.3f}" for e in vs) + f" | {peak:.3f} | "
                         + " | ".join(f"{a:.3f}" for a in alb) + " |")
    return "\n".join(lines)


def contact_sheet(images, m: float, path: Path) -> None:
    plt = plotting.pyplot()
    rows = len(GS) * len(LIGHT_ANGLES)
    fig, axes = plt.subplots(rows, len(DS), figsize=(2.3 * len(DS), 2.45 * rows), dpi=110)
    for i, th in enumerate(LIGHT_ANGLES):
        scale = max(float(images[(d, g, th)][0].max()) for d in DS for g in GS)
        for j, g in enumerate(GS):
            for k, d in enumerate(DS):
                ax = axes[i * len(GS) + j, k]
                img = images[(d, g, th)][0] / max(scale, 1e-6)
                ax.imshow(to_display(img))
                ax.set_xticks([])
                ax.set_yticks([])
                ax.set_title(f"{d} · {g} · light {th:g}°", fontsize=plotting.SMALL_PT)
    fig.suptitle(f"D × G at equal roughness m = {m:g} (F = 1); one linear exposure per light (peak = white)",
                 fontsize=9)
    fig.tight_layout()
    plotting.save(fig, path)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.dg_compare", description=__doc__.split("\n\n")[0])
    ap.add_argument("--m", type=float, default=0.3, help="Beckmann-equivalent roughness (default 0.3)")
    ap.add_argument("--size", type=int, default=160, help="pixels per sphere (default 160)")
    ap.add_argument("--out", type=Path, default=out_dir("dg"), help="output folder (default out/dg)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    images = render_all(args.m, args.size)
    text = table(images, args.m, args.size)
    contact_sheet(images, args.m, args.out / "dg.png")
    (args.out / "dg.md").write_text(text + "\n")
    print(text)
    print(f"\ncontact sheet: {args.out / 'dg.png'}\ntable: {args.out / 'dg.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
