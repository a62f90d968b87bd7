"""Interior points through processing.run: DEM points until the mesh is within
MAX_VERTICAL_ERROR of the DEM at every cell centre inside, and survey points (INPUT_POINTS)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from osgeo import gdal
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsFeature,
    QgsGeometry,
    QgsProcessingException,
    QgsProject,
    QgsVectorLayer,
)

from tests.conftest import SHARED_DATA
from tests.core.terrain.test_refine import surface
from tests.qgis.helpers import (
    RecordingFeedback,
    corners,
    polygon_layer,
    run,
    triangle_rows,
    write_utm_dem,
)

pytestmark = pytest.mark.usefixtures("provider")

X0, Y0, CELL, COLS, ROWS = 1_000_000.0, 6_230_000.0, 100.0, 40, 36
HILL = [(430, 310), (3720, 540), (3830, 3260), (2040, 2230), (560, 3420)]
HOLE = [(1500, 900), (2300, 950), (2200, 1500), (1400, 1450)]
SWELLENDAM = SHARED_DATA / "swellendam"


def hill(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A Gaussian hill on a tilted plane, with a ridge."""
    dx, dy = x - (X0 + 2000), (Y0 - 1800) - y
    return (
        300.0
        + 120.0 * np.exp(-(dx**2 + dy**2) / (2 * 700.0**2))
        + 0.01 * dx
        + 25.0 * np.abs(np.sin(dx / 400.0))
    )


def write_hill_dem(path: Path, nodata: tuple[slice, slice] | None = None) -> Path:
    """A Float64 GeoTIFF in EPSG:32733 of the hill at the cell centres."""
    xs = X0 + (np.arange(COLS) + 0.5) * CELL
    ys = Y0 - (np.arange(ROWS) + 0.5) * CELL
    values = hill(xs[None, :], ys[:, None])
    if nodata is not None:
        values[nodata] = -9999.0
    return write_utm_dem(path, values, X0, Y0, CELL)


def wkt(rings: list[list[tuple[float, float]]]) -> str:
    text = []
    for ring in rings:
        closed = [*ring, ring[0]]
        text.append("(" + ", ".join(f"{X0 + x} {Y0 - y}" for x, y in closed) + ")")
    return "POLYGON(" + ", ".join(text) + ")"


