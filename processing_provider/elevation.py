"""Elevation sources: give every ring vertex of a batch of features its z, in bulk."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable

import numpy as np
from qgis.core import (
    NULL,
    Qgis,
    QgsCoordinateTransform,
    QgsCsException,
    QgsExpression,
    QgsExpressionContext,
    QgsGeometry,
    QgsPointXY,
    QgsRasterDataProvider,
    QgsRectangle,
)

from ..bsp_triangulate.terrain.raster_sampling import PreparedGrid, fill_along_ring
from ..bsp_triangulate.terrain.refine import CellGrid
from .geometry_io import FeatureRings

ELEVATION_NONE = 0
ELEVATION_GEOMETRY = 1
ELEVATION_EXPRESSION = 2
ELEVATION_DEM = 3
# the DEM when one is given, else the expression when one is given, else the geometry's Z
ELEVATION_AUTOMATIC = 4

INTERPOLATION_METHODS = ("bilinear", "nearest")

NODATA_FILL = 0
NODATA_FAIL = 1

_RASTER_DTYPES = {
    Qgis.DataType.Byte: np.uint8,
    Qgis.DataType.UInt16: np.uint16,
    Qgis.DataType.Int16: np.int16,
    Qgis.DataType.UInt32: np.uint32,
    Qgis.DataType.Int32: np.int32,
    Qgis.DataType.Float32: np.float32,
    Qgis.DataType.Float64: np.float64,
}

# One multipoint WKB point: byte order, type 1 (Point), x, y.
_WKB_POINT = np.dtype([("order", "u1"), ("type", "<u4"), ("x", "<f8"), ("y", "<f8")])
_WKB_MULTIPOINT_HEADER = 9


def _rings(batch: list[FeatureRings]):
    """(item, ring) for every ring of every usable feature of the batch."""
    for item in batch:
        if item.ok:
            for part in item.parts:
                for ring in part:
                    yield item, ring


class ElevationSource:
    """Sets z of the rings of a batch in place; marks features it cannot serve with an error."""

    def __init__(self) -> None:
        self.warnings: list[str] = []

    def apply(self, batch: list[FeatureRings]) -> None:
        raise NotImplementedError


class FlatElevation(ElevationSource):
    """z = 0 everywhere."""

    def apply(self, batch: list[FeatureRings]) -> None:
        for _item, ring in _rings(batch):
            ring[:, 2] = 0.0


class GeometryElevation(ElevationSource):
    """The geometry's own z; missing z (repairs, densified points) filled along the ring."""

    def apply(self, batch: list[FeatureRings]) -> None:
        for item, ring in _rings(batch):
            if not item.has_z:
                if not self.warnings:
                    self.warnings.append("the input has no Z values: z = 0 is used")
                ring[:, 2] = 0.0
                continue
            z = ring[:, 2]
            missing = ~np.isfinite(z)
            if missing.all():
                item.error = "no vertex of a ring has a Z value"
            elif missing.any():
                ring[:, 2] = fill_along_ring(np.where(missing, np.nan, z), ring[:, :2])


class ExpressionElevation(ElevationSource):
    """One z per feature from an expression evaluated on the feature."""

    def __init__(self, expression: QgsExpression, context: QgsExpressionContext) -> None:
        super().__init__()
        self.expression = expression
        self.context = context
        self.expression.prepare(self.context)

    def value(self, item: FeatureRings) -> float | str:
        """The expression's number for a feature, or the reason there is none."""
        self.context.setFeature(item.feature)
        value = self.expression.evaluate(self.context)
        if self.expression.hasEvalError():
            return f"Z expression error: {self.expression.evalErrorString()}"
        if value is None or value == NULL:
            return "Z expression returned NULL"
        try:
            number = float(value)
        except (TypeError, ValueError):
            return f"Z expression returned {value!r}, not a number"
        if not np.isfinite(number):
            return f"Z expression returned {number}"
        return number

    def apply(self, batch: list[FeatureRings]) -> None:
        for item in batch:
            if not item.ok:
                continue
            value = self.value(item)
            if isinstance(value, str):
                item.error = value
                continue
            for part in item.parts:
                for ring in part:
                    ring[:, 2] = value


