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
    QgsPointXY,
    QgsProcessingException,
    QgsProject,
    QgsRasterLayer,
    QgsVectorLayer,
)

from bsp_triangulate.terrain.raster_sampling import PreparedGrid
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


def test_a_geographic_layer_with_a_projected_dem_is_refined_on_the_resampled_dem(
    tmp_path: Path,
):
    # refused before the DEM was resampled into the layer's CRS
    dem = write_hill_dem(tmp_path / "hill.tif", (slice(20, 23), slice(8, 12)))
    wgs84 = QgsVectorLayer("Polygon?crs=EPSG:4326", "input", "memory")
    feature = QgsFeature()
    geometry = QgsGeometry.fromWkt(wkt([HILL, HOLE]))
    geometry.transform(
        QgsCoordinateTransform(
            QgsCoordinateReferenceSystem("EPSG:32733"),
            QgsCoordinateReferenceSystem("EPSG:4326"),
            QgsProject.instance(),
        )
    )
    feature.setGeometry(geometry)
    wgs84.dataProvider().addFeatures([feature])
    feedback = RecordingFeedback()
    result = run(
        {"INPUT": wgs84, "DEM": str(dem), "MAX_VERTICAL_ERROR": 2.0, "APEX_RULE": 2}, feedback
    )
    assert result["FAILED_COUNT"] == 0 and result["POINTS_ADDED"] > 20
    assert not [w for w in feedback.warnings if "mesh within" in w]
    vertices, triangles, _owner = mesh_of(result)
    grid = resampled_grid(wgs84, dem)
    polygon = shapely.from_wkb(bytes(geometry.asWkb()))
    one = np.zeros(len(triangles), np.int64)
    assert largest_error_on_grid(grid, [polygon], vertices, triangles, one) <= 2.0
    assert largest_error_from_original(grid, dem, [polygon], vertices, triangles, one) <= 2.0 + 1e-6
    # the DEM's nodata cells stay nodata on the resampled grid (and are skipped)
    cells = grid.cells(*polygon.bounds)
    assert np.isnan(cells.values).sum() >= 12 and np.isfinite(cells.values).sum() > 300


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


def resampled_grid(layer: QgsVectorLayer, dem_path: Path):
    """The resampled DEM a run of ``layer`` over a DEM in another CRS refines on: the
    algorithm's own sampler, built from the same inputs (the layer's centre, the project's
    transform context)."""
    from bsptriangulate.processing_provider.elevation import DemSampler
    from bsptriangulate.processing_provider.warped_dem import WarpedDemSampler

    dem = QgsRasterLayer(str(dem_path), "dem")
    assert dem.isValid()
    return WarpedDemSampler(
        DemSampler(dem.dataProvider().clone(), 1, "bilinear"),
        layer.crs(),
        dem.crs(),
        QgsProject.instance().transformContext(),
        layer.extent().center(),
    )


def largest_error_on_grid(sampler, polygons: list, vertices, triangles, owner) -> float:
    """max |surface - cell value| over every cell centre of the resampled grid strictly
    inside each polygon (the cells the refinement measured, from ``sampler.cells``)."""
    worst = 0.0
    for fid, polygon in enumerate(polygons):
        xmin, ymin, xmax, ymax = polygon.bounds
        grid = sampler.cells(xmin, ymin, xmax, ymax)
        rows, cols = np.indices(grid.values.shape)
        x, y = grid.centre_x(cols.ravel()), grid.centre_y(rows.ravel())
        values = grid.values.ravel()
        keep = shapely.contains_xy(polygon, x, y) & np.isfinite(values)
        if not keep.any():
            continue
        z = surface(vertices, triangles[owner == fid], np.column_stack([x[keep], y[keep]]))
        assert not np.isnan(z).any(), "a cell centre inside is in no triangle"
        worst = max(worst, float(np.abs(z - values[keep]).max()))
    return worst


def largest_error_from_original(
    sampler, dem_path: Path, polygons: list, vertices, triangles, owner
) -> float:
    """max |surface - DEM| at the same cell centres (those with a value), the DEM sampled
    bilinearly in its own CRS at each centre transformed there (the resampled cell's value,
    computed again)."""
    dataset = gdal.Open(str(dem_path))
    band = dataset.GetRasterBand(1)
    original = PreparedGrid(band.ReadAsArray(), dataset.GetGeoTransform(), band.GetNoDataValue())
    worst = 0.0
    for fid, polygon in enumerate(polygons):
        grid = sampler.cells(*polygon.bounds)
        rows, cols = np.indices(grid.values.shape)
        x, y = grid.centre_x(cols.ravel()), grid.centre_y(rows.ravel())
        keep = shapely.contains_xy(polygon, x, y) & np.isfinite(grid.values.ravel())
        if not keep.any():
            continue
        xy = np.column_stack([x[keep], y[keep]])
        dem_xy = np.array(
            [
                (p.x(), p.y())
                for p in (sampler.to_dem.transform(QgsPointXY(float(a), float(b))) for a, b in xy)
            ]
        )
        expected = original.sample(dem_xy[:, 0], dem_xy[:, 1], "bilinear")
        z = surface(vertices, triangles[owner == fid], xy)
        worst = max(worst, float(np.nanmax(np.abs(z - expected))))
    return worst


