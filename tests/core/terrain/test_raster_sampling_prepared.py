"""PreparedGrid.sample (behind sample_grid) against a plain formulation of the sampling: the
same bits for every grid, nodata and point."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from bsp_triangulate.terrain.raster_sampling import PreparedGrid, world_to_pixel

GT = (1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0)


def _gather(
    grid: np.ndarray, rows: np.ndarray, cols: np.ndarray, nodata: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """Cell values as float64 and whether each is valid (finite and not nodata)."""
    values = grid[rows, cols].astype(np.float64)
    valid = np.isfinite(values)
    if nodata is not None and not np.isnan(nodata):
        if grid.dtype.kind == "f":  # a float32 nodata compares equal in its own precision
            valid &= grid[rows, cols] != grid.dtype.type(nodata)
        else:
            valid &= values != float(nodata)
    return values, valid


def reference_sample_grid(
    array: np.ndarray,
    geotransform: Sequence[float],
    xs: np.ndarray,
    ys: np.ndarray,
    method: str = "bilinear",
    nodata: float | None = None,
) -> np.ndarray:
    """``sample_grid`` as it was first written (clipped neighbours, a validity mask per
    gather): the independent formulation the prepared grid must match bit for bit.

    - ``nearest``: the value of the cell containing the point (points on the raster's right or
      bottom outer edge belong to the last cell); NaN outside the raster or on a nodata/NaN cell.
    - ``bilinear``: interpolation between the four cell centres around the point. Neighbours
      that are nodata/NaN or lie beyond the raster (the half-cell border) are left out and the
      remaining weights renormalised, i.e. the weighted mean of the valid neighbours; NaN when
      no neighbour with a positive weight is valid or the point is outside the raster extent.
    """
    grid = np.asarray(array)
    if grid.ndim != 2:
        raise ValueError("the raster array must be 2-D (rows, cols)")
    rows_n, cols_n = grid.shape
    cols, rows = world_to_pixel(geotransform, xs, ys)
    shape = cols.shape
    cols, rows = cols.ravel(), rows.ravel()
    inside = (cols >= 0) & (cols <= cols_n) & (rows >= 0) & (rows <= rows_n)
    result = np.full(cols.shape, np.nan)
    if method == "nearest":
        c = np.clip(np.floor(cols[inside]).astype(np.int64), 0, cols_n - 1)
        r = np.clip(np.floor(rows[inside]).astype(np.int64), 0, rows_n - 1)
        cell, ok = _gather(grid, r, c, nodata)
        result[inside] = np.where(ok, cell, np.nan)
        return result.reshape(shape)
    if method != "bilinear":
        raise ValueError(f"unknown sampling method {method!r}; use 'bilinear' or 'nearest'")
    u = cols[inside] - 0.5
    v = rows[inside] - 0.5
    c0 = np.floor(u).astype(np.int64)
    r0 = np.floor(v).astype(np.int64)
    fu = u - c0
    fv = v - r0
    total = np.zeros(u.shape)
    weight_sum = np.zeros(u.shape)
    for dr, dc, weight in (
        (0, 0, (1 - fu) * (1 - fv)),
        (0, 1, fu * (1 - fv)),
        (1, 0, (1 - fu) * fv),
        (1, 1, fu * fv),
    ):
        r = r0 + dr
        c = c0 + dc
        on_grid = (r >= 0) & (r < rows_n) & (c >= 0) & (c < cols_n)
        rc = np.clip(r, 0, rows_n - 1)
        cc = np.clip(c, 0, cols_n - 1)
        cell, ok = _gather(grid, rc, cc, nodata)
        use = on_grid & ok & (weight > 0)
        total += np.where(use, weight * np.where(use, cell, 0.0), 0.0)
        weight_sum += np.where(use, weight, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        result[inside] = np.where(weight_sum > 0, total / weight_sum, np.nan)
    return result.reshape(shape)


def _points(rng: np.random.Generator, rows: int, cols: int, count: int) -> tuple:
    """World points: anywhere around the grid, on cell centres, on cell edges and corners."""
    col = np.concatenate(
        [
            rng.uniform(-2, cols + 2, count),
            np.floor(rng.uniform(0, cols, count)) + 0.5,
            np.floor(rng.uniform(0, cols + 1, count)),
            np.array([0.0, cols, 0.5, cols - 0.5, np.nan, -1e-300]),
        ]
    )
    row = np.concatenate(
        [
            rng.uniform(-2, rows + 2, count),
            np.floor(rng.uniform(0, rows, count)) + 0.5,
            np.floor(rng.uniform(0, rows + 1, count)),
            np.array([0.0, rows, rows - 0.5, 0.5, 1.0, np.inf]),
        ]
    )
    return GT[0] + col * GT[1], GT[3] + row * GT[5]


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("method", ["bilinear", "nearest"])
@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.int32, np.float32, np.float64])
def test_prepared_grid_samples_the_same_bits_as_the_reference(method, dtype):
    rng = np.random.default_rng(5)
    for trial in range(20):
        rows, cols = (int(v) for v in rng.integers(1, 9, 2))
        grid = rng.integers(0, 100, (rows, cols)).astype(dtype)
        if np.dtype(dtype).kind == "f":
            grid = (grid - 50.5).astype(dtype)
            grid[rng.random((rows, cols)) < 0.1] = np.nan
            grid[rng.random((rows, cols)) < 0.05] = np.inf
            grid[rng.random((rows, cols)) < 0.05] = -0.0
        nodata = [None, float(grid.flat[0]), -9999.0, np.nan][trial % 4]
        xs, ys = _points(rng, rows, cols, 200)
        expected = reference_sample_grid(grid, GT, xs, ys, method, nodata)
        got = PreparedGrid(grid, GT, nodata).sample(xs, ys, method)
        assert _same_bits(got, expected)
        col, row = (xs - GT[0]) / GT[1], (ys - GT[3]) / GT[5]
        inside = (col >= 0) & (col <= cols) & (row >= 0) & (row <= rows)
        got = PreparedGrid(grid, GT, nodata).sample(xs[inside], ys[inside], method)
        expected = reference_sample_grid(grid, GT, xs[inside], ys[inside], method, nodata)
        assert _same_bits(got, expected)


def test_points_all_inside_and_a_two_dimensional_request_keep_their_shape():
    grid = np.arange(12, dtype=np.float32).reshape(3, 4)
    xs, ys = np.meshgrid(GT[0] + np.linspace(0, 40, 5), GT[3] - np.linspace(0, 30, 4))
    for method in ("bilinear", "nearest"):
        got = PreparedGrid(grid, GT).sample(xs, ys, method)
        assert _same_bits(got, reference_sample_grid(grid, GT, xs, ys, method))


def test_errors_match_sample_grid():
    with pytest.raises(ValueError, match="2-D"):
        PreparedGrid(np.zeros(3), GT)
    with pytest.raises(ValueError, match="unknown sampling method"):
        PreparedGrid(np.zeros((2, 2)), GT).sample([1005.0], [1995.0], method="cubic")


@pytest.mark.parametrize("holes", [False, True])
def test_points_away_from_cell_centres_take_the_unmasked_path_with_the_same_bits(holes):
    rng = np.random.default_rng(9)
    grid = rng.normal(100, 30, (40, 50)).astype(np.float32)
    if holes:
        grid[rng.random(grid.shape) < 0.02] = -9999.0
    col = rng.uniform(0, 50, 20_000)
    row = rng.uniform(0, 40, 20_000)
    xs, ys = GT[0] + col * GT[1], GT[3] + row * GT[5]
    expected = reference_sample_grid(grid, GT, xs, ys, "bilinear", -9999.0)
    got = PreparedGrid(grid, GT, -9999.0).sample(xs, ys, "bilinear")
    assert _same_bits(got, expected)
