#!/usr/bin/env python3
"""Checks the shading library's include rule: a file includes only its own layer and the layers
below it, as CMakeLists.txt names them (SHADING_LAYER_DEPS_<layer>), and the POV-Ray patches
include nothing of the library but the finish facade.

Usage: check_layers.py SHADING_DIR [PATCH_DIR]
Prints one line per offending include (file:line: what, and what the rule allows) and exits 1,
or prints a summary and exits 0. Tools, tests and fuzz targets stand above every layer.
"""
import pathlib
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]')
PATCH_INCLUDE = re.compile(r'^\+\s*#\s*include\s*[<"](shading/[^>"]+)[>"]')
#: What a POV-Ray patch may include of the library: the one facade.
PATCH_ALLOWED = ("shading/finish/",)


def layer_deps(shading: pathlib.Path) -> dict:
    """{layer: set of layers it may include}, read from CMakeLists.txt (the build's own rule)."""
    text = (shading / "CMakeLists.txt").read_text()
    order = re.search(r"set\(SHADING_LAYERS ([^)]*)\)", text)
    if not order:
        raise SystemExit(f"{shading / 'CMakeLists.txt'}: no set(SHADING_LAYERS ...) line")
    deps = {}
    for layer in order.group(1).split():
        m = re.search(rf"set\(SHADING_LAYER_DEPS_{layer}\b([^)]*)\)", text)
        deps[layer] = set(m.group(1).replace('""', "").split()) if m else set()
    # The rule is transitive: a layer may use what its layers use.
    changed = True
    while changed:
        changed = False
        for layer, ds in deps.items():
            more = set().union(*(deps.get(d, set()) for d in ds)) - ds
            if more:
                ds |= more
                changed = True
    return deps


def layer_of(path: pathlib.Path, shading: pathlib.Path, layers) -> str | None:
    rel = path.relative_to(shading).parts
    if rel[0] == "src" and len(rel) > 2 and rel[1] in layers:
        return rel[1]
    if rel[:2] == ("include", "shading") and len(rel) > 3 and rel[2] in layers:
        return rel[2]
    return None


def check(shading: pathlib.Path, patches: pathlib.Path | None = None) -> list:
    deps = layer_deps(shading)
    problems = []
    files = 0
    for path in sorted(list((shading / "src").rglob("*")) + list((shading / "include").rglob("*"))):
        if path.suffix not in (".h", ".cpp") or not path.is_file():
            continue
        files += 1
        rel = path.relative_to(shading)
        layer = layer_of(path, shading, deps)
        if layer is None:
            problems.append(f"{rel}: stands in no layer folder (src/<layer>/ or include/shading/<layer>/; "
                            f"layers: {', '.join(deps)})")
            continue
        for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            target = m.group(1)
            if not target.startswith("shading/"):
                if line.lstrip().startswith('#include "') and "/" not in target:
                    problems.append(f'{rel}:{n}: includes "{target}" by a bare name: write '
                                    f'"shading/<layer>/{target}"')
                continue
            parts = target.split("/")
            if len(parts) != 3 or parts[1] not in deps:
                problems.append(f'{rel}:{n}: includes "{target}", which names no layer '
                                f'(shading/<layer>/file.h; layers: {", ".join(deps)})')
                continue
            to = parts[1]
            if to != layer and to not in deps[layer]:
                allowed = ", ".join([layer] + sorted(deps[layer])) if deps[layer] else layer
                problems.append(f'{rel}:{n}: layer {layer} includes "{target}" from layer {to}; '
                                f"{layer} may include only {allowed}")
    if patches is not None:
        for patch in sorted(patches.glob("*.patch")):
            for n, line in enumerate(patch.read_text(errors="replace").splitlines(), 1):
                m = PATCH_INCLUDE.match(line)
                if m and not m.group(1).startswith(PATCH_ALLOWED):
                    problems.append(f'{patch.name}:{n}: a POV-Ray patch includes "{m.group(1)}"; '
                                    f"patches talk to the library through shading/finish/ only")
    check.files = files
    return problems


def main(argv) -> int:
    if len(argv) not in (2, 3):
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    shading = pathlib.Path(argv[1]).resolve()
    patches = pathlib.Path(argv[2]).resolve() if len(argv) == 3 else None
    problems = check(shading, patches)
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} include(s) break the layer rule", file=sys.stderr)
        return 1
    print(f"layers: {check.files} files keep the include rule"
          + (" and the patches include only the finish facade" if patches else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
