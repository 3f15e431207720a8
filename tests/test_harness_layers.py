"""The harness's layering contract (pyproject.toml, [tool.importlinter]): reports above tools
above reference above core, no import cycles inside a package, and no module reaching into
another module's private names."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from harness.core.paths import REPO_ROOT

HARNESS = REPO_ROOT / "harness"
LAYERS = ["reports", "tools", "reference", "core"]


def test_import_contracts_kept():
    """``lint-imports`` (import-linter) checks both contracts of pyproject.toml."""
    exe = Path(sys.executable).with_name("lint-imports")
    p = subprocess.run([str(exe)], cwd=REPO_ROOT, capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "2 kept, 0 broken" in p.stdout


def test_every_module_lives_in_a_layer():
    """No module at the top of the package: each one has a role."""
    top = sorted(p.name for p in HARNESS.glob("*.py") if p.name != "__init__.py")
    assert top == []
    assert sorted(p.name for p in HARNESS.iterdir() if p.is_dir() and (p / "__init__.py").is_file()) == sorted(LAYERS)


def _imports(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("harness"):
            for alias in node.names:
                yield node.lineno, node.module, alias.name


def test_no_private_names_imported_across_modules():
    """``from harness.x.y import _name`` (a private helper of another module) is not allowed;
    make it public in the module where a newcomer would look for it."""
    bad = []
    for path in HARNESS.rglob("*.py"):
        for line, module, name in _imports(path):
            if name.startswith("_") and not name.startswith("__"):
                bad.append(f"{path.relative_to(REPO_ROOT)}:{line}: from {module} import {name}")
    assert bad == []


def test_no_private_attributes_of_harness_modules_used():
    """``module._name`` on an imported harness module is the same reach into private code."""
    bad = []
    for path in list(HARNESS.rglob("*.py")) + list((REPO_ROOT / "tests").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        modules = {alias.asname or alias.name for node in ast.walk(tree)
                   if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("harness")
                   for alias in node.names if not alias.name[0].isupper()}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules
                    and node.attr.startswith("_") and not node.attr.startswith("__")):
                bad.append(f"{path.relative_to(REPO_ROOT)}:{node.lineno}: {node.value.id}.{node.attr}")
    assert bad == []
