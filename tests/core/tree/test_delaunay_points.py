"""Rule "delaunay" with interior points: the points inserted into the rings' triangulation
give the recursion's tree, field by field (docs/algorithm.md, section 5b)."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.geometry import bridges
from bsp_triangulate.geometry.predicates import exact_sq_distance, sq_distance_exact
from bsp_triangulate.tree import one_polygon

from ..random_polygons import random_polygon
from ..test_points import check_with_points, random_points

FIELDS = ("vertices", "triangles", "parent", "depth", "side", "point_ids")


def both_ways(
    rings: list, points: np.ndarray, monkeypatch: pytest.MonkeyPatch, shortcuts: list | None = None
) -> tuple[object, object, bool]:
    """The result by insertion, the recursion's, and whether insertion gave the first.

    The bridged sequence made with the mesh's edges (segment tests skipped) is checked equal
    to the one made without; ``shortcuts`` gets the number of tests each skipped."""
    taken = []
    original = one_polygon._delaunay_by_insertion
    original_bridges = one_polygon.bridge_islands

    def spy(*args: object) -> object:
        result = original(*args)
        taken.append(result is not None)
        return result

    def checked_bridges(*args: object, mesh_edges: object = None, **kwargs: object) -> object:
        sequence = original_bridges(*args, mesh_edges=mesh_edges, **kwargs)
        if mesh_edges is not None:
            np.testing.assert_array_equal(sequence, original_bridges(*args, **kwargs))
            if shortcuts is not None:
                shortcuts.append(mesh_edges.used)
        return sequence

    with monkeypatch.context() as patch:
        patch.setattr(one_polygon, "_delaunay_by_insertion", spy)
        patch.setattr(one_polygon, "bridge_islands", checked_bridges)
        inserted = triangulate(rings, points=points, rule="delaunay")
    with monkeypatch.context() as patch:
        # the recursion over the sequence made without the mesh's edges
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
    shortcuts: list[int] = []
    inserted, recursion, by_insertion = both_ways(rings, points, monkeypatch, shortcuts)
    assert by_insertion
    assert shortcuts and shortcuts[0] > 400  # most links are mesh edges: no segment test
    assert_same(inserted, recursion)
    check_with_points(rings, points, inserted, "delaunay")


def test_link_across_an_island_takes_the_slow_bridge(monkeypatch: pytest.MonkeyPatch) -> None:
    # the two points are each other's nearest vertex, but the thin island lies between them:
    # that link is no mesh edge, its segment is tested and the circle-tested bridge taken
    outer = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
    island = [(1.0, 5.0), (1.0, 5.2), (9.0, 5.2), (9.0, 5.0)]
    points = np.array([(5.0, 4.5), (5.0, 5.6), (2.0, 2.0), (7.5, 8.0)])
    slow = []
    original = bridges.delaunay_point_bridge

    def spy(bridger: object, h: int, *args: object) -> object:
        result = original(bridger, h, *args)
        slow.append(h)
        return result

    monkeypatch.setattr(bridges, "delaunay_point_bridge", spy)
    shortcuts: list[int] = []
    rings = [outer, island]
    inserted, recursion, by_insertion = both_ways(rings, points, monkeypatch, shortcuts)
    assert by_insertion
    assert slow and shortcuts and shortcuts[0] > 0
    assert_same(inserted, recursion)
    check_with_points(rings, points, inserted, "delaunay")


def test_mesh_edges_hold_the_rings_or_are_not_used() -> None:
    x = np.array([0.0, 4.0, 4.0, 0.0, 1.0])
    y = np.array([0.0, 0.0, 4.0, 4.0, 1.0])
    ring = np.arange(4, dtype=np.int64)
    point = np.array([4], dtype=np.int64)
    fan = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    edges = bridges.MeshEdges(fan, len(x))
    assert edges.holds_rings([ring, point])
    assert (4, 0) in edges and (0, 2) not in edges
    # a mesh without the ring edge 2-3 does not spare any test
    partial = bridges.MeshEdges(fan[:2], len(x))
    assert not partial.holds_rings([ring, point])
    plain = bridges.bridge_islands(x, y, [ring, point], [0, -1], delaunay=True)
    with_partial = bridges.bridge_islands(
        x, y, [ring, point], [0, -1], delaunay=True, mesh_edges=partial
    )
    np.testing.assert_array_equal(plain, with_partial)
    assert partial.used == 0
    with_edges = bridges.bridge_islands(
        x, y, [ring, point], [0, -1], delaunay=True, mesh_edges=edges
    )
    np.testing.assert_array_equal(plain, with_edges)
    assert edges.used == 1


def test_sq_distance_exact_orders_as_the_exact_distance() -> None:
    rnd = random.Random(5)
    special = [0.0, -0.0, 5e-324, -5e-324, 1e308, -1e308, 0.5, 1.5, 1e-300, 0.1, 0.3]
    pairs = []
    for _ in range(300):
        c = [
            rnd.choice(special)
            if rnd.random() < 0.3
            else rnd.uniform(-1e3, 1e3) * 10.0 ** rnd.randint(-8, 8)
            for _ in range(4)
        ]
        pairs.append((exact_sq_distance(*c), sq_distance_exact(*c)))
    for (e1, k1), (e2, k2) in zip(pairs, pairs[1:]):
        assert (e1 < e2) == (k1 < k2) and (e1 == e2) == (k1 == k2)
    assert sq_distance_exact(0.5, 0.5, 0.5, 1.5) == 2**2148


@pytest.mark.parametrize("seed", range(4))
def test_many_islands_and_points_equal_the_recursion(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # more than 16 islands: their bridges follow links (geometry/delaunay_links.py), which
    # must be edges of the mesh with the points as well
    from ..geometry.test_bridge_plan import scattered_squares

    rnd = random.Random(seed)
    rings = [ring.tolist() for ring in scattered_squares(seed, count=24)]
    points = random_points(rnd, rings, rnd.choice((40, 300)))
    inserted, recursion, by_insertion = both_ways(rings, points, monkeypatch)
    assert by_insertion
    assert_same(inserted, recursion)
    check_with_points(rings, points, inserted, "delaunay")
