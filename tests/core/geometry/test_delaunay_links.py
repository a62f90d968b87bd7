"""Rule delaunay's links between rings: each is a Gabriel edge crossing no ring edge (checked
by brute force in exact arithmetic), islands join along them, and the result stays the
constrained Delaunay triangulation, the same from the batch path and one polygon at a time."""

from __future__ import annotations

import random
from fractions import Fraction

import numpy as np
import pytest
import shapely

import bsp_triangulate.geometry.bridges as bridges
from bsp_triangulate import TriangulationError, triangulate, triangulate_many
from bsp_triangulate.geometry.delaunay_links import LINKED_ISLANDS, delaunay_links
from bsp_triangulate.geometry.rings import normalise_rings, prepare
from tests.core.geometry.test_bridge_plan import count_found, scattered_squares, square
from tests.core.random_polygons import add_islands, star_ring
from tests.core.test_rule_delaunay import check_delaunay


def prepared(rings: list) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    clean, axes = normalise_rings([np.asarray(r, dtype=float) for r in rings], "xy")
    ready = prepare(clean, axes)
    return ready.x, ready.y, ready.rings


def all_links(x: np.ndarray, y: np.ndarray, rings: list[np.ndarray]) -> list[tuple[int, int]]:
    """(island vertex id, target vertex id) of every link."""
    bridger = bridges._Bridger(x, y, rings)
    links = delaunay_links(
        x, y, rings, bridger.point_ids, bridger.edges, bridger.edge_a, bridger.edge_b
    )
    return [
        (int(rings[slot][index]), target)
        for target, found in links.links.items()
        for slot, index in found
    ]


def _orient(a: tuple, b: tuple, c: tuple) -> int:
    det = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return (det > 0) - (det < 0)


def _crosses(p: tuple, q: tuple, a: tuple, b: tuple) -> bool:
    """Segment a-b meets the open segment p-q (crossing it, or an end of a-b on it)."""
    o1, o2 = _orient(p, q, a), _orient(p, q, b)
    o3, o4 = _orient(a, b, p), _orient(a, b, q)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    for end, side in ((a, o1), (b, o2)):
        if side == 0 and end not in (p, q):
            dot = (end[0] - p[0]) * (q[0] - p[0]) + (end[1] - p[1]) * (q[1] - p[1])
            length = (q[0] - p[0]) ** 2 + (q[1] - p[1]) ** 2
            if 0 < dot < length:
                return True
    return False


def assert_gabriel_and_clear(x: np.ndarray, y: np.ndarray, rings: list[np.ndarray]) -> int:
    """Every link: its closed diametral circle holds no other vertex, it crosses no ring
    edge, and its ends lie on two rings (exact); returns the number of links."""
    point = {int(v): (Fraction(float(x[v])), Fraction(float(y[v]))) for r in rings for v in r}
    ring_of = {int(v): slot for slot, r in enumerate(rings) for v in r}
    edges = [(int(r[k]), int(r[(k + 1) % len(r)])) for r in rings for k in range(len(r))]
    found = all_links(x, y, rings)
    for h, v in found:
        assert ring_of[h] != ring_of[v]
        ph, pv = point[h], point[v]
        for w, pw in point.items():
            if w in (h, v):
                continue
            dot = (pw[0] - ph[0]) * (pw[0] - pv[0]) + (pw[1] - ph[1]) * (pw[1] - pv[1])
            assert dot > 0, (h, v, w)
        for a, b in edges:
            if h in (a, b) and v in (a, b):
                continue
            assert not _crosses(ph, pv, point[a], point[b]), (h, v, a, b)
    return len(found)


def scattered_stars(seed: int, count: int) -> list:
    rnd = random.Random(seed)
    outer = star_ring(rnd, 40, (0.0, 0.0), 200.0, integer=seed % 2 == 0)
    rings = add_islands(rnd, outer, count, 8.0, integer=seed % 2 == 0)
    assert rings is not None
    return rings


@pytest.mark.parametrize("seed", range(4))
def test_links_among_scattered_islands_are_gabriel_edges_crossing_no_ring_edge(seed: int):
    x, y, rings = prepared(scattered_squares(seed, count=40))
    assert assert_gabriel_and_clear(x, y, rings) >= 30
    x, y, rings = prepared(scattered_stars(seed, 24))
    assert assert_gabriel_and_clear(x, y, rings) > 0


def test_links_on_a_grid_of_cocircular_corners_are_gabriel_edges():
    # every gap between four squares of the grid holds four cocircular corners; the links
    # across the gaps are edges of every constrained Delaunay triangulation, the diagonals none
    islands = [square(4.0 * i + 2.0, 4.0 * j + 2.0, 2.0) for i in range(7) for j in range(7)]
    x, y, rings = prepared([square(0.0, 0.0, 30.0), *islands])
    assert assert_gabriel_and_clear(x, y, rings) > 0
    check_delaunay([square(0.0, 0.0, 30.0), *islands])


