"""Rule "delaunay" with interior points: the points inserted into the rings' triangulation
and the tree read off it breadth-first give the recursion's triangles, as a valid BSP
tree (docs/algorithm.md, section 5b)."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate import PackedPolygons, triangulate, triangulate_many, triangulate_packed
from bsp_triangulate.geometry import bridges
from bsp_triangulate.geometry.predicates import exact_sq_distance, sq_distance_exact
from bsp_triangulate.tree import one_polygon
from bsp_triangulate.tree.delaunay_points import tree_of_cdt
from bsp_triangulate.tree.points_batch import InsertedMesh

from ..checks import check_tree
from ..random_polygons import random_polygon
from ..test_points import check_with_points, random_points


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
        # the recursion over the sequence of section 2a
        patch.setattr(one_polygon, "_delaunay_by_insertion", lambda *args: None)
        recursion = triangulate(rings, points=points, rule="delaunay")
    return inserted, recursion, any(taken)


def triangle_set(triangles: np.ndarray) -> set[tuple[int, int, int]]:
    """The triangles, each from its smallest vertex id on (orientation kept)."""
    return {tuple(t[t.index(min(t)) :] + t[: t.index(min(t))]) for t in triangles.tolist()}


def assert_same_fields(got: object, want: object) -> None:
    """Every field equal."""
    for name in ("vertices", "triangles", "parent", "depth", "side", "point_ids"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), name)


def assert_same(inserted: object, recursion: object) -> None:
    """The same vertices, point rows and triangles; the trees may differ (other bridges)."""
    for name in ("vertices", "point_ids"):
        np.testing.assert_array_equal(getattr(inserted, name), getattr(recursion, name), name)
    assert len(inserted.triangles) == len(recursion.triangles)
    assert triangle_set(inserted.triangles) == triangle_set(recursion.triangles)


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


def test_link_across_an_island_takes_the_slow_bridge(monkeypatch: pytest.MonkeyPatch) -> None:
    # the two points are each other's nearest vertex, but the thin island lies between them:
    # the recursion tests that link's segment and takes the circle-tested bridge; insertion
    # needs no bridge, and both give the same triangles
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
    rings = [outer, island]
    inserted, recursion, by_insertion = both_ways(rings, points, monkeypatch)
    assert by_insertion
    assert slow
    assert_same(inserted, recursion)
    check_with_points(rings, points, inserted, "delaunay")


def fan_of_square() -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """A square with a point at its centre, triangulated as a fan: vertices, triangles, walls."""
    vertices = np.array([[0.0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0], [2, 2, 0]])
    fan = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    walls = (np.arange(4), np.array([1, 2, 3, 0]))
    return vertices, fan, walls


def test_the_tree_grows_level_by_level_and_leaves_one_bridge_per_point() -> None:
    vertices, fan, walls = fan_of_square()
    result = tree_of_cdt(fan, vertices, walls, mirrored=False)
    # root on 0 -> 1; its children across 0 4 (left) and 1 4 (right) make level 1; both reach
    # the last triangle (across 4 3 and across 4 2), and the left child, first in the level,
    # takes it: 2 4 stays the one bridge. Rows in pre-order
    np.testing.assert_array_equal(result.triangles, [[0, 1, 4], [0, 4, 3], [3, 4, 2], [4, 1, 2]])
    np.testing.assert_array_equal(result.parent, [-1, 0, 1, 0])
    np.testing.assert_array_equal(result.depth, [0, 1, 2, 1])
    np.testing.assert_array_equal(result.side, [0, 1, 2, 2])
    check_tree(result.triangles, result.parent, result.depth, result.side)
    mirrored = tree_of_cdt(fan, vertices, walls, mirrored=True)
    np.testing.assert_array_equal(mirrored.triangles, result.triangles[:, [1, 0, 2]])


def test_a_mesh_that_does_not_triangulate_the_rings_gives_no_tree() -> None:
    vertices, fan, walls = fan_of_square()
    assert tree_of_cdt(fan[1:], vertices, walls, mirrored=False) is None  # a gap
    assert tree_of_cdt(np.vstack([fan, fan[:1]]), vertices, walls, mirrored=False) is None
    # a ring edge that is no edge of the mesh
    assert tree_of_cdt(fan, vertices, (np.array([0, 0]), np.array([1, 2])), False) is None
    # two pieces that share no edge: the walk does not reach the second
    apart = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 0], [6, 5, 0], [5, 6, 0]])
    pieces = np.array([[0, 1, 2], [3, 4, 5]])
    rims = (np.arange(6), np.array([1, 2, 0, 4, 5, 3]))
    assert tree_of_cdt(pieces, apart, rims, mirrored=False) is None


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


def test_many_polygons_insert_their_points_all_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    # triangulate_many and triangulate_packed triangulate the rings of all polygons with
    # points at once and insert all points into those (points_batch): the results of one
    # polygon at a time, field by field. Clockwise rings, polygons that overlap, points on
    # the boundary, on vertices, outside and repeated are among them.
    rnd = random.Random(11)
    polygons = [random_polygon(rnd, islands=rnd.randint(0, 2)) for _ in range(12)]
    polygons += [[ring[::-1] for ring in rings] for rings in polygons[:3]]  # clockwise
    points = [random_points(rnd, rings, rnd.choice((5, 40))) for rings in polygons]
    square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
    polygons += [[square], [[(2.0, 2.0), (6.0, 2.0), (6.0, 6.0), (2.0, 6.0)]]]  # overlapping
    odd = [(3.0, 3.0), (2.0, 0.0), (4.0, 4.0), (5.0, 5.0), (3.0, 3.0), (1.0, 2.5), (2.0, 3.5)]
    points = [np.column_stack([p, np.zeros(len(p))]) if p.shape[1] == 2 else p for p in points]
    points += [np.array([(*p, 1.0) for p in odd]), np.array([(*p, 2.0) for p in odd[::-1]])]
    one_by_one = [triangulate(r, points=p, rule="delaunay") for r, p in zip(polygons, points)]
    own = []
    original = one_polygon._delaunay_mesh
    monkeypatch.setattr(one_polygon, "_delaunay_mesh", lambda *a: own.append(1) or original(*a))
    many = triangulate_many(polygons, points=points, rule="delaunay")
    counts = np.array([len(p) for p in points], dtype=np.int64)
    flat = np.concatenate(points)
    packed = triangulate_packed(PackedPolygons.of(polygons), points=(flat, counts), rule="delaunay")
    assert len(own) <= 2  # nearly every polygon took its inserted mesh
    for number, want in enumerate(one_by_one):
        assert_same_fields(many[number], want)
        assert_same_fields(packed.to_list()[number], want)
    assert (one_by_one[-1].point_ids >= 0).sum() == 3  # inside, once each


@pytest.mark.parametrize("hint", ["inserted_mesh", "ring_mesh"])
def test_a_hint_that_does_not_fit_the_polygon_is_not_used(hint: str) -> None:
    # points inserted with other rows, or the rings' triangulation of another polygon
    rnd = random.Random(13)
    rings = random_polygon(rnd, islands=1)
    points = random_points(rnd, rings, 20)
    plain = triangulate(rings, points=points, rule="delaunay")
    wrong = {
        "inserted_mesh": InsertedMesh(plain.triangles, np.roll(plain.point_ids, 1)),
        "ring_mesh": triangulate(random_polygon(rnd, islands=1), rule="delaunay"),
    }[hint]
    hinted = one_polygon._triangulate(
        rings, rule="delaunay", planar_tolerance=0.0, invalid="fail", points=points,
        **{hint: wrong},
    )  # fmt: skip
    assert_same_fields(hinted, plain)
