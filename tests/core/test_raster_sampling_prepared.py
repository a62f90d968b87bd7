"""PreparedGrid.sample against sample_grid: the same bits for every grid, nodata and point."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.raster_sampling import PreparedGrid, sample_grid

GT = (1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0)


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
def test_prepared_grid_samples_the_same_bits_as_sample_grid(method, dtype):
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
        expected = sample_grid(grid, GT, xs, ys, method, nodata)
        got = PreparedGrid(grid, GT, nodata).sample(xs, ys, method)
        assert _same_bits(got, expected)
        col, row = (xs - GT[0]) / GT[1], (ys - GT[3]) / GT[5]
        inside = (col >= 0) & (col <= cols) & (row >= 0) & (row <= rows)
        got = PreparedGrid(grid, GT, nodata).sample(xs[inside], ys[inside], method)
        assert _same_bits(got, sample_grid(grid, GT, xs[inside], ys[inside], method, nodata))


def test_points_all_inside_and_a_two_dimensional_request_keep_their_shape():
    grid = np.arange(12, dtype=np.float32).reshape(3, 4)
    xs, ys = np.meshgrid(GT[0] + np.linspace(0, 40, 5), GT[3] - np.linspace(0, 30, 4))
    for method in ("bilinear", "nearest"):
        got = PreparedGrid(grid, GT).sample(xs, ys, method)
        assert _same_bits(got, sample_grid(grid, GT, xs, ys, method))


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
    expected = sample_grid(grid, GT, xs, ys, "bilinear", -9999.0)
    got = PreparedGrid(grid, GT, -9999.0).sample(xs, ys, "bilinear")
    assert _same_bits(got, expected)
