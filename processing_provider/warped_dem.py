"""A DEM in another CRS than the layer's, resampled into the layer's CRS for the refinement.

The refinement (``terrain_points.InteriorPoints``) adds DEM cell centres as mesh vertices and
measures the mesh against them, so it needs north-up cells in the layer's CRS. A DEM in another
CRS is warped with GDAL, in memory, onto one grid of the layer's CRS for the whole run: square
tiles of that grid under the features (as ``DemSampler`` reads tiles), and the cells under one
part that spans tiles warped on their own. The ring vertices are sampled on the same grid, so
the mesh and the cells it is measured against come from one surface.
"""

from __future__ import annotations

import numpy as np
from osgeo import gdal
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsCoordinateTransformContext,
    QgsPointXY,
)

from ..bsp_triangulate.terrain.raster_sampling import PreparedGrid
from ..bsp_triangulate.terrain.refine import CellGrid
from .elevation import DemSampler, TiledGrid, transform_xy
from .qgis_compat import CrsWktVariant

# points per tile edge transformed to find the DEM cells under a tile
EDGE_POINTS = 17
WARP_METHODS = {"bilinear": "bilinear", "nearest": "near"}


def cell_size(corners: np.ndarray) -> tuple[float, float]:
    """(width, height) of cells of the same area as the quadrilateral ``corners`` (4, 2) and
    the proportions of its bounding box: a DEM cell's corners in the layer's CRS give a cell
    of about the DEM's resolution there."""
    x, y = corners[:, 0], corners[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    width, height = float(np.ptp(x)), float(np.ptp(y))
    if not (area > 0 and width > 0 and height > 0 and np.isfinite(area)):
        raise ValueError("the DEM's cells cannot be transformed into the layer's CRS")
    return float(np.sqrt(area * width / height)), float(np.sqrt(area * height / width))


class WarpedDemSampler(TiledGrid):
    """``DemSampler``'s interface (``sample``, ``cells``) in the layer's CRS over a DEM in
    another CRS: the DEM block under a tile read through ``base`` and warped by GDAL onto
    the run's grid (cell ``(i, j)`` spans ``[i*dx, (i+1)*dx) x [j*dy, (j+1)*dy)``; a
    tile's key: its ``(i // TILE, j // TILE)``)."""

    def __init__(
        self,
        base: DemSampler,
        layer_crs: QgsCoordinateReferenceSystem,
        dem_crs: QgsCoordinateReferenceSystem,
        transform_context: QgsCoordinateTransformContext,
        reference: QgsPointXY,
    ) -> None:
        """``reference``: a point of the layer's CRS (the layer's centre) where the grid's
        cells have about the DEM's cell area."""
        super().__init__(base.method)
        self.base = base
        self.transform = None  # samples points in the layer's CRS
        self.to_dem = QgsCoordinateTransform(layer_crs, dem_crs, transform_context)
        self.to_layer = QgsCoordinateTransform(dem_crs, layer_crs, transform_context)
        self.dem_wkt = dem_crs.toWkt(CrsWktVariant.Preferred)
        self.layer_wkt = layer_crs.toWkt(CrsWktVariant.Preferred)
        self.dx, self.dy = self._cell_size(reference)

    def _cell_size(self, reference: QgsPointXY) -> tuple[float, float]:
        base = self.base
        centre = transform_xy(np.array([[reference.x(), reference.y()]]), self.to_dem)[0]
        if not np.isfinite(centre).all():
            centre = np.array(
                [base.xmin + base.cols * base.xres / 2, base.ymax - base.rows * base.yres / 2]
            )
        # the DEM cell under the reference point (the nearest one when it is outside)
        col = min(max(np.floor((centre[0] - base.xmin) / base.xres), 0), base.cols - 1)
        row = min(max(np.floor((base.ymax - centre[1]) / base.yres), 0), base.rows - 1)
        left, top = base.xmin + col * base.xres, base.ymax - row * base.yres
        right, bottom = left + base.xres, top - base.yres
        quad = np.array([[left, top], [right, top], [right, bottom], [left, bottom]])
        return cell_size(transform_xy(quad, self.to_layer))

    def sample(self, xy: np.ndarray) -> np.ndarray:
        """Values at (n, 2) points of the layer's CRS on the warped grid; NaN outside the DEM
        and on nodata."""
        values = np.full(len(xy), np.nan)
        if not len(xy):
            return values
        with np.errstate(invalid="ignore"):
            i = np.floor(xy[:, 0] / self.dx)
            j = np.floor(xy[:, 1] / self.dy)
        index = np.flatnonzero(np.isfinite(i) & np.isfinite(j))
        if not len(index):
            return values
        keys = (np.column_stack([i[index], j[index]]) // self.TILE).astype(np.int64)
        return self._sample_tiles(xy, index, keys, values)

    def cells(self, xmin: float, ymin: float, xmax: float, ymax: float) -> CellGrid:
        """The warped cells whose centres lie in the box (possibly none): a window of the
        cached tile that holds them all, else warped at once."""
        c0 = int(np.ceil(xmin / self.dx - 0.5))
        c1 = int(np.floor(xmax / self.dx - 0.5))
        r0 = int(np.ceil(ymin / self.dy - 0.5))
        r1 = int(np.floor(ymax / self.dy - 0.5))
        if c1 < c0 or r1 < r0:
            return CellGrid(0.0, 0.0, self.dx, self.dy, np.zeros((0, 0)))
        return self._cells(
            (xmin, ymin, xmax, ymax),
            (c0 // self.TILE, r0 // self.TILE),
            (c1 // self.TILE, r1 // self.TILE),
            lambda: self._warp(c0, c1 + 1, r0, r1 + 1),
        )

    def _load(self, key: tuple[int, int]) -> PreparedGrid:
        ti, tj = key
        c0, r0 = ti * self.TILE - self.MARGIN, tj * self.TILE - self.MARGIN
        c1, r1 = (ti + 1) * self.TILE + self.MARGIN, (tj + 1) * self.TILE + self.MARGIN
        return PreparedGrid(*self._warp(c0, c1, r0, r1))

    def _warp(self, c0: int, c1: int, r0: int, r1: int) -> tuple:
        """Cells c0:c1 (x) and r0:r1 (y, northwards) of the grid as (array with rows going
        south, GDAL geotransform, nodata NaN): the DEM block under them warped by GDAL."""
        left, right = c0 * self.dx, c1 * self.dx
        bottom, top = r0 * self.dy, r1 * self.dy
        geotransform = (left, self.dx, 0.0, top, 0.0, -self.dy)
        empty = np.full((r1 - r0, c1 - c0), np.nan)
        window = self._dem_window(left, bottom, right, top)
        if window is None:
            return empty, geotransform, np.nan
        array, source_transform, nodata = self.base.read_block(*window)
        values = array.astype(np.float64)
        invalid = ~np.isfinite(values)
        if nodata is not None:
            invalid |= values == float(nodata)
        values[invalid] = np.nan
        driver = gdal.GetDriverByName("MEM")
        source = driver.Create("", values.shape[1], values.shape[0], 1, gdal.GDT_Float64)
        source.SetGeoTransform(source_transform)
        source.SetProjection(self.dem_wkt)
        band = source.GetRasterBand(1)
        band.SetNoDataValue(np.nan)
        band.WriteArray(values)
        warped = gdal.Warp(
            "",
            source,
            format="MEM",
            srcSRS=self.dem_wkt,
            dstSRS=self.layer_wkt,
            outputBounds=(left, bottom, right, top),
            width=c1 - c0,
            height=r1 - r0,
            resampleAlg=WARP_METHODS[self.method],
            srcNodata=np.nan,
            dstNodata=np.nan,
            outputType=gdal.GDT_Float64,
            errorThreshold=0.0,
            multithread=False,
        )
        if warped is None:
            raise ValueError("GDAL could not resample the DEM into the layer's CRS")
        result = warped.GetRasterBand(1).ReadAsArray().astype(np.float64)
        return result, geotransform, np.nan

    def _dem_window(self, left: float, bottom: float, right: float, top: float):
        """(r0, r1, c0, c1) of the DEM cells under the box of the layer's CRS, with a margin;
        None when the box misses the DEM."""
        base = self.base
        steps = np.linspace(0.0, 1.0, EDGE_POINTS)
        xs = left + steps * (right - left)
        ys = bottom + steps * (top - bottom)
        edge = np.concatenate(
            [
                np.column_stack([xs, np.full_like(xs, bottom)]),
                np.column_stack([xs, np.full_like(xs, top)]),
                np.column_stack([np.full_like(ys, left), ys]),
                np.column_stack([np.full_like(ys, right), ys]),
            ]
        )
        dem = transform_xy(edge, self.to_dem)
        dem = dem[np.isfinite(dem).all(axis=1)]
        if not len(dem):
            return None
        margin = self.MARGIN + 1
        c0 = max(int(np.floor((dem[:, 0].min() - base.xmin) / base.xres)) - margin, 0)
        c1 = min(int(np.floor((dem[:, 0].max() - base.xmin) / base.xres)) + margin, base.cols)
        r0 = max(int(np.floor((base.ymax - dem[:, 1].max()) / base.yres)) - margin, 0)
        r1 = min(int(np.floor((base.ymax - dem[:, 1].min()) / base.yres)) + margin, base.rows)
        if c1 <= c0 or r1 <= r0:
            return None
        return r0, r1, c0, c1
