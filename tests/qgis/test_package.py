"""`make package`'s zip: one ``bsptriangulate/`` folder with run-time files only, which the plugin
repository's uploader would take and which, installed into a fresh QGIS profile as the plugin
manager does, runs under qgis_process."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from qgis.core import QgsVectorLayer

from tests.conftest import (
    PLUGIN_PACKAGE,
    ROOT,
    QgisProcess,
    make_qgis_process,
    profile_plugins_dir,
    read_mesh,
    write_geojson,
)

X0, Y0 = 300_000.0, 6_200_000.0  # UTM 33S, near Swellendam
SQUARE = [(0, 0), (10, 0), (10, 10), (0, 10)]
HOLE = [(4, 4), (4, 6), (6, 6), (6, 4)]
L_SHAPE = [(20, 0), (26, 0), (26, 2), (22, 2), (22, 6), (20, 6)]
AREA = 10 * 10 - 2 * 2 + (6 * 2 + 2 * 4)
# A triangulation that adds no vertex has n + 2h - 2 triangles: n vertices, h holes.
TRIANGLES = (8 + 2 * 1 - 2) + (6 - 2)
NOT_IN_ZIP = {"tests", "bench", "scripts", "docs", ".ci", ".venv", ".git", "__pycache__", "dist"}


def package_script():
    """scripts/package.py as a module (scripts/ is not a package)."""
    spec = importlib.util.spec_from_file_location("package_script", ROOT / "scripts" / "package.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def ring(points: list[tuple[int, int]]) -> list[tuple[float, float]]:
    """Closed ring shifted to the UTM origin above."""
    shifted = [(X0 + x, Y0 + y) for x, y in points]
    return [*shifted, shifted[0]]


@pytest.fixture(scope="module")
def plugin_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "package.py"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return Path(proc.stdout.strip())


@pytest.fixture(scope="module")
def installed(plugin_zip: Path, tmp_path_factory: pytest.TempPathFactory) -> QgisProcess:
    """qgis_process with only the zip's plugin, unpacked into the profile's plugin folder."""
    workdir = tmp_path_factory.mktemp("installed")
    plugins = profile_plugins_dir(workdir / "profile")
    plugins.mkdir(parents=True)
    with zipfile.ZipFile(plugin_zip) as archive:
        archive.extractall(plugins)
    return make_qgis_process(workdir, None)


def test_zip_is_named_after_the_metadata_version(plugin_zip: Path) -> None:
    version = next(
        line.split("=", 1)[1].strip()
        for line in (ROOT / "metadata.txt").read_text(encoding="utf-8").splitlines()
        if line.startswith("version=")
    )
    assert plugin_zip.name == f"bsptriangulate-{version}.zip"


def test_zip_holds_one_plugin_folder_with_every_runtime_module_and_nothing_else(
    plugin_zip: Path,
) -> None:
    names = set(zipfile.ZipFile(plugin_zip).namelist())
    assert {name.split("/")[0] for name in names} == {PLUGIN_PACKAGE}
    inside = {name.split("/", 1)[1] for name in names}
    assert not {part for name in inside for part in name.split("/")} & NOT_IN_ZIP
    assert not [name for name in inside if name.endswith((".pyc", ".zip", ".model3"))]
    sources = {
        path.relative_to(ROOT).as_posix()
        for folder in ("bsp_triangulate", "processing_provider", "icons")
        for path in (ROOT / folder).rglob("*")
        if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc"
    }
    required = {"__init__.py", "plugin.py", "metadata.txt", "LICENSE", "icons/provider.svg"}
    assert sources | required <= inside
    assert "processing_provider/triangulate_algorithm.py" in inside


def test_zip_passes_the_plugin_repository_upload_checks(plugin_zip: Path) -> None:
    assert package_script().upload_problems(plugin_zip) == []
    assert plugin_zip.stat().st_size < 2_000_000


def rewritten(plugin_zip: Path, target: Path, *, drop=(), add=None, metadata=None) -> Path:
    """A copy of ``plugin_zip`` without the names in ``drop``, with ``add`` ({name: bytes}), and
    metadata.txt's lines passed through ``metadata``."""
    with zipfile.ZipFile(plugin_zip) as source, zipfile.ZipFile(target, "w") as copy:
        for name in source.namelist():
            data = source.read(name)
            if name.endswith("/metadata.txt") and metadata:
                data = "\n".join(metadata(data.decode().splitlines())).encode()
            if name.removeprefix(f"{PLUGIN_PACKAGE}/") not in drop:
                copy.writestr(name, data)
        for name, data in (add or {}).items():
            copy.writestr(name, data)
    return target


