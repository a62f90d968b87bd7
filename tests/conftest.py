"""Shared test set-up: offscreen Qt, a throwaway QGIS profile, the plugin as a package, and a
qgis_process runner that loads the plugin from a throwaway plugin folder."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = ROOT.parent / "shared" / "data"
PLUGIN_PACKAGE = "bsptriangulate"
QGIS_PROCESS_TIMEOUT_S = 600
# The triangulate algorithm's interface, as the README and the models use it.
TRIANGULATE_ID = "bsptriangulate:triangulate"
TRIANGULATE_PARAMETERS = frozenset(
    {
        "INPUT",
        "ELEVATION_SOURCE",
        "Z_EXPRESSION",
        "DEM",
        "DEM_BAND",
        "APEX_RULE",
        "PLANAR_TOLERANCE",
        "INVALID_POLYGONS",
        "WORKERS",
        "OUTPUT_MESH",
        "OUTPUT_TRIANGLES",
        "OUTPUT_TREE",
        "MAX_VERTICAL_ERROR",
        "MAX_POINTS",
        "INPUT_POINTS",
        "POINTS_Z_FIELD",
    }
)
TRIANGULATE_OUTPUTS = frozenset(
    {"FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT", "EMPTY_COUNT", "POINTS_ADDED"}
)

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("QGIS_CUSTOM_CONFIG_PATH", tempfile.mkdtemp(prefix="bsptri-qgis-profile-"))


def load_plugin_package():
    """Import the repository root as the plugin package ``bsptriangulate`` (as QGIS would)."""
    if PLUGIN_PACKAGE in sys.modules:
        return sys.modules[PLUGIN_PACKAGE]
    spec = importlib.util.spec_from_file_location(
        PLUGIN_PACKAGE, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[PLUGIN_PACKAGE] = module
    spec.loader.exec_module(module)
    return module


def qgis_process_binary() -> str | None:
    """``qgis_process.bin`` where it exists (Debian 12's wrapper script is broken), else
    ``qgis_process``; None when QGIS has neither."""
    return shutil.which("qgis_process.bin") or shutil.which("qgis_process")


def json_from_output(stdout: str) -> dict:
    """The JSON document in qgis_process's ``--json`` output (it may print other lines first)."""
    start = stdout.find("{")
    if start < 0:
        raise ValueError(f"no JSON in qgis_process output: {stdout[-2000:]!r}")
    return json.loads(stdout[start:])


@dataclass
class QgisProcess:
    """Runs qgis_process with its own profile and a plugin folder that holds ``bsptriangulate``."""

    binary: str
    profile: Path
    plugin_dir: Path

    def env(self) -> dict[str, str]:
        env = dict(os.environ)
        # pytest-qgis 3+ points this at its own settings folder; keep the profile apart.
        env.pop("QGIS_OPTIONS_PATH", None)
        env.update(
            QT_QPA_PLATFORM="offscreen",
            QGIS_CUSTOM_CONFIG_PATH=str(self.profile),
            QGIS_PLUGINPATH=str(self.plugin_dir),
        )
        return env

    def run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        """Run ``qgis_process ARGS``; on failure show its output in the assertion."""
        proc = subprocess.run(
            [self.binary, *args],
            env=self.env(),
            capture_output=True,
            text=True,
            timeout=QGIS_PROCESS_TIMEOUT_S,
            stdin=subprocess.DEVNULL,
        )
        if check:
            assert proc.returncode == 0, (
                f"qgis_process {' '.join(args)} exited {proc.returncode}\n"
                f"stdout:\n{proc.stdout[-4000:]}\nstderr:\n{proc.stderr[-4000:]}"
            )
        return proc

    def run_json(self, *args: str) -> dict:
        """Run ``qgis_process --json ARGS`` and return its parsed JSON answer."""
        return json_from_output(self.run("--json", *args).stdout)


def make_qgis_process(workdir: Path, plugin_source: Path | None) -> QgisProcess:
    """A qgis_process runner with a profile under ``workdir`` and plugin ``bsptriangulate``
    enabled: ``plugin_source`` linked into a plugin folder on QGIS_PLUGINPATH, or, when None,
    as already installed in the profile's own ``python/plugins`` (as the plugin manager does)."""
    binary = qgis_process_binary()
    if binary is None:
        pytest.fail("neither qgis_process.bin nor qgis_process is on PATH (is QGIS installed?)")
    profile = workdir / "profile"
    plugin_dir = workdir / "plugins"
    profile.mkdir(parents=True, exist_ok=True)
    plugin_dir.mkdir(parents=True)
    if plugin_source is not None:
        (plugin_dir / PLUGIN_PACKAGE).symlink_to(plugin_source.resolve(), target_is_directory=True)
    runner = QgisProcess(binary, profile, plugin_dir)
    runner.run("plugins", "enable", PLUGIN_PACKAGE)
    return runner


def profile_plugins_dir(profile: Path) -> Path:
    """Where the plugin manager installs plugins in the default profile under ``profile``."""
    return profile / "profiles" / "default" / "python" / "plugins"


@pytest.fixture(scope="session")
def qgis_process(tmp_path_factory: pytest.TempPathFactory) -> QgisProcess:
    """qgis_process with this work tree enabled as plugin ``bsptriangulate``."""
    return make_qgis_process(tmp_path_factory.mktemp("qgis-process"), ROOT)


@pytest.fixture(scope="session")
def qgis_process_list(qgis_process: QgisProcess) -> dict:
    """``qgis_process --json list`` with the work tree's plugin, run once for the tests that
    read it (each run starts QGIS and loads every provider)."""
    return qgis_process.run_json("list")


def read_mesh(path: Path) -> tuple[list[tuple[float, float, float]], list[list[int]]]:
    """Vertices (x, y, z) and faces (vertex indices) of a mesh file, as QGIS's MDAL reads it."""
    from qgis.core import QgsMesh, QgsMeshLayer

    layer = QgsMeshLayer(str(path), path.name, "mdal")
    assert layer.isValid(), f"QGIS cannot open {path} as a mesh layer"
    mesh = QgsMesh()
    layer.dataProvider().populateMesh(mesh)
    vertices = [
        (mesh.vertex(i).x(), mesh.vertex(i).y(), mesh.vertex(i).z())
        for i in range(mesh.vertexCount())
    ]
    return vertices, [list(mesh.face(i)) for i in range(mesh.faceCount())]


def write_geojson(
    path: Path, polygons: list[list[list[tuple[float, ...]]]], epsg: int, id_field: str = "id"
) -> Path:
    """A GeoJSON file with one Polygon feature per entry (rings of (x, y[, z]) points) and an
    integer attribute ``id_field`` numbering them from 1."""
    features = [
        {
            "type": "Feature",
            "properties": {id_field: i + 1},
            "geometry": {
                "type": "Polygon",
                "coordinates": [[list(point) for point in ring] for ring in rings],
            },
        }
        for i, rings in enumerate(polygons)
    ]
    crs = {"type": "name", "properties": {"name": f"urn:ogc:def:crs:EPSG::{epsg}"}}
    document = {"type": "FeatureCollection", "crs": crs, "features": features}
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


_EXIT_STATUS: list[int] = []


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    _EXIT_STATUS.append(int(exitstatus))


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    """Leave with pytest's own status once everything is reported: tearing down QGIS's
    application objects (3D renderers, layers of many tests) at interpreter exit can crash in
    QGIS's C++ code after every test has passed, which would turn a green run red."""
    if _EXIT_STATUS and os.environ.get("BSPTRI_CLEAN_EXIT") != "1":
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT_STATUS[-1])
