"""The plugin from the work tree under qgis_process: listed, documented, and run on a tilted
PolygonZ layer with the geometry's own Z and a PLY mesh."""

from __future__ import annotations

from pathlib import Path

import pytest
from qgis.core import QgsVectorLayer

from tests.conftest import (
    TRIANGULATE_OUTPUTS,
    TRIANGULATE_PARAMETERS,
    QgisProcess,
    qgis_process_binary,
    read_mesh,
    write_geojson,
)

pytestmark = pytest.mark.qgis_process

# A plane z = 100 + 0.5 x + 0.25 y, so every output vertex can be checked against it.
X0, Y0 = 500_000.0, 6_000_000.0


def on_plane(x: float, y: float) -> tuple[float, float, float]:
    return (X0 + x, Y0 + y, 100.0 + 0.5 * x + 0.25 * y)


def closed(points: list[tuple[float, float]]) -> list[tuple[float, float, float]]:
    ring = [on_plane(x, y) for x, y in points]
    return [*ring, ring[0]]


def test_qgis_process_binary_is_the_working_one_of_debian_12() -> None:
    binary = qgis_process_binary()
    assert binary is not None
    assert Path(binary).name in {"qgis_process.bin", "qgis_process"}
    if Path("/usr/bin/qgis_process.bin").exists():
        assert binary.endswith("qgis_process.bin")


def test_enabled_plugin_lists_provider_bsptriangulate_with_triangulate(
    qgis_process_list: dict,
) -> None:
    providers = qgis_process_list["providers"]
    assert "bsptriangulate" in providers
    assert "bsptriangulate:triangulate" in providers["bsptriangulate"]["algorithms"]


def test_help_of_triangulate_lists_the_documented_parameters(qgis_process: QgisProcess) -> None:
    answer = qgis_process.run_json("help", "bsptriangulate:triangulate")
    assert set(answer["parameters"]) >= TRIANGULATE_PARAMETERS
    assert set(answer["outputs"]) >= TRIANGULATE_OUTPUTS
    assert answer["algorithm_details"]["id"] == "bsptriangulate:triangulate"


def test_run_on_a_tilted_concave_polygonz_keeps_geometry_z_in_a_ply_mesh(
    qgis_process: QgisProcess, tmp_path: Path
) -> None:
    # A U shape (8 vertices, concave) with a triangular hole in its base: 8 + 3 + 2 - 2 triangles.
    u_shape = [(0, 0), (30, 0), (30, 20), (20, 20), (20, 8), (10, 8), (10, 20), (0, 20)]
    hole = [(12, 2), (18, 2), (15, 5)]
    source = write_geojson(tmp_path / "u.geojson", [[closed(u_shape), closed(hole)]], 32733)
    mesh_path = tmp_path / "u.ply"
    triangles_path = tmp_path / "u_triangles.gpkg"
    results = qgis_process.run_json(
        "run",
        "bsptriangulate:triangulate",
        "--",
        f"INPUT={source}",
        "ELEVATION_SOURCE=1",
        f"OUTPUT_MESH={mesh_path}",
        f"OUTPUT_TRIANGLES={triangles_path}",
    )["results"]
    assert (results["FEATURE_COUNT"], results["TRIANGLE_COUNT"]) == (1, 11)
    assert (results["FAILED_COUNT"], results["EMPTY_COUNT"]) == (0, 0)

    vertices, faces = read_mesh(mesh_path)
    assert len(faces) == 11
    expected = {on_plane(x, y) for x, y in u_shape + hole}
    assert {(x, y) for x, y, _ in vertices} == {(x, y) for x, y, _ in expected}
    for x, y, z in vertices:
        assert z == pytest.approx(100.0 + 0.5 * (x - X0) + 0.25 * (y - Y0), abs=1e-6)

    layer = QgsVectorLayer(str(triangles_path), "triangles", "ogr")
    area = 30 * 20 - 10 * 12 - 6 * 3 / 2
    assert sum(f.geometry().area() for f in layer.getFeatures()) == pytest.approx(area)


