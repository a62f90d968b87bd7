"""tests/data/river_mesh.model3, a graphical-modeler model (rivers -> reproject to UTM 33S ->
buffer -> triangulate over the SRTM DEM): it loads in this QGIS and runs under qgis_process."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsProcessingModelAlgorithm, QgsVectorLayer, QgsWkbTypes

from tests.conftest import ROOT, SHARED_DATA, QgisProcess, load_plugin_package, read_mesh

MODEL = ROOT / "tests" / "data" / "river_mesh.model3"
RIVERS = SHARED_DATA / "swellendam" / "rivers.shp"
DEM = SHARED_DATA / "swellendam" / "srtm_41_19.tif"
# One tributary keeps the run short; it climbs through real terrain.
RIVER = "The Hermitage"
RIVER_SOURCE = f"{RIVERS}|subset=\"name\" = '{RIVER}'"
BUFFER_M = 100.0


@pytest.fixture(scope="module")
def registered_plugin(qgis_processing):
    plugin = load_plugin_package().classFactory(None)
    plugin.initProcessing()
    yield plugin
    plugin.unload()


@pytest.fixture(scope="module")
def model_run(qgis_process: QgisProcess, tmp_path_factory: pytest.TempPathFactory) -> dict:
    out = tmp_path_factory.mktemp("river-model")
    answer = qgis_process.run_json(
        "run",
        str(MODEL),
        "--",
        f"rivers={RIVER_SOURCE}",
        f"dem={DEM}",
        f"buffer_distance={BUFFER_M}",
        f"triangulate:mesh={out / 'river.2dm'}",
        f"triangulate:triangles={out / 'river_triangles.gpkg'}",
    )
    return answer["results"]


def river_buffer_area() -> float:
    """Area of the same river buffer made here, step by step, with QGIS's own algorithms."""
    import processing  # importable once pytest-qgis has set Processing up

    reprojected = processing.run(
        "native:reprojectlayer",
        {"INPUT": RIVER_SOURCE, "TARGET_CRS": "EPSG:32733", "OUTPUT": "memory:"},
    )["OUTPUT"]
    buffered = processing.run(
        "native:buffer",
        {"INPUT": reprojected, "DISTANCE": BUFFER_M, "SEGMENTS": 5, "OUTPUT": "memory:"},
    )["OUTPUT"]
    assert buffered.featureCount() == 1
    return sum(f.geometry().area() for f in buffered.getFeatures())


def dem_range_around(x: float, y: float, dem: np.ndarray, transform: tuple) -> tuple[float, float]:
    """Lowest and highest of the (up to) 2 x 2 cells whose centres surround (x, y): any nearest
    or bilinear sample at (x, y) lies between them."""
    column = (x - transform[0]) / transform[1] - 0.5
    row = (y - transform[3]) / transform[5] - 0.5
    c0, r0 = math.floor(column), math.floor(row)
    cells = dem[max(r0, 0) : r0 + 2, max(c0, 0) : c0 + 2]
    return float(cells.min()), float(cells.max())


def test_model_loads_with_its_three_steps_and_every_algorithm_resolved(registered_plugin) -> None:
    model = QgsProcessingModelAlgorithm()
    assert model.fromFile(str(MODEL))
    children = model.childAlgorithms()
    assert {key: child.algorithmId() for key, child in children.items()} == {
        "reproject": "native:reprojectlayer",
        "buffer": "native:buffer",
        "triangulate": "bsptriangulate:triangulate",
    }
    assert all(child.algorithm() is not None for child in children.values())
    assert {p.name() for p in model.parameterDefinitions()} == {
        "rivers",
        "dem",
        "buffer_distance",
        "triangulate:mesh",
        "triangulate:triangles",
    }
    sources = children["triangulate"].parameterSources()
    assert sources["ELEVATION_SOURCE"][0].staticValue() == 3
    assert sources["DEM"][0].parameterName() == "dem"
    assert sources["INPUT"][0].outputChildId() == "buffer"


def test_model_run_covers_the_river_buffer_with_triangles(model_run: dict, qgis_processing) -> None:
    layer = QgsVectorLayer(model_run["triangulate:triangles"], "triangles", "ogr")
    assert layer.isValid()
    assert layer.crs().authid() == "EPSG:32733"
    assert QgsWkbTypes.hasZ(layer.wkbType())
    _, faces = read_mesh(Path(model_run["triangulate:mesh"]))
    assert layer.featureCount() == len(faces) > 100
    area = sum(f.geometry().area() for f in layer.getFeatures())
    assert area == pytest.approx(river_buffer_area(), rel=1e-9)


def test_model_run_takes_mesh_elevations_from_the_dem(model_run: dict) -> None:
    vertices, _ = read_mesh(Path(model_run["triangulate:mesh"]))
    raster = gdal.Open(str(DEM))
    dem = raster.GetRasterBand(1).ReadAsArray().astype(np.float64)
    transform = raster.GetGeoTransform()
    outside = []
    for x, y, z in vertices:
        low, high = dem_range_around(x, y, dem, transform)
        if not low - 1e-6 <= z <= high + 1e-6:
            outside.append((x, y, z, low, high))
    assert outside == []
    heights = [z for _, _, z in vertices]
    assert max(heights) - min(heights) > 20.0  # the river runs over terrain, not a flat plane
