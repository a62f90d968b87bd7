"""A DEM read by window: only the cells around one partition's points, through GDAL's Python
bindings (``osgeo``, imported here only), sampled with the engine's ``PreparedGrid``.

A point's value is the one a ``PreparedGrid`` of the whole band gives: its pixel position is
computed with the DEM's own geotransform, then shifted by the window's whole-cell offset
(exact in floating point), and the window keeps two cells around every point (a bilinear
neighbour is never cut off except at the DEM's own edge).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..terrain.raster_sampling import PreparedGrid, world_to_pixel

# cells kept around the points' pixel box
MARGIN = 2
_PIXEL = (0.0, 1.0, 0.0, 0.0, 0.0, 1.0)  # a window's own pixel coordinates as "world"


def _gdal():
    try:
        from osgeo import gdal
    except ImportError as error:  # pragma: no cover - depends on the machine
        raise ImportError("a DEM needs GDAL's Python bindings (osgeo)") from error
    gdal.UseExceptions()
    return gdal


@dataclass(frozen=True)
class DemInfo:
    """What the client learns of a DEM once: size, geotransform, CRS (WKT, may be empty)."""

    path: str
    band: int
    cols: int
    rows: int
    geotransform: tuple[float, ...]
    crs_wkt: str

    @classmethod
    def open(cls, path: str, band: int = 1) -> DemInfo:
        dataset = _gdal().Open(str(path))
        if band < 1 or band > dataset.RasterCount:
            raise ValueError(f"the DEM {path} has no band {band}")
        return cls(
            str(path),
            band,
            dataset.RasterXSize,
            dataset.RasterYSize,
            tuple(float(v) for v in dataset.GetGeoTransform()),
            dataset.GetProjection() or "",
        )


def window(info: DemInfo, cols: np.ndarray, rows: np.ndarray) -> tuple[int, int, int, int]:
    """(col0, row0, width, height) of the cells around the pixel positions, within the DEM
    (width or height 0 where no point is near it)."""
    finite = np.isfinite(cols) & np.isfinite(rows)
    if not finite.any():
        return 0, 0, 0, 0
    c0 = max(math.floor(float(cols[finite].min())) - MARGIN, 0)
    r0 = max(math.floor(float(rows[finite].min())) - MARGIN, 0)
    c1 = min(math.floor(float(cols[finite].max())) + MARGIN + 1, info.cols)
    r1 = min(math.floor(float(rows[finite].max())) + MARGIN + 1, info.rows)
    return c0, r0, max(c1 - c0, 0), max(r1 - r0, 0)


def sample(info: DemInfo, xs: np.ndarray, ys: np.ndarray, method: str = "bilinear") -> np.ndarray:
    """The band's values at the points (in the DEM's CRS); NaN outside it and on nodata.
    Reads one window: the cells around these points."""
    values = np.full(len(xs), np.nan)
    if not len(xs):
        return values
    cols, rows = world_to_pixel(info.geotransform, xs, ys)
    c0, r0, width, height = window(info, cols, rows)
    if width == 0 or height == 0:
        return values
    dataset = _gdal().Open(info.path)
    band = dataset.GetRasterBand(info.band)
    array = band.ReadAsArray(c0, r0, width, height)
    nodata = band.GetNoDataValue()
    grid = PreparedGrid(array, _PIXEL, nodata)
    # outside the DEM as a whole (the window may be smaller): no value, as for the whole band
    inside = (cols >= 0) & (cols <= info.cols) & (rows >= 0) & (rows <= info.rows)
    if inside.any():
        values[inside] = grid.sample(cols[inside] - c0, rows[inside] - r0, method)
    return values