def mesh_of(result: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, triangles, feature id per triangle) of the triangles output."""
    rows = triangle_rows(result)
    points = np.concatenate([corners(row) for row in rows])
    triangles = np.arange(len(points)).reshape(-1, 3)
    return points, triangles, np.array([row["feature_id"] for row in rows])


def largest_error(dem_path: Path, polygons: list, vertices, triangles, owner) -> float:
    """max |surface - DEM| over every cell centre strictly inside each polygon (``owner``:
    the polygon of each triangle)."""
    dataset = gdal.Open(str(dem_path))
    x0, dx, _, y0, _, dy = dataset.GetGeoTransform()
    band = dataset.GetRasterBand(1)
    values = band.ReadAsArray().astype(np.float64)
    rows, cols = np.indices(values.shape)
    x, y = x0 + (cols.ravel() + 0.5) * dx, y0 + (rows.ravel() + 0.5) * dy
    valid = values.ravel() != band.GetNoDataValue()
    worst = 0.0
    for fid, polygon in enumerate(polygons):
        keep = shapely.contains_xy(polygon, x, y) & valid
        z = surface(vertices, triangles[owner == fid], np.column_stack([x[keep], y[keep]]))
        assert not np.isnan(z).any(), "a cell centre inside is in no triangle"
        if keep.any():
            worst = max(worst, float(np.abs(z - values.ravel()[keep]).max()))
    return worst


@pytest.mark.parametrize("rule", [2, 0])
def test_mesh_is_within_the_tolerance_at_every_cell_centre(tmp_path: Path, rule: int):
    dem = write_hill_dem(tmp_path / "hill.tif", (slice(20, 23), slice(8, 12)))
    text = wkt([HILL, HOLE])
    feedback = RecordingFeedback()
    result = run(
        {
            "INPUT": polygon_layer([text]),
            "DEM": str(dem),
            "MAX_VERTICAL_ERROR": 2.0,
            "APEX_RULE": rule,
        },
        feedback,
    )
    assert result["FAILED_COUNT"] == 0 and not feedback.errors
    assert result["POINTS_ADDED"] > 20
    vertices, triangles, _owner = mesh_of(result)
    assert len(triangles) == result["TRIANGLE_COUNT"]
    polygon = shapely.from_wkt(text)
    one = np.zeros(len(triangles), np.int64)
    assert largest_error(dem, [polygon], vertices, triangles, one) <= 2.0
    assert sum(row["area_2d"] for row in triangle_rows(result)) == pytest.approx(polygon.area)


def test_without_points_the_error_is_larger(tmp_path: Path):
    dem = write_hill_dem(tmp_path / "hill.tif")
    text = wkt([HILL, HOLE])
    result = run({"INPUT": polygon_layer([text]), "DEM": str(dem)})
    vertices, triangles, _owner = mesh_of(result)
    assert result["POINTS_ADDED"] == 0
    one = np.zeros(len(triangles), np.int64)
    assert largest_error(dem, [shapely.from_wkt(text)], vertices, triangles, one) > 20


def test_the_cap_is_reported_with_the_feature_and_the_error(tmp_path: Path):
    dem = write_hill_dem(tmp_path / "hill.tif")
    feedback = RecordingFeedback()
    report = tmp_path / "report.csv"
    result = run(
        {
            "INPUT": polygon_layer([wkt([HILL]), wkt([[(100, 100), (300, 100), (200, 250)]])]),
            "DEM": str(dem),
            "MAX_VERTICAL_ERROR": 0.5,
            "MAX_POINTS": 4,
            "OUTPUT_REPORT": str(report),
        },
        feedback,
    )
    assert result["FAILED_COUNT"] == 0 and result["POINTS_ADDED"] <= 4
    assert len({row["feature_id"] for row in triangle_rows(result)}) == 2
    [warning] = [w for w in feedback.warnings if "cap of 4" in w]
    assert warning.startswith("Feature 1: mesh within ")
    text = report.read_text()
    assert "cap of 4" in text and text.splitlines()[1].startswith("1,")


def point_layer(points: list[tuple[float, float, float]], z_in_geometry: bool) -> QgsVectorLayer:
    kind = "PointZ" if z_in_geometry else "Point"
    layer = QgsVectorLayer(f"{kind}?crs=EPSG:32733&field=h:double", "points", "memory")
    features = []
    for x, y, z in points:
        feature = QgsFeature(layer.fields())
        feature.setAttributes([z])
        point = (
            f"POINT Z ({X0 + x} {Y0 - y} {z})" if z_in_geometry else f"POINT ({X0 + x} {Y0 - y})"
        )
        feature.setGeometry(QgsGeometry.fromWkt(point))
        features.append(feature)
    assert layer.dataProvider().addFeatures(features)
    return layer


SURVEY = [(1000.0, 1000.0, 512.5), (3000.0, 1500.0, 77.0), (1800.0, 1200.0, 5.0), (-50, 0, 1)]


@pytest.mark.parametrize("z_in_geometry", [True, False])
def test_input_points_become_vertices_with_their_z(z_in_geometry: bool):
    # the third point is in the island, the fourth outside: neither is used
    layer = point_layer(SURVEY, z_in_geometry)
    parameters = {"INPUT": polygon_layer([wkt([HILL, HOLE])]), "ELEVATION_SOURCE": 0}
    parameters["INPUT_POINTS"] = layer
    if not z_in_geometry:
        parameters["POINTS_Z_FIELD"] = "h"
    result = run(parameters)
    vertices, _triangles, _owner = mesh_of(result)
    assert result["TRIANGLE_COUNT"] == (5 + 4) + 2 * 1 - 2 + 2 * 2
    for x, y, z in SURVEY[:2]:
        assert [X0 + x, Y0 - y, z] in vertices.tolist()
    assert not any(x == X0 + 1800.0 for x in vertices[:, 0])
    assert set(vertices[:, 2]) == {0.0, 512.5, 77.0}


def test_input_points_with_dem_points_keep_their_z(tmp_path: Path):
    dem = write_hill_dem(tmp_path / "hill.tif")
    result = run(
        {
            "INPUT": polygon_layer([wkt([HILL, HOLE])]),
            "DEM": str(dem),
            "MAX_VERTICAL_ERROR": 5.0,
            "APEX_RULE": 2,
            "INPUT_POINTS": point_layer(SURVEY[:1], True),
        }
    )
    vertices, _triangles, _owner = mesh_of(result)
    assert [X0 + 1000.0, Y0 - 1000.0, 512.5] in vertices.tolist()
    assert result["POINTS_ADDED"] > 0


def test_bad_combinations_are_refused(tmp_path: Path):
    dem = write_hill_dem(tmp_path / "hill.tif")
    layer = polygon_layer([wkt([HILL])])
    with pytest.raises(QgsProcessingException, match="needs the DEM"):
        run({"INPUT": layer, "ELEVATION_SOURCE": 0, "MAX_VERTICAL_ERROR": 1.0})
    with pytest.raises(QgsProcessingException, match="no Z"):
        run({"INPUT": layer, "INPUT_POINTS": point_layer(SURVEY, False), "DEM": str(dem)})
    with pytest.raises(QgsProcessingException, match="without input points"):
        run({"INPUT": layer, "POINTS_Z_FIELD": "h"})
    wgs84 = QgsVectorLayer("Polygon?crs=EPSG:4326", "input", "memory")
    feature = QgsFeature()
    geometry = QgsGeometry.fromWkt(wkt([HILL]))
    geometry.transform(
        QgsCoordinateTransform(
            QgsCoordinateReferenceSystem("EPSG:32733"),
            QgsCoordinateReferenceSystem("EPSG:4326"),
            QgsProject.instance(),
        )
    )
    feature.setGeometry(geometry)
    wgs84.dataProvider().addFeatures([feature])
    with pytest.raises(QgsProcessingException, match="layer's CRS"):
        run({"INPUT": wgs84, "DEM": str(dem), "MAX_VERTICAL_ERROR": 1.0})


FARMS = SWELLENDAM / "farms_33S.shp"
FARM_DEM = SWELLENDAM / "srtm_41_19.tif"


@pytest.mark.skipif(not FARMS.exists(), reason="the Swellendam data is not there")
def test_swellendam_farms_within_the_tolerance():
    source = QgsVectorLayer(str(FARMS), "farms", "ogr")
    # a few small farms, for a run of seconds
    chosen = [f for f in source.getFeatures() if f.geometry().area() < 1.5e6][:12]
    layer = QgsVectorLayer("Polygon?crs=EPSG:32733", "farms", "memory")
    copies = []
    for feature in chosen:
        copy = QgsFeature()
        copy.setGeometry(feature.geometry())
        copies.append(copy)
    assert layer.dataProvider().addFeatures(copies)
    feedback = RecordingFeedback()
    result = run(
        {"INPUT": layer, "DEM": str(FARM_DEM), "MAX_VERTICAL_ERROR": 5.0, "APEX_RULE": 2},
        feedback,
    )
    assert result["FEATURE_COUNT"] == len(chosen) == 12
    assert result["FAILED_COUNT"] == 0 and result["EMPTY_COUNT"] == 0
    assert not [w for w in feedback.warnings if "mesh within" in w]
    vertices, triangles, owner = mesh_of(result)
    polygons = [shapely.from_wkb(bytes(c.geometry().asWkb())) for c in layer.getFeatures()]
    ids = [c.id() for c in layer.getFeatures()]
    owner = np.searchsorted(ids, owner)
    assert largest_error(FARM_DEM, polygons, vertices, triangles, owner) <= 5.0


def test_input_points_in_another_crs_are_reprojected():
    utm = QgsCoordinateReferenceSystem("EPSG:32733")
    wgs84 = QgsCoordinateReferenceSystem("EPSG:4326")
    to_wgs84 = QgsCoordinateTransform(utm, wgs84, QgsProject.instance())
    layer = QgsVectorLayer("PointZ?crs=EPSG:4326", "points", "memory")
    feature = QgsFeature()
    geometry = QgsGeometry.fromWkt(f"POINT Z ({X0 + 1000.0} {Y0 - 1000.0} 512.5)")
    geometry.transform(to_wgs84)
    feature.setGeometry(geometry)
    assert layer.dataProvider().addFeatures([feature])
    result = run(
        {"INPUT": polygon_layer([wkt([HILL])]), "ELEVATION_SOURCE": 0, "INPUT_POINTS": layer}
    )
    vertices, _triangles, _owner = mesh_of(result)
    near = np.hypot(vertices[:, 0] - (X0 + 1000.0), vertices[:, 1] - (Y0 - 1000.0)) < 1e-3
    assert near.any() and (vertices[near, 2] == 512.5).all()
    assert result["TRIANGLE_COUNT"] == 5 - 2 + 2
