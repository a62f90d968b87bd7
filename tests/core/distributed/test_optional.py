"""The Dask subpackage stays optional: nothing else imports it, and the engine imports in a
Python where dask and its companions cannot be imported."""

from __future__ import annotations

import ast
import subprocess
import sys

from ...conftest import ROOT

CORE = ROOT / "bsp_triangulate"
OPTIONAL = ("dask", "distributed", "dask_geopandas", "geopandas", "pandas", "pyarrow", "pyogrio")


def imported_modules(path) -> set[str]:
    """Every module name ``path`` imports, relative ones with their leading dots."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


def test_no_other_module_imports_the_distributed_subpackage() -> None:
    for path in CORE.rglob("*.py"):
        if "distributed" in path.relative_to(CORE).parts:
            continue
        found = {name for name in imported_modules(path) if "distributed" in name.split(".")}
        assert found == set(), path


def test_the_engine_imports_without_dask() -> None:
    blocked = "".join(f"sys.modules[{name!r}] = None\n" for name in OPTIONAL)
    code = (
        f"import sys\n{blocked}"
        "import bsp_triangulate\n"
        "from bsp_triangulate import formats, terrain, metrics\n"
        "print(bsp_triangulate.triangulate([[(0, 0), (1, 0), (0, 1)]]).triangles.tolist())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[[0, 1, 2]]"