def test_input_with_a_fid_attribute_gives_a_geopackage_with_one_row_per_triangle(
    qgis_process: QgisProcess, tmp_path: Path
) -> None:
    # Layers read from a GeoPackage carry a "fid" field; a GeoPackage output uses "fid" as its
    # primary key, so the triangles of one polygon must not all copy the polygon's fid into it.
    square = [(0, 0), (10, 0), (10, 10), (0, 10)]
    source = write_geojson(
        tmp_path / "fid.geojson",
        [[closed(square)], [closed([(20, 0), (30, 0), (25, 9)])]],
        32733,
        id_field="fid",
    )
    triangles_path = tmp_path / "fid_triangles.gpkg"
    results = qgis_process.run_json(
        "run",
        "bsptriangulate:triangulate",
        "--",
        f"INPUT={source}",
        f"OUTPUT_MESH={tmp_path / 'fid.2dm'}",
        f"OUTPUT_TRIANGLES={triangles_path}",
    )["results"]
    assert results["TRIANGLE_COUNT"] == 3
    layer = QgsVectorLayer(str(triangles_path), "triangles", "ogr")
    assert layer.featureCount() == 3


def test_leaving_out_the_triangles_output_gives_a_mesh_only_run(
    qgis_process: QgisProcess, tmp_path: Path
) -> None:
    square_with_hole = [
        closed([(0, 0), (10, 0), (10, 10), (0, 10)]),
        closed([(3, 3), (7, 3), (5, 6)]),
    ]
    source = write_geojson(tmp_path / "square.geojson", [square_with_hole], 32733)
    mesh_path = tmp_path / "square.ply"
    results = qgis_process.run_json(
        "run",
        "bsptriangulate:triangulate",
        "--",
        f"INPUT={source}",
        "ELEVATION_SOURCE=1",
        f"OUTPUT_MESH={mesh_path}",
    )["results"]
    assert "OUTPUT_TRIANGLES" not in results
    assert (results["FEATURE_COUNT"], results["TRIANGLE_COUNT"]) == (1, 4 + 3 + 2 - 2)
    _vertices, faces = read_mesh(mesh_path)
    assert len(faces) == 7
    assert sorted(path.name for path in tmp_path.iterdir()) == [
        "square.geojson",
        "square.ply",
        "square.qml",
    ]


def test_worker_processes_started_by_qgis_process_write_the_mesh_of_one_process(
    qgis_process: QgisProcess, tmp_path: Path
) -> None:
    # one polygon more than an engine call takes: two calls, so the workers start (under
    # qgis_process, Python is embedded and sys.executable is not its interpreter)
    square_with_hole = [
        closed([(0, 0), (10, 0), (10, 10), (0, 10)]),
        closed([(3, 3), (7, 3), (5, 6)]),
    ]
    polygons = [
        [[(x + 20.0 * (i % 100), y + 20.0 * (i // 100), z) for x, y, z in ring] for ring in rings]
        for i, rings in enumerate([square_with_hole] * 10_001)
    ]
    source = write_geojson(tmp_path / "squares.geojson", polygons, 32733)
    meshes, logs = [], []
    for workers in (1, 2):
        mesh_path = tmp_path / f"squares_{workers}.2dm"
        run = qgis_process.run(
            "run", "bsptriangulate:triangulate", "--", f"INPUT={source}",
            "ELEVATION_SOURCE=1", f"WORKERS={workers}", f"OUTPUT_MESH={mesh_path}",
        )  # fmt: skip
        meshes.append(mesh_path.read_bytes())
        logs.append(run.stdout + run.stderr)
    assert "worker processes" not in logs[0]
    assert "2 of 2 engine calls ran in 2 worker processes" in logs[1]
    assert "stopped" not in logs[1]
    assert meshes[0] == meshes[1]
    _vertices, faces = read_mesh(tmp_path / "squares_2.2dm")
    assert len(faces) == 7 * 10_001