def transform_xy(xy: np.ndarray, transform: QgsCoordinateTransform) -> np.ndarray:
    """Transform (n, 2) coordinates in one call via a multipoint geometry; NaN where it fails."""
    points = np.zeros(len(xy), dtype=_WKB_POINT)
    points["order"] = 1
    points["type"] = 1
    points["x"] = xy[:, 0]
    points["y"] = xy[:, 1]
    header = np.array([1], "u1").tobytes() + np.array([4, len(xy)], "<u4").tobytes()
    geometry = QgsGeometry()
    geometry.fromWkb(header + points.tobytes())
    try:
        geometry.transform(transform)
    except QgsCsException:
        return _transform_each(xy, transform)
    out = np.frombuffer(bytes(geometry.asWkb())[_WKB_MULTIPOINT_HEADER:], dtype=_WKB_POINT)
    if len(out) != len(xy):
        return _transform_each(xy, transform)
    return np.column_stack([out["x"], out["y"]])


def _transform_each(xy: np.ndarray, transform: QgsCoordinateTransform) -> np.ndarray:
    """Point by point fallback after a bulk failure, so one bad point only loses itself."""
    out = np.full_like(xy, np.nan)
    for i, (x, y) in enumerate(xy):
        try:
            point = transform.transform(QgsPointXY(float(x), float(y)))
        except QgsCsException:
            continue
        out[i] = (point.x(), point.y())
    return out


class TiledGrid:
    """A grid read in square tiles of ``TILE`` cells (and a ``MARGIN`` of cells around
    them), the last ``CACHE`` tiles kept: the tiling that ``DemSampler`` and
    ``warped_dem.WarpedDemSampler`` share. A tile is named by a pair of whole numbers; a
    subclass reads it (``_load``)."""

    TILE = 1024
    MARGIN = 2
    CACHE = 8

    def __init__(self, method: str) -> None:
        self.method = method
        self._cache: OrderedDict[tuple[int, int], PreparedGrid] = OrderedDict()

    def _load(self, key: tuple[int, int]) -> PreparedGrid:
        """The cells of tile ``key``, with its margin."""
        raise NotImplementedError

    def _tile(self, key) -> PreparedGrid:
        """Tile ``key`` (a pair), from the cache or read."""
        key = (int(key[0]), int(key[1]))
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        tile = self._load(key)
        self._cache[key] = tile
        if len(self._cache) > self.CACHE:
            self._cache.popitem(last=False)
        return tile

    def _sample_tiles(
        self, xy: np.ndarray, index: np.ndarray, keys: np.ndarray, values: np.ndarray
    ) -> np.ndarray:
        """``values`` with the points ``xy[index]`` sampled from their tiles, ``keys`` (a
        row per point, or one row when all are in one tile), tile by tile."""
        if (keys == keys[0]).all():
            # one tile (a grid of at most TILE x TILE cells, or points within one tile)
            grid = self._tile(keys[0])
            if len(index) == len(xy):
                return grid.sample(xy[:, 0], xy[:, 1], self.method)
            values[index] = grid.sample(xy[index, 0], xy[index, 1], self.method)
            return values
        order = np.lexsort((keys[:, 1], keys[:, 0]))
        keys, index = keys[order], index[order]
        starts = np.flatnonzero(np.r_[True, (keys[1:] != keys[:-1]).any(axis=1)])
        for start, stop in zip(starts, np.r_[starts[1:], len(keys)]):
            chosen = index[start:stop]
            grid = self._tile(keys[start])
            values[chosen] = grid.sample(xy[chosen, 0], xy[chosen, 1], self.method)
        return values

    def _cells(
        self,
        box: tuple[float, float, float, float],
        first: tuple[int, int],
        last: tuple[int, int],
        read: Callable[[], tuple],
    ) -> CellGrid:
        """The cells whose centres lie in ``box``: a window of the cached tile when the
        tiles of the first and last of them (``first``, ``last``) are one, else the block
        of ``read()`` (array, GDAL geotransform, nodata) at once."""
        if first == last:
            return CellGrid.from_prepared(self._tile(first)).window(*box)
        return CellGrid.from_array(*read())


