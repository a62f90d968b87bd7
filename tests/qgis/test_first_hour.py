"""What a new user meets in the first hour: geographic layers with a DEM, wrong inputs and
parameters refused before any work, progress that moves, failures summarised."""

from __future__ import annotations

import csv
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from qgis.core import (
    QgsDistanceArea,
    QgsProcessingException,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)

from tests import model_checks
from tests.conftest import SHARED_DATA
from tests.qgis.helpers import (
    DEM_POLYGON,
    RecordingFeedback,
    corners,
    plane,
    polygon_layer,
    run,
    triangle_rows,
    utm_wkt,
    write_plane_dem,
)

SWELLENDAM = SHARED_DATA / "swellendam"
BUILDINGS = f"{SWELLENDAM / 'training_data.gpkg'}|layername=buildings"
SRTM = str(SWELLENDAM / "srtm_41_19.tif")

pytestmark = pytest.mark.usefixtures("provider")
gltf_validator = model_checks.gltf_validator  # the session fixture, used by name


class ProgressFeedback(RecordingFeedback):
    """Records every progress report with its time."""

    def __init__(self) -> None:
        super().__init__()
        self.reports: list[tuple[float, float]] = []
        self.progressChanged.connect(lambda value: self.reports.append((time.monotonic(), value)))


def areas_by_feature(rows: list, field: str | None = None) -> dict[int, float]:
    """Per source feature: its triangles' planar areas in layer units, or a field's sum."""
    total: dict[int, float] = defaultdict(float)
    for row in rows:
        total[row["feature_id"]] += row[field] if field else row.geometry().area()
    return total


@pytest.mark.parametrize("interpolation", [0, 1], ids=["bilinear", "nearest"])
def test_geographic_buildings_on_the_utm_dem_all_triangulate_and_keep_their_areas(
    interpolation: int,
) -> None:
    layer = QgsVectorLayer(BUILDINGS, "buildings", "ogr")
    assert layer.isValid() and layer.crs().isGeographic()
    feedback = RecordingFeedback()
    result = run(
        {"INPUT": layer, "DEM": SRTM, "DEM_INTERPOLATION": interpolation, "APEX_RULE": 1},
        feedback,
    )
    assert result["FAILED_COUNT"] == 0, feedback.errors[:5]
    assert result["FEATURE_COUNT"] == layer.featureCount() == 4708
    rows = triangle_rows(result)
    sums = areas_by_feature(rows)
    metres = areas_by_feature(rows, "area_2d")
    ellipsoidal = QgsDistanceArea()
    ellipsoidal.setSourceCrs(layer.crs(), QgsProject.instance().transformContext())
    ellipsoidal.setEllipsoid("EPSG:7030")
    for feature in layer.getFeatures():
        assert sums[feature.id()] == pytest.approx(feature.geometry().area(), rel=1e-9)
        square_metres = ellipsoidal.measureArea(feature.geometry())
        assert metres[feature.id()] == pytest.approx(square_metres, rel=2e-3)
    # z from the DEM (metres) and x, y in metres for the metrics: the slopes of the terrain
    # (slivers of a footprint can still be steep)
    slopes = sorted(row["slope"] for row in rows if row["slope"] == row["slope"])
    assert slopes[len(slopes) // 2] < 30.0
    assert all(50.0 < z < 1700.0 for row in rows[:500] for z in corners(row)[:, 2])


def test_geographic_layer_with_its_own_z_is_triangulated_in_xy_and_says_so() -> None:
    ring = "20.43 -34.03 99, 20.43012 -34.03 101, 20.43012 -34.0299 103.5, 20.43006 -34.02995 100"
    wkt = f"POLYGON Z(({ring}, 20.43 -34.0299 102, 20.43 -34.03 99))"
    layer = polygon_layer([wkt], "PolygonZ", crs="EPSG:4326")
    messages: list[str] = []
    feedback = RecordingFeedback()
    feedback.pushInfo = messages.append  # type: ignore[method-assign]
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 1}, feedback)
    assert result["FAILED_COUNT"] == 0 and result["TRIANGLE_COUNT"] == 3
    assert sum("triangulated in XY" in message for message in messages) == 1


@pytest.mark.parametrize(
    ("geometry", "wkt"),
    [("Point", "POINT(1 2)"), ("LineString", "LINESTRING(0 0, 10 10)")],
)
def test_point_and_line_layers_are_refused_before_running(geometry: str, wkt: str) -> None:
    layer = polygon_layer([wkt], geometry)
    with pytest.raises(QgsProcessingException, match="polygon layer"):
        run({"INPUT": layer})


def test_mesh_in_a_folder_that_does_not_exist_is_written_there(tmp_path: Path) -> None:
    path = tmp_path / "new" / "deeper" / "mesh.ply"
    result = run({"INPUT": polygon_layer([utm_wkt(DEM_POLYGON)]), "OUTPUT_MESH": str(path)})
    assert result["OUTPUT_MESH"] == str(path) and path.stat().st_size > 0


def test_dem_that_does_not_overlap_the_layer_is_refused_before_running(tmp_path: Path) -> None:
    dem = write_plane_dem(tmp_path / "plane.tif")
    far = polygon_layer(["POLYGON((0 0, 10 0, 10 10, 0 0))"])  # UTM, thousands of km away
    with pytest.raises(QgsProcessingException, match="does not overlap"):
        run({"INPUT": far, "ELEVATION_SOURCE": 3, "DEM": str(dem)})


