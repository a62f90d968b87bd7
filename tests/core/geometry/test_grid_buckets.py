"""The grids' bucket starts, counted instead of searched: the same arrays as a search of
every cell in the sorted cell numbers."""

import numpy as np
import pytest

from bsp_triangulate.geometry.spatial_index import (
    _GRID_DISC,
    ChainBoxes,
    PointColumns,
    SegmentGrid,
    bucket_starts,
)


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


def _descent_near(boxes: ChainBoxes, lo: int, hi: int, disc: tuple) -> list[tuple[int, int]]:
    return list(boxes._leaves(lo, hi, -1, None, disc))


@pytest.mark.parametrize("seed", range(4))
def test_chain_leaves_near_a_small_disc_hold_every_leaf_of_the_descent(seed: int) -> None:
    rng = np.random.default_rng(seed)
    count = 4001 + seed  # the last leaf shorter than the others
    angles = np.sort(rng.uniform(0, 2 * np.pi, count))
    radii = 1000.0 * (1.0 + 0.1 * np.sin(40 * angles)) + rng.uniform(-5, 5, count)
    x, y = radii * np.cos(angles), radii * np.sin(angles)
    x, y = np.append(x, x[0]), np.append(y, y[0])
    boxes = ChainBoxes(x, y)
    gridded = 0
    for trial in range(300):
        lo = int(rng.integers(0, count - 1000))
        hi = int(rng.integers(lo + 2, count + 1))
        p = int(rng.integers(0, count))
        # some centres off the chain, a few off the grid's frame
        ox, oy = float(x[p]), float(y[p])
        if trial % 3 == 0:
            ox, oy = ox + rng.uniform(-80, 80), oy + rng.uniform(-80, 80)
        if trial % 50 == 0:
            ox += 3000.0
        disc = (ox, oy, float(rng.uniform(0.0, 60.0)) ** 2)
        runs = list(boxes.leaves_near(lo, hi, disc))
        gridded += disc[2] <= _GRID_DISC**2 * boxes._grid_cell2()
        assert runs == sorted(runs)
        assert all(lo <= start < end <= hi for start, end in runs)
        assert set(_descent_near(boxes, lo, hi, disc)) <= set(runs)
        # every point of the range in the disc starts a segment of the runs
        inside = {q for q in range(lo, hi) if (x[q] - ox) ** 2 + (y[q] - oy) ** 2 <= disc[2]}
        assert inside <= {q for start, end in runs for q in range(start, end)}
    assert gridded > 100  # most discs took the grid


def test_chain_leaves_near_a_disc_the_grid_cannot_place_come_from_the_descent() -> None:
    x = np.linspace(0.0, 100.0, 50)
    boxes = ChainBoxes(x, np.sin(x))
    for disc in ((np.nan, 0.0, 4.0), (np.inf, 0.0, 4.0), (10.0, 0.0, -1.0)):
        assert list(boxes.leaves_near(0, 49, disc)) == _descent_near(boxes, 0, 49, disc)
