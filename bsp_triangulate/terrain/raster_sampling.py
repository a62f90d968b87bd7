"""Vectorised sampling of a raster grid (e.g. a DEM) at points, and gap filling along rings.

Pixel convention as GDAL: the geotransform maps pixel/line coordinates (col, row) to
``x = gt[0] + col * gt[1] + row * gt[2]`` and ``y = gt[3] + col * gt[4] + row * gt[5]``; (0, 0)
is the outer corner of the first cell and cell (r, c) has its centre at (c + 0.5, r + 0.5).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def world_to_pixel(
    geotransform: Sequence[float], xs: np.ndarray, ys: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Fractional (col, row) of world points through the inverse of a GDAL geotransform."""
    gt = [float(v) for v in geotransform]
    det = gt[1] * gt[5] - gt[2] * gt[4]
    if det == 0:
        raise ValueError(f"geotransform {tuple(gt)} is not invertible")
    dx = np.asarray(xs, dtype=np.float64) - gt[0]
    dy = np.asarray(ys, dtype=np.float64) - gt[3]
    if gt[2] == 0 and gt[4] == 0:
        return dx / gt[1], dy / gt[5]
    cols = (gt[5] * dx - gt[2] * dy) / det
    rows = (gt[1] * dy - gt[4] * dx) / det
    return cols, rows


def sample_grid(
    array: np.ndarray,
    geotransform: Sequence[float],
    xs: np.ndarray,
    ys: np.ndarray,
    method: str = "bilinear",
    nodata: float | None = None,
) -> np.ndarray:
    """Raster values at the points (xs, ys); NaN where there is no value.

    - ``nearest``: the value of the cell containing the point (points on the raster's right or
      bottom outer edge belong to the last cell); NaN outside the raster or on a nodata/NaN cell.
    - ``bilinear``: interpolation between the four cell centres around the point. Neighbours
      that are nodata/NaN or lie beyond the raster (the half-cell border) are left out and the
      remaining weights renormalised, i.e. the weighted mean of the valid neighbours; NaN when
      no neighbour with a positive weight is valid or the point is outside the raster extent.
    """
    return PreparedGrid(array, geotransform, nodata).sample(xs, ys, method)


class PreparedGrid:
    """A raster grid prepared for repeated sampling (``sample``, as ``sample_grid`` describes).

    The values are kept as float64 with a border of one cell, and every cell without a value
    (nodata, NaN, infinite, or beyond the grid) is NaN: a neighbour's index needs no clipping
    and its validity is one NaN test.
    """

    def __init__(
        self, array: np.ndarray, geotransform: Sequence[float], nodata: float | None = None
    ) -> None:
        grid = np.asarray(array)
        if grid.ndim != 2:
            raise ValueError("the raster array must be 2-D (rows, cols)")
        self.rows, self.cols = grid.shape
        self.geotransform = geotransform
        values = grid.astype(np.float64)
        valid = np.isfinite(values)
        if nodata is not None and not np.isnan(nodata):
            if grid.dtype.kind == "f":  # a float32 nodata compares equal in its own precision
                valid &= grid != grid.dtype.type(nodata)
            else:
                valid &= values != float(nodata)
        padded = np.full((self.rows + 2, self.cols + 2), np.nan)
        padded[1:-1, 1:-1] = np.where(valid, values, np.nan)
        self.width = self.cols + 2
        self.values = padded.ravel()

    def sample(self, xs: np.ndarray, ys: np.ndarray, method: str = "bilinear") -> np.ndarray:
        """Values at the points (xs, ys), NaN where there is none (see ``sample_grid``)."""
        rows_n, cols_n, width = self.rows, self.cols, self.width
        cols, rows = world_to_pixel(self.geotransform, xs, ys)
        shape = cols.shape
        cols, rows = cols.ravel(), rows.ravel()
        inside = (cols >= 0) & (cols <= cols_n) & (rows >= 0) & (rows <= rows_n)
        every = bool(inside.all())
        if not every:
            cols, rows = cols[inside], rows[inside]
        if method == "nearest":
            c = np.clip(np.floor(cols).astype(np.int64), 0, cols_n - 1)
            r = np.clip(np.floor(rows).astype(np.int64), 0, rows_n - 1)
            found = self.values[(r + 1) * width + (c + 1)]
        elif method == "bilinear":
            found = self._bilinear(cols, rows)
        else:
            raise ValueError(f"unknown sampling method {method!r}; use 'bilinear' or 'nearest'")
        if every:
            return found.reshape(shape)
        result = np.full(inside.shape, np.nan)
        result[inside] = found
        return result.reshape(shape)

    def _bilinear(self, cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """``sample_grid``'s bilinear arithmetic, operation for operation."""
        width = self.width
        u = cols - 0.5
        v = rows - 0.5
        c0 = np.floor(u).astype(np.int64)
        r0 = np.floor(v).astype(np.int64)
        fu = u - c0
        fv = v - r0
        gu = 1 - fu
        gv = 1 - fv
        first = (r0 + 1) * width + (c0 + 1)
        neighbours = ((0, gu * gv), (1, fu * gv), (width, gu * fv), (width + 1, fu * fv))
        with np.errstate(invalid="ignore", divide="ignore"):
            if (gu > 0).all() and (fu > 0).all() and (gv > 0).all() and (fv > 0).all():
                # every weight positive: where no neighbour lacks a value (no NaN comes
                # out), every neighbour is used and no masking is needed
                total = np.zeros(u.shape)
                weight_sum = np.zeros(u.shape)
                for offset, weight in neighbours:
                    total += weight * self.values[first + offset]
                    weight_sum += weight
                if not np.isnan(total).any():
                    return np.where(weight_sum > 0, total / weight_sum, np.nan)
            total = np.zeros(u.shape)
            weight_sum = np.zeros(u.shape)
            for offset, weight in neighbours:
                cell = self.values[first + offset]
                unused = np.isnan(cell) | ~(weight > 0)
                term = weight * cell
                if unused.any():
                    term[unused] = 0.0
                    weight = np.where(unused, 0.0, weight)
                total += term
                weight_sum += weight
            return np.where(weight_sum > 0, total / weight_sum, np.nan)


def fill_along_ring(values: np.ndarray, xy: np.ndarray | None = None) -> np.ndarray:
    """Fill NaNs of a closed ring's values from the nearest valid values on both sides.

    A run of NaNs is interpolated linearly between the valid value before it and the valid
    value after it, going round the ring cyclically (so a gap over the first vertex is bridged
    by the last valid value). Position along the ring is the vertex index, or the XY arc length
    when ``xy`` (n, 2+) is given (a repeated closing point is just a zero-length edge). A single
    valid value fills everything. Raises ValueError if no value is valid.
    """
    values = np.asarray(values, dtype=np.float64)
    missing = np.isnan(values)
    if not missing.any():
        return values.copy()
    if missing.all():
        raise ValueError("no valid value on the ring to fill from")
    n = len(values)
    position = np.arange(n, dtype=np.float64)
    period = float(n)
    if xy is not None:
        xy = np.asarray(xy, dtype=np.float64)[:, :2]
        steps = np.hypot(*(np.roll(xy, -1, axis=0) - xy).T)
        if steps.sum() > 0:
            position = np.concatenate([[0.0], np.cumsum(steps[:-1])])
            period = float(steps.sum())
    filled = values.copy()
    valid = ~missing
    filled[missing] = np.interp(position[missing], position[valid], values[valid], period=period)
    return filled