class DemSampler(TiledGrid):
    """Samples one band of a raster at arrays of points, reading it in cached tiles (a
    tile's key: its row and column of tiles)."""

    def __init__(
        self,
        provider: QgsRasterDataProvider,
        band: int,
        method: str = "bilinear",
        transform: QgsCoordinateTransform | None = None,
    ) -> None:
        super().__init__(method)
        self.provider = provider
        self.band = band
        self.transform = transform
        extent = provider.extent()
        self.cols, self.rows = provider.xSize(), provider.ySize()
        if self.cols <= 0 or self.rows <= 0:
            raise ValueError("the DEM has no fixed cell size")
        self.xmin, self.ymax = extent.xMinimum(), extent.yMaximum()
        self.xres = extent.width() / self.cols
        self.yres = extent.height() / self.rows
        self.tiles_x = -(-self.cols // self.TILE)

    def sample(self, xy: np.ndarray) -> np.ndarray:
        """Values at (n, 2) points in the layer's CRS; NaN outside the DEM and on nodata."""
        if self.transform is not None and len(xy):
            xy = transform_xy(xy, self.transform)
        values = np.full(len(xy), np.nan)
        with np.errstate(invalid="ignore"):
            col = (xy[:, 0] - self.xmin) / self.xres
            row = (self.ymax - xy[:, 1]) / self.yres
        # 0 <= floor(q) < n exactly when 0 <= q < n (n whole; False for NaN and infinities)
        inside = (col >= 0) & (col < self.cols) & (row >= 0) & (row < self.rows)
        index = np.flatnonzero(inside)
        if not len(index):
            return values
        if self.tiles_x == 1 and self.rows <= self.TILE:
            keys = np.zeros((1, 2), dtype=np.int64)  # a single tile
        else:
            keys = np.column_stack([np.floor(row[index]), np.floor(col[index])]) // self.TILE
            keys = keys.astype(np.int64)
        return self._sample_tiles(xy, index, keys, values)

    def cells(self, xmin: float, ymin: float, xmax: float, ymax: float) -> CellGrid:
        """The DEM's cells whose centres lie in the box (in the DEM's CRS; possibly none),
        from the cached tile that holds them all, else read at once."""
        c0 = max(int(np.ceil((xmin - self.xmin) / self.xres - 0.5)), 0)
        c1 = min(int(np.floor((xmax - self.xmin) / self.xres - 0.5)), self.cols - 1)
        r0 = max(int(np.ceil((self.ymax - ymax) / self.yres - 0.5)), 0)
        r1 = min(int(np.floor((self.ymax - ymin) / self.yres - 0.5)), self.rows - 1)
        if c1 < c0 or r1 < r0:
            return CellGrid(self.xmin, self.ymax, self.xres, self.yres, np.zeros((0, 0)))
        return self._cells(
            (xmin, ymin, xmax, ymax),
            (r0 // self.TILE, c0 // self.TILE),
            (r1 // self.TILE, c1 // self.TILE),
            lambda: self.read_block(r0, r1 + 1, c0, c1 + 1),
        )

    def _load(self, key: tuple[int, int]) -> PreparedGrid:
        tile_row, tile_col = key
        r0 = max(tile_row * self.TILE - self.MARGIN, 0)
        r1 = min((tile_row + 1) * self.TILE + self.MARGIN, self.rows)
        c0 = max(tile_col * self.TILE - self.MARGIN, 0)
        c1 = min((tile_col + 1) * self.TILE + self.MARGIN, self.cols)
        return PreparedGrid(*self.read_block(r0, r1, c0, c1))

    def read_block(self, r0: int, r1: int, c0: int, c1: int) -> tuple:
        """Rows r0:r1, columns c0:c1 of the band (0 <= r0 < r1 <= rows, the same for the
        columns) as (array, GDAL geotransform, nodata): the cells as the provider gives
        them, those in the user's nodata ranges set to the nodata value (None when there is
        none). The tiles and ``warped_dem.WarpedDemSampler`` read the DEM through it."""
        left, top = self.xmin + c0 * self.xres, self.ymax - r0 * self.yres
        rect = QgsRectangle(left, self.ymax - r1 * self.yres, self.xmin + c1 * self.xres, top)
        block = self.provider.block(self.band, rect, c1 - c0, r1 - r0)
        if block is None or not block.isValid():
            raise ValueError(f"cannot read band {self.band} of the DEM")
        dtype = _RASTER_DTYPES.get(block.dataType())
        if dtype is None:
            raise ValueError(f"unsupported DEM data type {block.dataType()}")
        array = np.frombuffer(bytes(block.data()), dtype=dtype).reshape(r1 - r0, c1 - c0)
        nodata = block.noDataValue() if block.hasNoDataValue() else None
        user_ranges = self.provider.userNoDataValues(self.band)
        if user_ranges:
            array, nodata = _mask_ranges(array, user_ranges, nodata)
        geotransform = (left, self.xres, 0.0, top, 0.0, -self.yres)
        return array, geotransform, nodata


def _mask_ranges(array: np.ndarray, ranges, nodata: float | None) -> tuple[np.ndarray, float]:
    """Set cells inside the user's nodata ranges (bounds included) to a nodata value."""
    if nodata is None:
        nodata = -np.finfo(np.float64).max
    array = array.astype(np.float64)
    masked = np.zeros(array.shape, dtype=bool)
    for value_range in ranges:
        low, high = value_range.min(), value_range.max()
        inside = np.ones(array.shape, dtype=bool)
        if np.isfinite(low):
            inside &= array >= low
        if np.isfinite(high):
            inside &= array <= high
        masked |= inside
    array[masked] = nodata
    return array, nodata


class DemElevation(ElevationSource):
    """z sampled from a DEM band at every vertex; nodata and outside cells filled or failed."""

    def __init__(self, sampler: DemSampler, nodata_policy: int = NODATA_FILL) -> None:
        super().__init__()
        self.sampler = sampler
        self.nodata_policy = nodata_policy
        # features with vertices outside the DEM or on nodata whose z was filled
        self.filled = 0

    def apply(self, batch: list[FeatureRings]) -> None:
        usable = [item for item in batch if item.ok]
        if not usable:
            return
        # the z columns to fill, in ring order: runs of rows of one array where the reader
        # left the rings one after another, single rings elsewhere
        targets = _z_targets(usable)
        xy = np.concatenate([target[:, :2] for target in targets])
        values = self.sampler.sample(xy)
        position = 0
        for target in targets:
            target[:, 2] = values[position : position + len(target)]
            position += len(target)
        missing_values = np.isnan(values)
        if not missing_values.any():
            return
        # missing values per ring, counted for all rings at once; only those rings need more
        rings = [ring for item in usable for part in item.parts for ring in part]
        owners = [item for item in usable for part in item.parts for _ring in part]
        lengths = np.fromiter(map(len, rings), dtype=np.int64, count=len(rings))
        offsets = np.concatenate([[0], np.cumsum(lengths)])
        ring_of_value = np.repeat(np.arange(len(rings)), lengths)
        missing_counts = np.bincount(ring_of_value[missing_values], minlength=len(rings))
        filled: set[int] = set()
        for index in np.flatnonzero(missing_counts).tolist():
            item, ring = owners[index], rings[index]
            if item.error is not None:
                continue
            z = values[offsets[index] : offsets[index + 1]]
            missing = int(missing_counts[index])
            if missing == len(z):
                item.error = "no vertex of a ring lies on a valid DEM cell"
            elif self.nodata_policy == NODATA_FAIL:
                item.error = (
                    f"{missing} of {len(z)} vertices of a ring fall on DEM nodata "
                    "or outside the DEM"
                )
            else:
                ring[:, 2] = fill_along_ring(z, ring[:, :2])
                filled.add(id(item))
        self.filled += len(filled)


def _z_targets(items: list[FeatureRings]) -> list[np.ndarray]:
    """The rows holding the items' rings, in order: one view per run of items whose blocks
    follow each other in one array, one view per ring of the other items."""
    targets: list[np.ndarray] = []
    run_array, run_start, run_stop = None, 0, 0
    for item in items:
        block = item.block
        if block is not None and block[0] is run_array and block[1] == run_stop:
            run_stop = block[2]
            continue
        if run_array is not None:
            targets.append(run_array[run_start:run_stop])
            run_array = None
        if block is not None:
            run_array, run_start, run_stop = block
        else:
            targets.extend(ring for part in item.parts for ring in part)
    if run_array is not None:
        targets.append(run_array[run_start:run_stop])
    return targets


def scale_z(batch: list[FeatureRings], scale: float, offset: float) -> None:
    """z = z * scale + offset on every ring of the usable features."""
    if scale == 1.0 and offset == 0.0:
        return
    for _item, ring in _rings(batch):
        ring[:, 2] = ring[:, 2] * scale + offset
