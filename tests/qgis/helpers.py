"""Helpers of the bsptriangulate:triangulate tests: memory layers, runs, triangle rows and a
planar DEM whose bilinear samples are exact."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from osgeo import gdal, osr
from qgis.core import (
    QgsFeature,
    QgsFeatureRequest,
    QgsGeometry,
    QgsProcessingContext,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)

ALG = "bsptriangulate:triangulate"
UTM = "EPSG:32733"


class RecordingFeedback(QgsProcessingFeedback):
    """Keeps reported errors and warnings for assertions."""

    def __init__(self) -> None:
        super().__init__()
        self.errors: list[str] = []
        self.warnings: list[str] = []

    def reportError(self, error: str, fatalError: bool = False) -> None:  # noqa: N803
        self.errors.append(error)

    def pushWarning(self, warning: str) -> None:
        self.warnings.append(warning)


def polygon_layer(
    wkts: list[str | None],
    geometry: str = "Polygon",
    crs: str = UTM,
    fields: str = "&field=name:string&field=height:double&field=depth:integer",
) -> QgsVectorLayer:
    """A memory layer with one feature per WKT (None = null geometry); attributes name, height."""
    layer = QgsVectorLayer(f"{geometry}?crs={crs}{fields}", "input", "memory")
    features = []
    for index, wkt in enumerate(wkts):
        feature = QgsFeature(layer.fields())
        feature.setAttributes([f"f{index}", 10.0 * (index + 1), 7][: len(layer.fields())])
        if wkt is not None:
            feature.setGeometry(QgsGeometry.fromWkt(wkt))
        features.append(feature)
    assert layer.dataProvider().addFeatures(features)
    return layer


def run(
    parameters: dict,
    feedback: QgsProcessingFeedback | None = None,
    invalid_check: QgsFeatureRequest.InvalidGeometryCheck = QgsFeatureRequest.GeometryNoCheck,
) -> dict:
    import processing

    defaults = {"OUTPUT_TRIANGLES": "memory:", "OUTPUT_MESH": "TEMPORARY_OUTPUT"}
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    context.setInvalidGeometryCheck(invalid_check)
    return processing.run(
        ALG, {**defaults, **parameters}, feedback=feedback or RecordingFeedback(), context=context
    )


def triangle_rows(result: dict) -> list[QgsFeature]:
    return list(result["OUTPUT_TRIANGLES"].getFeatures())


def corners(feature: QgsFeature) -> np.ndarray:
    """The three (x, y, z) corners of a triangle feature."""
    ring = feature.geometry().constGet().exteriorRing()
    points = [(ring.xAt(i), ring.yAt(i), ring.zAt(i)) for i in range(ring.numPoints())]
    assert points[0] == points[-1] and len(points) == 4
    return np.array(points[:3])


# DEM tests: z = A*(x - X0) + B*(Y0 - y) + C at every cell centre, so bilinear is exact.
A, B, C = 0.37, -0.21, 250.0
X0, Y0, CELL, COLS, ROWS = 1_000_000.0, 6_230_000.0, 100.0, 60, 50


def plane(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return A * (x - X0) + B * (Y0 - y) + C


def write_plane_dem(path: Path, nodata_cells: tuple[tuple[int, int], ...] = ()) -> Path:
    """A Float64 GeoTIFF in EPSG:32733 holding the plane; listed cells set to nodata."""
    xs = X0 + (np.arange(COLS) + 0.5) * CELL
    ys = Y0 - (np.arange(ROWS) + 0.5) * CELL
    values = plane(xs[None, :], ys[:, None])
    for row, col in nodata_cells:
        values[row, col] = -9999.0
    return write_utm_dem(path, values, X0, Y0, CELL)


def write_utm_dem(path: Path, values: np.ndarray, x0: float, y0: float, cell: float) -> Path:
    """``values`` (rows, cols) as a Float64 GeoTIFF in EPSG:32733, north-up from the top-left
    corner (x0, y0) with square cells; -9999 is nodata."""
    rows, cols = values.shape
    dataset = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Float64)
    dataset.SetGeoTransform((x0, cell, 0.0, y0, 0.0, -cell))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32733)
    dataset.SetProjection(srs.ExportToWkt())
    band = dataset.GetRasterBand(1)
    band.SetNoDataValue(-9999.0)
    band.WriteArray(values)
    dataset = None
    return path


def utm_wkt(points: list[tuple[float, float]]) -> str:
    ring = [*points, points[0]]
    return "POLYGON((" + ", ".join(f"{X0 + x} {Y0 - y}" for x, y in ring) + "))"


DEM_POLYGON = [(430, 310), (4520, 540), (5230, 4260), (2540, 2230), (960, 4420)]