@pytest.fixture(scope="module")
def dem_4326(tmp_path_factory) -> Path:
    """The Swellendam SRTM DEM in EPSG:4326 at 3 arc-seconds (as SRTM is published), warped
    from the EPSG:32733 copy of the shared data (its EPSG:4326 original is not there)."""
    path = tmp_path_factory.mktemp("dem") / "srtm_41_19_4326.tif"
    warped = gdal.Warp(
        str(path),
        str(FARM_DEM),
        dstSRS="EPSG:4326",
        xRes=1 / 1200,
        yRes=1 / 1200,
        resampleAlg="bilinear",
        dstNodata=-32768,
        outputType=gdal.GDT_Int16,
    )
    assert warped is not None
    warped = None
    return path


def small_farms(crs: str = "EPSG:32733") -> QgsVectorLayer:
    """The first 12 farms under 1.5 km², in a memory layer of ``crs``."""
    source = QgsVectorLayer(str(FARMS), "farms", "ogr")
    chosen = [f for f in source.getFeatures() if f.geometry().area() < 1.5e6][:12]
    layer = QgsVectorLayer(f"Polygon?crs={crs}", "farms", "memory")
    transform = QgsCoordinateTransform(
        source.crs(), QgsCoordinateReferenceSystem(crs), QgsProject.instance()
    )
    copies = []
    for feature in chosen:
        copy = QgsFeature()
        geometry = QgsGeometry(feature.geometry())
        geometry.transform(transform)
        copy.setGeometry(geometry)
        copies.append(copy)
    assert layer.dataProvider().addFeatures(copies)
    return layer


def polygons_and_owner(layer: QgsVectorLayer, owner: np.ndarray) -> tuple[list, np.ndarray]:
    polygons = [shapely.from_wkb(bytes(c.geometry().asWkb())) for c in layer.getFeatures()]
    ids = [c.id() for c in layer.getFeatures()]
    return polygons, np.searchsorted(ids, owner)


class InfoFeedback(RecordingFeedback):
    """Keeps the info lines too."""

    def __init__(self) -> None:
        super().__init__()
        self.infos: list[str] = []

    def pushInfo(self, info: str) -> None:
        self.infos.append(info)


@pytest.mark.skipif(not FARMS.exists(), reason="the Swellendam data is not there")
def test_utm_farms_with_a_geographic_dem_are_within_the_tolerance(dem_4326: Path):
    layer = small_farms()
    feedback = InfoFeedback()
    result = run(
        {"INPUT": layer, "DEM": str(dem_4326), "MAX_VERTICAL_ERROR": 5.0, "APEX_RULE": 2},
        feedback,
    )
    assert result["FEATURE_COUNT"] == 12
    assert result["FAILED_COUNT"] == 0 and result["EMPTY_COUNT"] == 0
    assert result["POINTS_ADDED"] > 0
    assert not [w for w in feedback.warnings if "mesh within" in w]
    [info] = [i for i in feedback.infos if "resampled into the layer's CRS" in i]
    assert "EPSG:4326" in info and "EPSG:32733" in info
    vertices, triangles, owner = mesh_of(result)
    assert len({int(fid) for fid in owner}) == 12
    polygons, owner = polygons_and_owner(layer, owner)
    sampler = resampled_grid(layer, dem_4326)
    # SRTM's 3" cells are about 77 m x 92 m here: the grid keeps their area
    assert 70 < sampler.dx < 85 and 85 < sampler.dy < 100
    assert largest_error_on_grid(sampler, polygons, vertices, triangles, owner) <= 5.0
    # the same cell centres against the original DEM, sampled bilinearly: the resampled
    # cells are those samples, up to rounding
    original = largest_error_from_original(sampler, dem_4326, polygons, vertices, triangles, owner)
    assert original <= 5.0 + 1e-6


@pytest.mark.skipif(not FARMS.exists(), reason="the Swellendam data is not there")
def test_geographic_farms_with_a_geographic_dem_are_not_resampled(dem_4326: Path):
    layer = small_farms("EPSG:4326")
    feedback = InfoFeedback()
    result = run(
        {"INPUT": layer, "DEM": str(dem_4326), "MAX_VERTICAL_ERROR": 5.0, "APEX_RULE": 2},
        feedback,
    )
    assert result["FEATURE_COUNT"] == 12
    assert result["FAILED_COUNT"] == 0 and result["POINTS_ADDED"] > 0
    assert not [i for i in feedback.infos if "resampled" in i]
    assert not [w for w in feedback.warnings if "mesh within" in w]
    vertices, triangles, owner = mesh_of(result)
    polygons, owner = polygons_and_owner(layer, owner)
    assert largest_error(dem_4326, polygons, vertices, triangles, owner) <= 5.0


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
