"""Which model does a table need? ``brdftool recommend`` plus image error on a reference render.

    python -m harness.tools.recommend build/brdf_data/red-plastic-measured.brdf [--tol 0.05]

1. The render costs (:mod:`harness.tools.cost`) are measured once into ``build/costs.txt``
   (``--no-measure`` uses whatever is there, or brdftool's built-in order).
2. ``brdftool recommend TABLE --tsv`` fits every family and ranks them by the table error
   (cos-weighted rel-RMSE over the table's nodes, see ``shading/include/shading/fit/fit.h``)
   against the cost; it names the cheapest family within ``--tol`` or "keep the table".
3. The reference render: a sphere under three distant lights (head-on, 45 deg and a grazing
   80 deg light), orthographic, 128x128, rendered by the fork once with ``brdf_table`` of the
   table and once with ``brdf_model`` of each fitted spec (the choice and the ``--render``
   best families). Image error = rel-RMSE over the sphere's pixels
   (:func:`harness.core.compare.rel_rmse`) against the table render.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

from harness.tools import cost
from harness.core import runner
from harness.core.compare import rel_rmse
from harness.reference.expect import surface_samples
from harness.core.paths import brdftool
from harness.core.scenes import DistantLight, SphereScene

LIGHTS = (DistantLight(0.0), DistantLight(45.0, 30.0), DistantLight(80.0, 200.0))


@dataclass
class Row:
    family: str
    error: float          # table error (brdftool's metric)
    cost: float
    within: bool
    spec: str
    image_error: Optional[float] = None


def run_recommend(table: Path, tol: float, costs: Optional[Path], model: str = "all",
                  extra: Sequence[str] = ()) -> tuple[list[Row], float, str]:
    """Rows (best error first), the table's cost, and the chosen family (or 'table')."""
    cmd = [str(brdftool()), "recommend", str(table), "--tsv", "--quiet", "--tol", repr(tol), "--model", model, *extra]
    if costs is not None:
        cmd += ["--costs", str(costs)]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"brdftool recommend failed: {out.stderr.strip()}")
    rows, table_cost, choice = [], float("nan"), "table"
    for line in out.stdout.splitlines()[1:]:
        f = line.split("\t")
        if f[0] == "table":
            table_cost = float(f[2])
        elif f[0] == "choice":
            choice = f[1]
        else:
            rows.append(Row(f[0], float(f[1]), float(f[2]), f[3] == "yes", f[4]))
    return rows, table_cost, choice


def sphere(finish: dict, size: int) -> SphereScene:
    return SphereScene(lights=LIGHTS, finish=finish, width=size, height=size)


def image_errors(table: Path, rows: Sequence[Row], size: int = 128) -> None:
    """Fills ``row.image_error`` for each row: rel-RMSE of the model render vs the table render."""
    mask = surface_samples(sphere({}, size)).mask
    ref = runner.render(sphere({"brdf_table": {"file": "t.brdf"}}, size), "fork", float_exr=True,
                        files={"t.brdf": table}).image
    jobs = [runner.RenderJob(sphere({"brdf_model": {"spec": r.spec}}, size), {"float_exr": True}) for r in rows]
    for r, res in zip(rows, runner.render_many(jobs, binary="fork", progress=False, return_exceptions=True)):
        r.image_error = float("nan") if isinstance(res, Exception) else rel_rmse(res.image, ref, mask)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="brdf-recommend", description=__doc__.split("\n\n")[0])
    ap.add_argument("table", type=Path)
    ap.add_argument("--tol", type=float, default=0.05, help="largest acceptable table error (default 0.05)")
    ap.add_argument("--model", default="all", help="family pattern for brdftool (default all)")
    ap.add_argument("--render", type=int, default=5, help="render the N best families as well as the choice")
    ap.add_argument("--size", type=int, default=128, help="reference render size (default 128)")
    ap.add_argument("--no-measure", action="store_true", help="do not measure costs if build/costs.txt is missing")
    args = ap.parse_args(argv)
    costs: Optional[Path] = None
    if args.no_measure:
        costs = cost.COSTS_PATH if cost.COSTS_PATH.is_file() else None
    else:
        costs = cost.ensure_costs(log=lambda s: print(s, file=sys.stderr, flush=True))
    rows, table_cost, choice = run_recommend(args.table, args.tol, costs, args.model)
    chosen = [r for r in rows if r.family == choice]
    show = rows[: max(0, args.render)] + [r for r in chosen if r not in rows[: max(0, args.render)]]
    image_errors(args.table, show, args.size)
    print(f"table: {args.table}\ncosts: {costs or 'built-in order'}\ntolerance: {args.tol}\n")
    print(f"  {'model':<44} {'table err':>9} {'image err':>9} {'cost':>6}  within tol")
    for r in rows:
        img = f"{r.image_error:9.4f}" if r.image_error is not None else " " * 9
        print(f"  {r.family:<44} {r.error:9.4f} {img} {r.cost:6.3f}  {'yes' if r.within else ''}")
    print(f"  {'(keep the table)':<44} {0:9.4f} {0:9.4f} {table_cost:6.3f}  yes\n")
    if choice == "table":
        print(f"choice: keep the table (no model within {args.tol})")
    else:
        c = chosen[0]
        print(f"choice: {c.family} (table error {c.error:.4f}, image error {c.image_error:.4f}, cost {c.cost:.3f}"
              f" vs table {table_cost:.3f})\n  finish {{ brdf_model {{ \"{c.spec}\" }} }}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