def with_key(key: str, value: str | None):
    """A metadata.txt edit: ``key`` set to ``value`` (None: removed)."""

    def edit(lines: list[str]) -> list[str]:
        kept = [line for line in lines if not line.startswith(f"{key}=")]
        return kept if value is None else [*kept, f"{key}={value}"]

    return edit


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ({"add": {f"{PLUGIN_PACKAGE}/plugin.pyc": b"\0"}}, "compiled file"),
        ({"add": {f"{PLUGIN_PACKAGE}/__pycache__/x.py": b""}}, "forbidden folder"),
        ({"add": {f"{PLUGIN_PACKAGE}/.hidden": b""}}, "hidden file"),
        ({"add": {"other/__init__.py": b""}}, "not one top folder"),
        ({"drop": {"LICENSE"}}, "no LICENSE"),
        ({"drop": {"icons/provider.svg"}}, "icon"),
        ({"metadata": with_key("email", None)}, "no email"),
        ({"metadata": with_key("author", "A/B")}, "author has a slash"),
        ({"metadata": with_key("qgisMaximumVersion", "4")}, "qgisMaximumVersion='4' malformed"),
        ({"metadata": with_key("tracker", "bugs")}, "tracker='bugs' malformed"),
        ({"metadata": with_key("about", "100 %")}, "metadata.txt: '%' must be followed"),
    ],
    ids=lambda value: value if isinstance(value, str) else None,
)
def test_upload_checks_find_what_the_plugin_repository_refuses(
    plugin_zip: Path, tmp_path: Path, change: dict, problem: str
) -> None:
    broken = rewritten(plugin_zip, tmp_path / "broken.zip", **change)
    problems = package_script().upload_problems(broken)
    assert any(problem in line for line in problems), problems


@pytest.mark.qgis_process
def test_installed_zip_triangulates_a_square_with_a_hole_and_an_l_shape(
    installed: QgisProcess, tmp_path: Path
) -> None:
    source = write_geojson(
        tmp_path / "polygons.geojson", [[ring(SQUARE), ring(HOLE)], [ring(L_SHAPE)]], 32733
    )
    mesh_path = tmp_path / "mesh.2dm"
    triangles_path = tmp_path / "triangles.gpkg"
    answer = installed.run_json(
        "run",
        "bsptriangulate:triangulate",
        "--",
        f"INPUT={source}",
        f"OUTPUT_MESH={mesh_path}",
        f"OUTPUT_TRIANGLES={triangles_path}",
    )
    results = answer["results"]
    assert (
        results["FEATURE_COUNT"],
        results["TRIANGLE_COUNT"],
        results["FAILED_COUNT"],
        results["EMPTY_COUNT"],
    ) == (2, TRIANGLES, 0, 0)

    vertices, faces = read_mesh(mesh_path)
    assert len(faces) == TRIANGLES
    expected_xy = {(X0 + x, Y0 + y) for x, y in SQUARE + HOLE + L_SHAPE}
    assert {(x, y) for x, y, _ in vertices} == expected_xy

    layer = QgsVectorLayer(str(triangles_path), "triangles", "ogr")
    assert layer.isValid()
    assert layer.featureCount() == TRIANGLES
    assert sum(f.geometry().area() for f in layer.getFeatures()) == pytest.approx(AREA)
