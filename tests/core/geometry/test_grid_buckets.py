"""The grids' bucket starts, counted instead of searched: the same arrays as a search of
every cell in the sorted cell numbers."""

import numpy as np
import pytest

from bsp_triangulate.geometry.spatial_index import PointColumns, SegmentGrid, bucket_starts


@pytest.mark.parametrize("items, cells", [(0, 1), (1, 1), (5, 40), (1_000, 37), (3_000, 20_000)])
def test_bucket_starts_are_the_searched_ones(items: int, cells: int) -> None:
    cell = np.random.default_rng(items + cells).integers(0, cells, items)
    searched = np.searchsorted(np.sort(cell), np.arange(cells + 1))
    assert np.array_equal(bucket_starts(cell, cells), searched)


def test_grids_find_their_items_by_the_counted_starts() -> None:
    rng = np.random.default_rng(7)
    # a cluster in a wide frame: most cells empty, a few crowded
    x = np.concatenate([rng.uniform(0, 1, 500), rng.uniform(0, 1000, 50)])
    y = np.concatenate([rng.uniform(0, 1, 500), rng.uniform(0, 1000, 50)])
    points = PointColumns(x, y)
    cells = points._col(x) * points.ny + points._row(y)
    for k in np.unique(cells).tolist():
        held = points.order[points.starts[k] : points.starts[k + 1]]
        assert sorted(held.tolist()) == np.flatnonzero(cells == k).tolist()
    grid = SegmentGrid(x[:-1], y[:-1], x[1:], y[1:])
    assert grid.starts[-1] == len(grid.items)
    assert (np.diff(grid.starts) >= 0).all()
    # every segment is found in the cell of its first end
    for s in range(0, len(x) - 1, 37):
        assert s in grid.query_box(x[s], y[s], x[s], y[s]).tolist()
