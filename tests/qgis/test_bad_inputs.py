"""The bad-input matrix through bsptriangulate:triangulate, in each INVALID_POLYGONS mode.

Every run must account for every feature (FEATURE_COUNT = triangulated + FAILED_COUNT +
EMPTY_COUNT), keep the area of what it triangulates, and report failures with the feature id.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal, osr
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsDistanceArea,
    QgsGeometry,
    QgsLineString,
    QgsPointXY,
    QgsPolygon,
    QgsProcessingException,
    QgsProject,
    QgsVectorLayer,
)

from tests.qgis.helpers import (
    CELL,
    COLS,
    DEM_POLYGON,
    UTM,
    X0,
    Y0,
    A,
    B,
    RecordingFeedback,
    corners,
    plane,
    polygon_layer,
    run,
    triangle_rows,
    utm_wkt,
    write_plane_dem,
)

REPAIR, FAIL, AS_GIVEN = 0, 1, 2
SQUARE = "0 0, 10 0, 10 10, 0 10, 0 0"


pytestmark = pytest.mark.usefixtures("provider")


def outcome(layer: QgsVectorLayer, mode: int, **parameters) -> tuple[dict, list, list[str]]:
    """Run the algorithm; check the counts add up; return the result, rows and errors."""
    feedback = RecordingFeedback()
    result = run({"INPUT": layer, "INVALID_POLYGONS": mode, **parameters}, feedback)
    rows = triangle_rows(result)
    triangulated = len({row["feature_id"] for row in rows})
    assert result["FEATURE_COUNT"] == layer.featureCount()
    assert result["TRIANGLE_COUNT"] == len(rows)
    assert triangulated + result["FAILED_COUNT"] + result["EMPTY_COUNT"] == layer.featureCount()
    assert result["FAILED_COUNT"] == len(feedback.errors), feedback.errors
    return result, rows, feedback.errors


def area(rows: list) -> float:
    return sum(row["area_2d"] for row in rows)


def xy_corners(rows: list) -> set[tuple[float, float]]:
    return {(x, y) for row in rows for x, y, _z in corners(row)}


def only_fid(layer: QgsVectorLayer) -> int:
    return next(layer.getFeatures()).id()


# --- empty, degenerate --------------------------------------------------------------------------


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
def test_null_and_empty_geometries_count_as_empty_in_every_mode(mode: int):
    layer = polygon_layer([None, "POLYGON EMPTY", f"POLYGON(({SQUARE}))"])
    result, rows, _errors = outcome(layer, mode)
    assert (result["EMPTY_COUNT"], result["FAILED_COUNT"], len(rows)) == (2, 0, 2)
    assert area(rows) == pytest.approx(100.0)


DEGENERATE = {
    "two_distinct_points": "POLYGON((0 0, 5 5, 0 0, 0 0))",
    "all_points_collinear": "POLYGON((0 0, 1 1, 2 2, 3 3, 0 0))",
}


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
@pytest.mark.parametrize("name", sorted(DEGENERATE))
def test_degenerate_ring_gives_no_triangles_and_is_empty_or_failed_with_its_id(
    name: str, mode: int
):
    layer = polygon_layer([DEGENERATE[name]])
    result, rows, errors = outcome(layer, mode)
    assert rows == []
    if mode == AS_GIVEN:
        assert result["EMPTY_COUNT"] == 1  # the engine's degenerate case
    else:
        # GEOS calls it invalid: fail names the feature; repair leaves nothing or fails it
        assert result["EMPTY_COUNT"] + result["FAILED_COUNT"] == 1
        assert all(e.startswith(f"Feature {only_fid(layer)}:") for e in errors)
    if mode == FAIL:
        assert result["FAILED_COUNT"] == 1


# --- valid or repairable rows with a known area --------------------------------------------------

AREAS = {
    "duplicate_consecutive_points": ("POLYGON((0 0, 0 0, 10 0, 10 0, 10 10, 0 10, 0 0))", 100.0),
    "island_touching_outer_ring_at_a_vertex": (f"POLYGON(({SQUARE}),(0 0, 3 1, 1 3, 0 0))", 96.0),
    "islands_touching_each_other_at_a_vertex": (
        f"POLYGON(({SQUARE}),(2 2, 4 2, 4 4, 2 2),(4 4, 6 4, 6 6, 4 4))",
        96.0,
    ),
    "coordinates_around_1e15": (
        "POLYGON((1e15 1e15, 1000000000000003 1e15, 1000000000000003 1000000000000002, "
        "1000000000000001 1000000000000001, 1e15 1000000000000002, 1e15 1e15))",
        4.5,
    ),
    "polygon_of_size_1e_9": (
        "POLYGON((0 0, 3e-9 0, 3e-9 2e-9, 1e-9 1e-9, 0 2e-9, 0 0))",
        4.5e-18,
    ),
}


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
@pytest.mark.parametrize("name", sorted(AREAS))
def test_valid_polygon_is_tiled_over_its_area_in_every_mode(name: str, mode: int):
    wkt, expected = AREAS[name]
    result, rows, errors = outcome(polygon_layer([wkt]), mode)
    assert (result["FAILED_COUNT"], result["EMPTY_COUNT"], errors) == (0, 0, [])
    assert area(rows) == pytest.approx(expected, rel=1e-9)
    geometry = QgsGeometry.fromWkt(wkt)  # kept alive while its vertices are read
    inputs = {(p.x(), p.y()) for p in geometry.vertices()}
    assert xy_corners(rows) <= inputs


# Invalid for GEOS. repair: QGIS makeValid's area; fail: the feature fails with its id;
# as given: the engine's own handling (area of the rings' valid interpretation).
INVALID = {
    "outward_zero_width_spike": ("POLYGON((0 0, 10 0, 10 10, 5 10, 5 15, 5 10, 0 10, 0 0))", 100),
    "inward_zero_width_spike": ("POLYGON((0 0, 10 0, 10 10, 5 10, 5 5, 5 10, 0 10, 0 0))", 100),
    "bow_tie": ("POLYGON((0 0, 10 10, 10 0, 0 10, 0 0))", 50),
    "bow_tie_unequal_lobes": ("POLYGON((0 0, 10 10, 10 0, 0 6, 0 0))", 42.5),
    "island_outside_the_outer_ring": (f"POLYGON(({SQUARE}),(20 0, 22 0, 22 2, 20 0))", 102),
    "island_crossing_the_outer_ring": (f"POLYGON(({SQUARE}),(8 2, 12 2, 12 4, 8 4, 8 2))", 96),
    "island_nested_in_another_island": (
        f"POLYGON(({SQUARE}),(1 1, 9 1, 9 9, 1 9, 1 1),(3 3, 5 3, 5 5, 3 5, 3 3))",
        36,
    ),
    "island_along_an_outer_edge": (f"POLYGON(({SQUARE}),(2 0, 4 0, 3 2, 2 0))", 98),
    "islands_sharing_an_edge": (
        f"POLYGON(({SQUARE}),(2 2, 4 2, 4 4, 2 4, 2 2),(4 2, 6 2, 6 4, 4 4, 4 2))",
        92,
    ),
}


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_polygon_with_fail_policy_fails_with_its_feature_id(name: str):
    wkt, _ = INVALID[name]
    layer = polygon_layer([wkt, "POLYGON((20 0, 24 0, 24 3, 20 0))"])
    result, rows, errors = outcome(layer, FAIL)
    fid = only_fid(layer)
    assert result["FAILED_COUNT"] == 1 and len(rows) == 1
    assert errors[0].startswith(f"Feature {fid}: invalid polygon")


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_polygon_repaired_by_default_keeps_the_repaired_area(name: str):
    wkt, _ = INVALID[name]
    layer = polygon_layer([wkt])
    result, rows, errors = outcome(layer, REPAIR)
    repaired = QgsGeometry.fromWkt(wkt).makeValid()
    assert (result["FAILED_COUNT"], errors) == (0, [])
    assert area(rows) == pytest.approx(repaired.area(), rel=1e-9)
    union = QgsGeometry.unaryUnion([row.geometry() for row in rows])
    assert union.symDifference(repaired).area() == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_polygon_as_given_covers_the_valid_area_of_its_rings(name: str):
    wkt, expected = INVALID[name]
    result, rows, errors = outcome(polygon_layer([wkt]), AS_GIVEN)
    assert (result["FAILED_COUNT"], errors) == (0, [])
    assert area(rows) == pytest.approx(expected, rel=1e-9)


def test_island_identical_to_the_outer_ring_leaves_nothing_to_triangulate():
    wkt = f"POLYGON(({SQUARE}),({SQUARE}))"
    result, rows, _errors = outcome(polygon_layer([wkt]), AS_GIVEN)
    assert rows == [] and result["EMPTY_COUNT"] == 1
    result, rows, _errors = outcome(polygon_layer([wkt]), REPAIR)
    assert area(rows) == pytest.approx(QgsGeometry.fromWkt(wkt).makeValid().area())
    result, rows, errors = outcome(polygon_layer([wkt]), FAIL)
    assert result["FAILED_COUNT"] == 1 and "invalid polygon" in errors[0]


# --- non-finite coordinates ---------------------------------------------------------------------


def non_finite_layer(value: float) -> QgsVectorLayer:
    """A square with one non-finite x, then a valid triangle."""
    layer = polygon_layer([None, "POLYGON((20 0, 24 0, 24 3, 20 0))"])
    xs, ys = [0.0, value, 10.0, 0.0, 0.0], [0.0, 0.0, 10.0, 10.0, 0.0]
    polygon = QgsPolygon(QgsLineString(xs, ys))
    fid = only_fid(layer)
    assert layer.dataProvider().changeGeometryValues({fid: QgsGeometry(polygon)})
    return layer


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
@pytest.mark.parametrize("value", [math.nan, math.inf], ids=["nan", "inf"])
def test_non_finite_coordinate_fails_only_that_feature_with_its_id(value: float, mode: int):
    layer = non_finite_layer(value)
    result, rows, errors = outcome(layer, mode)
    assert len(rows) == 1 and result["FAILED_COUNT"] == 1
    assert errors[0].startswith(f"Feature {only_fid(layer)}:")


# --- 3D, multipolygons, curves, geographic CRS --------------------------------------------------


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
def test_vertical_wall_is_triangulated_in_its_own_plane_with_its_z(mode: int):
    wall = "POLYGON Z((0 0 0, 10 0 0, 10 0 5, 5 0 3, 0 0 5, 0 0 0))"
    result, rows, errors = outcome(polygon_layer([wall], "PolygonZ"), mode, ELEVATION_SOURCE=1)
    assert (result["FAILED_COUNT"], errors) == (0, [])
    assert len(rows) == 3
    given = {(0, 0, 0), (10, 0, 0), (10, 0, 5), (5, 0, 3), (0, 0, 5)}
    assert {tuple(c) for row in rows for c in corners(row)} <= given
    assert sum(row["area_3d"] for row in rows) == pytest.approx(40.0)


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
def test_multipolygon_parts_touching_at_a_vertex_or_an_edge_are_all_tiled(mode: int):
    vertex = "MULTIPOLYGON(((0 0, 10 0, 10 10, 0 10, 0 0)), ((10 10, 15 15, 10 15, 10 10)))"
    edge = "MULTIPOLYGON(((0 0, 10 0, 10 10, 0 10, 0 0)), ((10 0, 20 0, 20 10, 10 10, 10 0)))"
    layer = polygon_layer([vertex, edge], "MultiPolygon")
    result, rows, errors = outcome(layer, mode)
    fids = [f.id() for f in layer.getFeatures()]
    by_feature = {fid: [r for r in rows if r["feature_id"] == fid] for fid in fids}
    if mode == FAIL:
        # parts sharing an edge make an invalid multipolygon for GEOS
        assert result["FAILED_COUNT"] == 1 and errors[0].startswith(f"Feature {fids[1]}:")
    else:
        assert result["FAILED_COUNT"] == 0
        assert area(by_feature[fids[1]]) == pytest.approx(200.0)
    assert area(by_feature[fids[0]]) == pytest.approx(112.5)


@pytest.mark.parametrize("mode", [REPAIR, FAIL, AS_GIVEN])
def test_curve_polygon_is_segmentized_and_its_area_approximated_from_inside(mode: int):
    wkt = "CURVEPOLYGON(CIRCULARSTRING(0 0, 10 10, 20 0, 10 -10, 0 0))"
    result, rows, errors = outcome(polygon_layer([wkt], "CurvePolygon"), mode)
    assert (result["FAILED_COUNT"], errors) == (0, [])
    assert len(rows) > 20
    circle = math.pi * 100
    assert 0.99 * circle < area(rows) < circle
    for x, y in xy_corners(rows):
        assert math.hypot(x - 10, y) == pytest.approx(10.0, abs=1e-6)


def test_layer_in_geographic_crs_is_triangulated_in_degrees_with_metrics_in_metres():
    wkt = "POLYGON((20.1 -34.0, 20.3 -34.0, 20.3 -33.9, 20.2 -33.95, 20.1 -33.9, 20.1 -34.0))"
    layer = polygon_layer([wkt], crs="EPSG:4326")
    result, rows, errors = outcome(layer, REPAIR)
    assert len(rows) == 3 and errors == []
    degrees = sum(row.geometry().area() for row in rows)
    assert degrees == pytest.approx(QgsGeometry.fromWkt(wkt).area(), rel=1e-9)
    ellipsoidal = QgsDistanceArea()
    ellipsoidal.setSourceCrs(layer.crs(), QgsProject.instance().transformContext())
    ellipsoidal.setEllipsoid("EPSG:7030")
    square_metres = ellipsoidal.measureArea(QgsGeometry.fromWkt(wkt))
    assert area(rows) == pytest.approx(square_metres, rel=2e-3)
    assert result["OUTPUT_TRIANGLES"].crs().authid() == "EPSG:4326"


# --- DEM rows -----------------------------------------------------------------------------------


def dem_run(
    dem: Path, points: list[tuple[float, float]], nodata_policy: int, interpolation: int = 0
) -> tuple:
    layer = polygon_layer([utm_wkt(points)])
    parameters = {
        "ELEVATION_SOURCE": 3,
        "DEM": str(dem),
        "DEM_NODATA": nodata_policy,
        "DEM_INTERPOLATION": interpolation,
    }
    return layer, *outcome(layer, REPAIR, **parameters)


def test_dem_nodata_under_several_vertices_is_filled_between_valid_neighbours(tmp_path: Path):
    # vertices 2 and 3 of DEM_POLYGON on nodata cells (rows 42, 22; cols 52, 25)
    dem = write_plane_dem(tmp_path / "holes.tif", nodata_cells=((42, 52), (22, 25)))
    layer, result, rows, errors = dem_run(dem, DEM_POLYGON, 0, interpolation=1)
    assert result["FAILED_COUNT"] == 0 and len(rows) == 3
    z = np.array([c[2] for row in rows for c in corners(row)])
    valid = [plane(X0 + x, Y0 - y) for x, y in DEM_POLYGON]
    assert np.isfinite(z).all()
    cell_step = (abs(A) + abs(B)) * CELL  # nearest cell vs the plane at the vertex
    assert min(valid) - cell_step <= z.min() and z.max() <= max(valid) + cell_step
    layer, result, rows, errors = dem_run(dem, DEM_POLYGON, 1, interpolation=1)
    assert result["FAILED_COUNT"] == 1 and "nodata" in errors[0]
    assert errors[0].startswith(f"Feature {only_fid(layer)}:")


def test_polygon_partly_outside_the_dem_fills_or_fails_the_outside_vertices(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    width = COLS * CELL
    points = [(1000, 1000), (width + 500, 1000), (width + 500, 3000), (1000, 3000)]
    layer, result, rows, errors = dem_run(dem, points, 0)
    assert result["FAILED_COUNT"] == 0 and len(rows) == 2
    for x, y, z in (c for row in rows for c in corners(row)):
        if x < X0 + width:
            assert z == pytest.approx(plane(x, y), abs=1e-6)
        else:
            assert math.isfinite(z) and z > -9999
    layer, result, rows, errors = dem_run(dem, points, 1)
    assert result["FAILED_COUNT"] == 1 and errors[0].startswith(f"Feature {only_fid(layer)}:")


@pytest.mark.parametrize("nodata_policy", [0, 1])
def test_polygon_wholly_outside_the_dem_fails_with_its_id(tmp_path: Path, nodata_policy: int):
    dem = write_plane_dem(tmp_path / "plane.tif")
    far = [(x + 100_000, y) for x, y in DEM_POLYGON]
    layer = polygon_layer([utm_wkt(DEM_POLYGON), utm_wkt(far)])
    parameters = {"ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_NODATA": nodata_policy}
    result, rows, errors = outcome(layer, REPAIR, **parameters)
    assert result["FAILED_COUNT"] == 1 and len(rows) == 3
    far_fid = max(feature.id() for feature in layer.getFeatures())
    assert errors[0].startswith(f"Feature {far_fid}:")


def test_dem_in_geographic_crs_is_sampled_at_the_reprojected_vertices(tmp_path: Path):
    # a DEM in EPSG:4326 whose value is 1000 * longitude + latitude, over a UTM 33S polygon
    path = tmp_path / "geo.tif"
    west, north, step, size = 14.0, -33.0, 0.01, 300
    lon = west + (np.arange(size) + 0.5) * step
    lat = north - (np.arange(size) + 0.5) * step
    dataset = gdal.GetDriverByName("GTiff").Create(str(path), size, size, 1, gdal.GDT_Float64)
    dataset.SetGeoTransform((west, step, 0.0, north, 0.0, -step))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    dataset.SetProjection(srs.ExportToWkt())
    dataset.GetRasterBand(1).WriteArray(1000 * lon[None, :] + lat[:, None])
    dataset = None
    # UTM 33S around 15.5 E, 34.5 S
    wkt = (
        "POLYGON((500000 6180000, 510000 6180000, 510000 6190000, 500000 6190000, 500000 6180000))"
    )
    _result, rows, errors = outcome(polygon_layer([wkt]), REPAIR, ELEVATION_SOURCE=3, DEM=str(path))
    assert errors == [] and len(rows) == 2
    to_wgs84 = QgsCoordinateTransform(
        QgsCoordinateReferenceSystem(UTM),
        QgsCoordinateReferenceSystem("EPSG:4326"),
        QgsProject.instance(),
    )
    for x, y, z in (c for row in rows for c in corners(row)):
        lonlat = to_wgs84.transform(QgsPointXY(x, y))
        assert z == pytest.approx(1000 * lonlat.x() + lonlat.y(), abs=1e-6)


# --- bad parameter values -----------------------------------------------------------------------


def test_dem_band_out_of_range_is_refused_naming_the_band(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    layer = polygon_layer([utm_wkt(DEM_POLYGON)])
    for band in (0, 3):
        with pytest.raises(QgsProcessingException, match=r"(?i)band"):
            run({"INPUT": layer, "ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_BAND": band})


def test_expression_with_a_syntax_error_is_refused_before_running():
    layer = polygon_layer([f"POLYGON(({SQUARE}))"])
    with pytest.raises(QgsProcessingException, match=r"(?i)expression"):
        run({"INPUT": layer, "ELEVATION_SOURCE": 2, "Z_EXPRESSION": '"height" * * 2'})


def test_expression_failing_at_evaluation_fails_each_feature_with_its_id():
    layer = polygon_layer([f"POLYGON(({SQUARE}))", "POLYGON((20 0, 24 0, 24 3, 20 0))"])
    expression = "to_int('not a number')"
    result, rows, errors = outcome(layer, REPAIR, ELEVATION_SOURCE=2, Z_EXPRESSION=expression)
    assert rows == [] and result["FAILED_COUNT"] == 2
    fids = sorted(f.id() for f in layer.getFeatures())
    assert sorted(int(e.split()[1].rstrip(":")) for e in errors) == fids


@pytest.mark.parametrize("name", ["out.stl", "out", "out.2dm.txt"])
def test_unknown_mesh_file_extension_is_refused(tmp_path: Path, name: str):
    layer = polygon_layer([f"POLYGON(({SQUARE}))"])
    with pytest.raises(QgsProcessingException, match=r"\.2dm or \.ply|2dm|ply"):
        run({"INPUT": layer, "OUTPUT_MESH": str(tmp_path / name)})
    assert not (tmp_path / name).exists()


def test_a_layer_mixing_every_bad_row_accounts_for_every_feature():
    wkts = [
        None,
        "POLYGON EMPTY",
        DEGENERATE["all_points_collinear"],
        *(wkt for wkt, _ in AREAS.values()),
        *(wkt for wkt, _ in INVALID.values()),
    ]
    triangulated = {}
    for mode in (REPAIR, FAIL, AS_GIVEN):
        result, rows, _errors = outcome(polygon_layer(wkts), mode)
        triangulated[mode] = len({row["feature_id"] for row in rows})
        assert result["EMPTY_COUNT"] >= 2
    assert triangulated[FAIL] == len(AREAS)
    assert triangulated[REPAIR] == triangulated[AS_GIVEN] == len(AREAS) + len(INVALID)