def test_dem_given_with_the_default_source_is_used(tmp_path: Path) -> None:
    dem = write_plane_dem(tmp_path / "plane.tif")
    result = run({"INPUT": polygon_layer([utm_wkt(DEM_POLYGON)]), "DEM": str(dem)})
    points = np.concatenate([corners(row) for row in triangle_rows(result)])
    np.testing.assert_allclose(points[:, 2], plane(points[:, 0], points[:, 1]), atol=1e-6)


def test_dem_given_with_geometry_z_as_the_source_is_refused(tmp_path: Path) -> None:
    dem = write_plane_dem(tmp_path / "plane.tif")
    layer = polygon_layer([utm_wkt(DEM_POLYGON)])
    with pytest.raises(QgsProcessingException, match="DEM is given"):
        run({"INPUT": layer, "ELEVATION_SOURCE": 1, "DEM": str(dem)})


def test_dem_covering_part_of_the_layer_warns_once_with_the_count(tmp_path: Path) -> None:
    dem = write_plane_dem(tmp_path / "plane.tif")
    inside = utm_wkt(DEM_POLYGON)
    across = utm_wkt([(430, 310), (4520, 540), (99_000, 4260)])
    feedback = RecordingFeedback()
    result = run({"INPUT": polygon_layer([inside, across, across]), "DEM": str(dem)}, feedback)
    assert result["FAILED_COUNT"] == 0
    outside = [w for w in feedback.warnings if "outside the DEM" in w]
    assert len(outside) == 1 and outside[0].startswith("2 feature(s)")


def test_many_failures_of_one_kind_are_summarised_and_listed_in_the_report(tmp_path: Path):
    bow_tie = "POLYGON((0 0, 10 10, 10 0, 0 10, 0 0))"
    layer = polygon_layer([bow_tie] * 30 + [utm_wkt(DEM_POLYGON)])
    feedback = RecordingFeedback()
    report = tmp_path / "failures.csv"
    result = run({"INPUT": layer, "INVALID_POLYGONS": 1, "OUTPUT_REPORT": str(report)}, feedback)
    assert result["FAILED_COUNT"] == 30
    listed = [e for e in feedback.errors if e.startswith("Feature ")]
    assert len(listed) == 10 and len(set(listed)) == 10
    assert sum("20 more feature(s)" in e for e in feedback.errors) == 1
    with report.open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 30 and {row["fid"] for row in rows} == {str(i) for i in range(1, 31)}


def test_progress_moves_forward_in_small_steps_over_a_real_layer() -> None:
    layer = QgsVectorLayer(str(SWELLENDAM / "farms_33S.shp"), "farms", "ogr")
    feedback = ProgressFeedback()
    run({"INPUT": layer, "DEM": SRTM}, feedback)
    values = [value for _when, value in feedback.reports]
    assert values == sorted(values) and values[-1] == 100
    assert len(values) >= 10
    steps = [b - a for a, b in zip(values, values[1:])]
    assert max(steps) <= 30.0  # no stage jumps from 0 to the end at once


def test_cancel_during_the_engine_stage_stops_the_run_at_once() -> None:
    layer = QgsVectorLayer(str(SWELLENDAM / "farms_33S.shp"), "farms", "ogr")
    feedback = ProgressFeedback()

    def cancel_in_the_engine(value: float) -> None:
        if value > 30:
            feedback.cancel()

    feedback.progressChanged.connect(cancel_in_the_engine)
    start = time.monotonic()
    with pytest.raises(QgsProcessingException, match="Cancelled"):
        run({"INPUT": layer, "DEM": SRTM, "APEX_RULE": 1, "WORKERS": 1}, feedback)
    cancelled_at = next(when for when, value in feedback.reports if value > 30)
    assert time.monotonic() - cancelled_at < 5.0
    assert time.monotonic() - start > 0


def test_progress_of_a_plain_feedback_is_accepted() -> None:
    # the console's processing.run passes a plain QgsProcessingFeedback
    result = run({"INPUT": polygon_layer([utm_wkt(DEM_POLYGON)])}, QgsProcessingFeedback())
    assert result["TRIANGLE_COUNT"] == 3


@pytest.mark.parametrize("extension", ["glb", "gltf", "obj"])
def test_triangulate_writes_3d_models_that_validate_and_read_back(
    tmp_path: Path, extension: str, gltf_validator
) -> None:
    dem = write_plane_dem(tmp_path / "plane.tif")
    path = tmp_path / f"model.{extension}"
    layer = polygon_layer([utm_wkt(DEM_POLYGON), utm_wkt([(x + 10, y) for x, y in DEM_POLYGON])])
    result = run({"INPUT": layer, "DEM": str(dem), "OUTPUT_MESH": str(path)})
    assert result["OUTPUT_MESH"] == str(path) and result["TRIANGLE_COUNT"] == 6
    if extension == "obj":
        assert "UTM zone 33S" in path.with_suffix(".prj").read_text(encoding="utf-8")
    else:
        model_checks.assert_valid_gltf(gltf_validator, path)
    mesh = model_checks.trimesh_read(path)
    assert len(mesh.faces) == 6


def test_apex_rule_delaunay_gives_the_constrained_delaunay_triangles() -> None:
    # a long thin pentagon: rule first fans from one corner, delaunay does not
    wkt = utm_wkt([(0, 0), (400, 0), (800, 10), (400, 20), (0, 20)])
    rows = {
        rule: triangle_rows(run({"INPUT": polygon_layer([wkt]), "APEX_RULE": rule}))
        for rule in (0, 2)
    }
    assert len(rows[0]) == len(rows[2]) == 3
    smallest = {rule: min(row["min_angle"] for row in found) for rule, found in rows.items()}
    assert smallest[2] >= smallest[0]