@pytest.mark.parametrize("seed", range(4))
def test_islands_join_along_links_and_the_result_is_constrained_delaunay(
    seed: int, monkeypatch: pytest.MonkeyPatch
):
    joined = count_found(monkeypatch, "linked")
    rings = scattered_squares(seed, count=40)
    check_delaunay(rings)
    assert sum(joined) >= 20
    check_delaunay(scattered_stars(seed, 24))


def test_batch_and_one_polygon_at_a_time_agree_beyond_the_linked_islands():
    many = scattered_squares(0, count=LINKED_ISLANDS + 1)
    few = scattered_squares(1, count=LINKED_ISLANDS)
    results = triangulate_many([many, few, scattered_stars(2, 20)], rule="delaunay")
    for rings, got in zip([many, few, scattered_stars(2, 20)], results):
        want = triangulate(rings, rule="delaunay")
        for field in ("vertices", "triangles", "parent", "depth", "side"):
            assert np.array_equal(getattr(got, field), getattr(want, field)), field


def test_an_island_outside_the_shell_fails_or_is_joined_as_under_rule_first():
    rings = [*scattered_squares(3, count=30), square(150.0, 150.0, 1.0)]
    for rule in ("first", "delaunay"):
        with pytest.raises(TriangulationError):
            triangulate(rings, rule=rule)
    as_given = [
        len(triangulate(rings, rule=rule, invalid="as_given")) for rule in ("first", "delaunay")
    ]
    assert as_given[0] == as_given[1]


@pytest.mark.parametrize("scale", [2.0**-500, 2.0**500, 2.0**1000])
def test_scaled_islands_give_the_same_triangles(scale: float):
    # powers of two keep every sign; near the float range's ends the float tests only get
    # more careful (fewer links), never wrong
    rings = scattered_squares(5, count=30)
    want = triangulate(rings, rule="delaunay")
    got = triangulate([ring * scale for ring in rings], rule="delaunay")
    assert {tuple(sorted(t)) for t in got.triangles.tolist()} == {
        tuple(sorted(t)) for t in want.triangles.tolist()
    }


def test_islands_touching_each_other_and_the_shell_are_constrained_delaunay():
    # chains of islands sharing corners, two of them at shell corners, among free squares:
    # the touching ones join at their shared points, the others along links
    shell = np.array([(0.0, 0.0), (40.0, 0.0), (40.0, 40.0), (0.0, 40.0)])
    chains = [np.array([(0.0, 0.0), (2.0, 1.0), (2.0, 2.0), (1.0, 2.0)])]  # at (0, 0)
    chains += [square(2.0 + k, 2.0 + k, 1.0) for k in range(2)]
    chains += [square(20.0 + k, 10.0 + k, 1.0) for k in range(4)]
    chains += [np.array([(40.0, 40.0), (38.0, 39.0), (39.0, 38.0)])]  # at (40, 40)
    chains += [np.array([(39.0, 38.0), (38.0, 37.0), (39.0, 36.0)])]
    free = [square(5.0 + 6.0 * i, 25.0 + 5.0 * j, 2.0) for i in range(5) for j in range(2)]
    rings = [shell, *chains, *free]
    assert len(rings) - 1 > LINKED_ISLANDS
    assert shapely.Polygon(shell, chains + free).is_valid
    check_delaunay(rings)


@pytest.mark.parametrize("offset", [1e15, 2.0**52])
def test_links_far_from_the_origin_give_the_same_tree(offset: float):
    # 20 triangles in a 60 m square moved 1e15 from the origin: the vertex grid's rounding
    # slack was 1e-12 of the coordinates (1,000 there), over its whole safe radius, so no
    # link was found and the bridges, hence the tree, changed (the same triangles)
    shell = [(0.0, 0.0), (60.0, 0.0), (60.0, 60.0), (0.0, 60.0)]
    islands = [
        [(x + 2.0, y + 1.0), (x, y + 2.0), (x, y)]
        for y in (10.0, 20.0, 30.0, 40.0)
        for x in (10.0, 20.0, 30.0, 40.0, 50.0)
    ]
    rings = [shell, *islands]
    assert len(islands) > LINKED_ISLANDS
    want = triangulate(rings, rule="delaunay")
    got = triangulate([[(x + offset, y + offset) for x, y in r] for r in rings], rule="delaunay")
    for field in ("triangles", "parent", "depth", "side"):
        assert np.array_equal(getattr(got, field), getattr(want, field)), field
