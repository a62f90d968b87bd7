"""Rule "delaunay" with interior points: the points inserted into the rings' triangulation
give the recursion's tree, field by field (docs/algorithm.md, section 5b)."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.tree import one_polygon

from ..random_polygons import random_polygon
from ..test_points import check_with_points, random_points

FIELDS = ("vertices", "triangles", "parent", "depth", "side", "point_ids")


def both_ways(
    rings: list, points: np.ndarray, monkeypatch: pytest.MonkeyPatch
) -> tuple[object, object, bool]:
    """The result by insertion, the recursion's, and whether insertion gave the first."""
    taken = []
    original = one_polygon._delaunay_by_insertion

    def spy(*args: object) -> object:
        result = original(*args)
        taken.append(result is not None)
        return result

    with monkeypatch.context() as patch:
        patch.setattr(one_polygon, "_delaunay_by_insertion", spy)
        inserted = triangulate(rings, points=points, rule="delaunay")
    with monkeypatch.context() as patch:
        patch.setattr(one_polygon, "_delaunay_by_insertion", lambda *args: None)
        recursion = triangulate(rings, points=points, rule="delaunay")
    return inserted, recursion, any(taken)


def assert_same(inserted: object, recursion: object) -> None:
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(inserted, name), getattr(recursion, name), name)


@pytest.mark.parametrize("seed", range(30))
def test_random_polygons_with_islands_and_points_equal_the_recursion(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    rnd = random.Random(seed)
    rings = random_polygon(rnd, islands=rnd.randint(0, 4), integer=seed % 2 == 0)
    points = random_points(rnd, rings, rnd.choice((5, 40, 120)))
    inserted, recursion, by_insertion = both_ways(rings, points, monkeypatch)
    assert by_insertion or (inserted.point_ids < 0).all()
    assert_same(inserted, recursion)
    check_with_points(rings, points, inserted, "delaunay")


@pytest.mark.parametrize("clockwise", [False, True])
def test_cell_centres_with_cocircular_ties_equal_the_recursion(
    clockwise: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    # DEM-like cell centres: every four neighbours are cocircular, decided by the tie rule
    outer = [(0.0, 0.0), (31.0, 0.0), (31.0, 31.0), (15.5, 22.0), (0.0, 31.0)]
    island = [(8.2, 8.2), (8.2, 12.8), (12.8, 12.8), (12.8, 8.2)]
    if clockwise:
        outer, island = outer[::-1], island[::-1]
    rnd = random.Random(3)
    centres = [(i + 0.5, j + 0.5) for i in range(31) for j in range(31)]
    points = np.array(rnd.sample(centres, 500))
    rings = [outer, island]
    inserted, recursion, by_insertion = both_ways(rings, points, monkeypatch)
    assert by_insertion
    assert_same(inserted, recursion)
    check_with_points(rings, points, inserted, "delaunay")
