"""Plugin layout: the core stands alone, imports are relative, metadata is complete, icons exist."""

from __future__ import annotations

import ast
import configparser
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.conftest import ROOT

CORE = ROOT / "bsp_triangulate"
PROVIDER = ROOT / "processing_provider"
CORE_FILES = sorted(CORE.rglob("*.py"))
PLUGIN_FILES = [ROOT / "__init__.py", ROOT / "plugin.py", *sorted(PROVIDER.rglob("*.py"))]
REQUIRED_METADATA = (
    "name",
    "qgisMinimumVersion",
    "qgisMaximumVersion",
    "supportsQt6",
    "description",
    "about",
    "version",
    "author",
    "email",
    "repository",
    "tracker",
    "homepage",
    "tags",
    "category",
    "icon",
    "experimental",
    "hasProcessingProvider",
    "changelog",
)


def absolute_imports(path: Path) -> set[str]:
    """Top-level names of the modules that ``path`` imports absolutely."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def metadata() -> configparser.SectionProxy:
    parser = configparser.ConfigParser(interpolation=None)
    parser.read(ROOT / "metadata.txt", encoding="utf-8")
    return parser["general"]


def test_core_package_has_python_files() -> None:
    assert CORE / "__init__.py" in CORE_FILES
    assert len(CORE_FILES) >= 2


@pytest.mark.parametrize("path", CORE_FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_core_module_imports_only_stdlib_numpy_and_shapely(path: Path) -> None:
    # Also catches qgis/PyQt and absolute imports of the core's own modules, which would
    # break when QGIS loads the core as bsptriangulate.bsp_triangulate. shapely is optional
    # (only the repair of crossing rings uses it); the test below imports the core without it.
    allowed = {"numpy", "shapely", "__future__"}
    if path.relative_to(CORE).parts[0] == "distributed":  # the optional Dask subpackage
        allowed |= {"dask", "distributed", "dask_geopandas", "geopandas", "pandas"}
        allowed |= {"pyarrow", "pyogrio", "pyproj", "osgeo"}
    foreign = absolute_imports(path) - set(sys.stdlib_module_names) - allowed
    assert foreign == set()


@pytest.mark.parametrize("path", PLUGIN_FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_plugin_module_imports_its_own_packages_relatively(path: Path) -> None:
    assert absolute_imports(path) & {
        "bsp_triangulate",
        "bsptriangulate",
        "processing_provider",
    } == (set())


def test_core_imports_in_a_python_where_qgis_cannot_be_imported() -> None:
    # A fresh interpreter with every qgis/PyQt import made to fail, as outside QGIS.
    code = (
        "import sys\n"
        "for name in ('qgis', 'qgis.core', 'PyQt5', 'PyQt6', 'shapely'):\n"
        "    sys.modules[name] = None\n"
        "import bsp_triangulate\n"
        "print(bsp_triangulate.Triangulation.__name__)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "Triangulation"


def test_metadata_has_every_key_the_plugin_repository_requires() -> None:
    general = metadata()
    missing = [key for key in REQUIRED_METADATA if not general.get(key, "").strip()]
    assert missing == []


def test_metadata_declares_qgis_322_to_4_qt6_and_a_processing_provider() -> None:
    general = metadata()
    assert general["qgisMinimumVersion"] == "3.22"
    # QGIS 4 (Qt 6) loads plugins that declare it; tests/test_qt6.py checks the code for it.
    assert general["qgisMaximumVersion"] == "4.99"
    assert general["supportsQt6"] == "True"
    assert general["hasProcessingProvider"] == "yes"
    assert general["experimental"] in {"True", "False"}
    assert (ROOT / general["icon"]).is_file()


def test_metadata_version_matches_pyproject_and_changelog() -> None:
    general = metadata()
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert re.search(r'^version = "(.+)"$', pyproject, re.MULTILINE)[1] == general["version"]
    assert general["changelog"].split()[0] == general["version"]


def test_every_algorithm_module_has_an_svg_icon() -> None:
    modules = sorted(PROVIDER.glob("*_algorithm.py"))
    assert modules, "processing_provider/ has no *_algorithm.py module"
    for module in modules:
        icon = ROOT / "icons" / f"{module.stem.removesuffix('_algorithm')}.svg"
        assert icon.is_file(), f"{module.name} has no {icon.relative_to(ROOT)}"
        assert ET.parse(icon).getroot().tag == "{http://www.w3.org/2000/svg}svg"


def test_license_is_gpl_as_the_plugin_repository_requires() -> None:
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert "GNU GENERAL PUBLIC LICENSE" in text
