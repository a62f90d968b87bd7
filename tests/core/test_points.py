"""Interior points: each point strictly inside the polygon becomes a vertex (a one-point
island joined by a bridge), under every apex rule.

Expectations come from docs/algorithm.md and independent references, never from the engine:
- which points are used: shapely's ``contains`` (strict interior) and the first of equal
  x, y; their rows follow the ring vertices in the given order;
- the usual checks (vertices from the input or the given points, counter-clockwise, tree
  fields, exact tiling, zero deviation), with 2V - B - 2 + 2h + 2k triangles for k points;
- rule "delaunay": the brute-force constrained-Delaunay check of test_rule_delaunay.py with
  the points as vertices;
- triangulate_many and triangulate_packed give what triangulate gives one by one.
"""

from __future__ import annotations

import json
import random
from fractions import Fraction

import numpy as np
import pytest
import shapely

from bsp_triangulate import (
    RULES,
    PackedPolygons,
    TriangulationError,
    triangulate,
    triangulate_many,
    triangulate_packed,
)
from bsp_triangulate.geometry import points as points_module
from bsp_triangulate.geometry.points import PointOrder, nearest_vertices
from bsp_triangulate.geometry.predicates import compare_sq_distances_many, exact_sq_distance

from ..conftest import SHARED_DATA
from .checks import (
    check_ccw,
    check_tiling,
    check_tree,
    check_vertices,
    clean_ring,
    deviation,
    polygon_counts,
    used_rings,
)
from .random_polygons import random_polygon, with_z
from .test_rule_delaunay import delaunay_violations
from .tree.test_batch import first_differing_field

STEINER = SHARED_DATA / "earcut" / "fixtures" / "steiner.json"
RULE_NAMES = ("first", "elevation", "delaunay")


def expected_point_ids(rings: list, points: np.ndarray, ring_vertices: int) -> np.ndarray:
    """Rows the points must get: strictly inside (shapely), first of equal x, y; -1 else."""
    kept = used_rings(rings)
    ids = np.full(len(points), -1, dtype=np.int64)
    if not kept:
        return ids
    polygon = shapely.Polygon([p[:2] for p in kept[0]], [[p[:2] for p in r] for r in kept[1:]])
    seen: set[tuple[float, float]] = set()
    row = ring_vertices
    for number, point in enumerate(points.tolist()):
        key = (point[0], point[1])
        first = key not in seen
        seen.add(key)
        if first and polygon.contains(shapely.Point(key)):
            ids[number] = row
            row += 1
    return ids


def random_points(rnd: random.Random, rings: list, count: int) -> np.ndarray:
    """Random points in and around the polygon, plus points on its vertices and edges
    (exact midpoints of integer edges) and repeats, shuffled; (k, 3) with integer z."""
    xy = np.array([p[:2] for ring in rings for p in ring], dtype=float)
    lo, hi = xy.min(axis=0) - 2.0, xy.max(axis=0) + 2.0
    points = [(rnd.uniform(lo[0], hi[0]), rnd.uniform(lo[1], hi[1])) for _ in range(count)]
    integer = all(float(c).is_integer() for ring in rings for p in ring for c in p[:2])
    for ring in rings:
        a, b = ring[0][:2], ring[1][:2]
        points.append(tuple(a))
        if integer:  # else the rounded midpoint may lie off the edge
            points.append(((a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0))
    points += rnd.sample(points, min(3, len(points)))
    rnd.shuffle(points)
    return np.array([(x, y, float(rnd.randint(0, 9))) for x, y in points])


def check_with_points(rings: list, points: np.ndarray, result, rule: str) -> None:
    """Every check of a valid polygon, with the used points as vertices."""
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    plain = triangulate(rings, rule=rule)
    expected = expected_point_ids(rings, points, len(plain.vertices))
    assert result.point_ids.dtype == np.int64
    np.testing.assert_array_equal(result.point_ids, expected)
    used = expected >= 0
    k = int(used.sum())
    vertices = np.asarray(result.vertices, dtype=float)
    triangles = np.asarray(result.triangles, dtype=np.int64).reshape(-1, 3)
    assert len(vertices) == len(plain.vertices) + k
    np.testing.assert_array_equal(vertices[: len(plain.vertices)], plain.vertices)
    np.testing.assert_array_equal(vertices[expected[used]], points[used])
    check_vertices([*rings, points[used].tolist()], vertices, triangles)
    check_ccw(vertices, triangles)
    check_tree(triangles, result.parent, result.depth, result.side)
    check_tiling(rings, vertices, triangles)
    assert deviation([clean_ring(r) for r in rings], vertices, triangles) == 0
    assert len(triangles) == polygon_counts(rings).triangles + 2 * k
    assert set(expected[used].tolist()) <= set(np.unique(triangles).tolist())
    if rule == "delaunay":
        problems = delaunay_violations(rings, result, points[used])
        assert not problems, problems[:5]


@pytest.mark.parametrize("rule", RULE_NAMES)
@pytest.mark.parametrize("seed", range(12))
def test_random_polygons_with_islands_and_points(rule: str, seed: int) -> None:
    rnd = random.Random(seed)
    rings = random_polygon(rnd, islands=rnd.randint(0, 3), integer=seed % 2 == 0)
    rings = with_z(rnd, rings)
    points = random_points(rnd, rings, rnd.choice((1, 5, 30, 120)))
    result = triangulate(rings, points=points, rule=rule)
    check_with_points(rings, points, result, rule)


@pytest.mark.parametrize("rule", RULE_NAMES)
def test_points_on_an_integer_grid_are_collinear_with_edges_and_each_other(rule: str) -> None:
    rings = [[(0, 0), (8, 0), (8, 8), (0, 8)], [(3, 3), (3, 5), (5, 5), (5, 3)]]
    points = np.array([(x, y) for x in range(-1, 10) for y in range(-1, 10)], dtype=float)
    result = triangulate(rings, points=points, rule=rule)
    check_with_points(rings, points, result, rule)
    assert (result.point_ids >= 0).sum() == 7 * 7 - 9


@pytest.mark.parametrize("rule", RULE_NAMES)
def test_earcut_steiner_fixture(rule: str) -> None:
    fixture = json.loads(STEINER.read_text())
    rings = [fixture[0]]
    points = np.array([ring[0] for ring in fixture[1:]], dtype=float)
    result = triangulate(rings, points=points, rule=rule)
    check_with_points(rings, points, result, rule)
    # 4 ring vertices and 4 points: 2V - B - 2 (earcut's own output has 9 triangles)
    assert len(result.triangles) == 10
    np.testing.assert_array_equal(result.point_ids, [4, 5, 6, 7])


def test_every_registered_rule_takes_points() -> None:
    rings = [[(0, 0), (10, 0), (10, 10), (0, 10)]]
    for rule in RULES:
        result = triangulate(rings, points=[(2, 3), (7, 7)], rule=rule)
        assert len(result.triangles) == 6


def test_a_point_in_an_island_or_outside_is_not_used() -> None:
    rings = [[(0, 0), (10, 0), (10, 10), (0, 10)], [(4, 4), (4, 6), (6, 6), (6, 4)]]
    points = [(5, 5), (20, 5), (4, 5), (0, 0), (1, 1), (1, 1), (10, 3)]
    result = triangulate(rings, points=points)
    np.testing.assert_array_equal(result.point_ids, [-1, -1, -1, -1, 8, -1, -1])
    assert len(result.triangles) == 8 + 2


def test_points_given_to_a_degenerate_polygon_are_all_unused() -> None:
    result = triangulate([[(0, 0), (1, 1), (2, 2)]], points=[(1, 0.5)])
    assert result.is_empty
    np.testing.assert_array_equal(result.point_ids, [-1])


def test_no_points_give_an_empty_point_ids_array() -> None:
    rings = [[(0, 0), (4, 0), (0, 4)]]
    for points in (None, [], np.zeros((0, 2))):
        result = triangulate(rings, points=points)
        assert result.point_ids.dtype == np.int64 and result.point_ids.shape == (0,)
        assert len(result.triangles) == 1


def test_bad_points_raise_triangulation_error() -> None:
    rings = [[(0, 0), (4, 0), (0, 4)]]
    with pytest.raises(TriangulationError, match="point 2"):
        triangulate(rings, points=[(1, 1), (np.nan, 1)])
    with pytest.raises(TriangulationError, match="shape"):
        triangulate(rings, points=[(1, 1, 1, 1)])
    with pytest.raises(TriangulationError, match="numeric"):
        triangulate(rings, points=[("a", "b")])


def test_a_mirrored_outer_ring_and_a_wall_keep_the_points() -> None:
    clockwise = [(0, 0), (0, 10), (10, 10), (10, 0)]
    result = triangulate([clockwise], points=[(3, 3), (6, 2)])
    check_with_points([clockwise], np.array([(3, 3), (6, 2)], float), result, "first")
    wall = [(0, 0, 0), (10, 0, 0), (10, 0, 10), (0, 0, 10)]
    result = triangulate([wall], points=[(5, 0, 5), (3, 1, 4), (2, 0, 0)])
    np.testing.assert_array_equal(result.point_ids, [4, 5, -1])
    assert len(result.triangles) == 2 + 4


def test_many_points_in_a_large_polygon() -> None:
    rnd = random.Random(3)
    angles = np.sort(np.array([rnd.uniform(0, 2 * np.pi) for _ in range(300)]))
    radii = np.array([rnd.uniform(60, 100) for _ in range(300)])
    outer = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    points = np.array([(rnd.uniform(-100, 100), rnd.uniform(-100, 100)) for _ in range(1500)])
    rings = [outer.tolist()]
    for rule in ("first", "delaunay"):
        result = triangulate(rings, points=points, rule=rule)
        check_with_points(rings, points, result, rule)


def _polygons_with_points(seed: int, count: int) -> tuple[list, list]:
    rnd = random.Random(seed)
    polygons, points = [], []
    for number in range(count):
        rings = random_polygon(rnd, islands=rnd.randint(0, 2))
        polygons.append([np.asarray(r, dtype=float) for r in with_z(rnd, rings)])
        if number % 3 == 0:
            points.append(None)
        elif number % 3 == 1:
            points.append(np.zeros((0, 3)))
        else:
            points.append(random_points(rnd, rings, rnd.randint(1, 20)))
    return polygons, points


def _same(got, want) -> str | None:
    differing = first_differing_field(got, want)
    if differing is not None:
        return differing
    if got.point_ids.dtype != want.point_ids.dtype:
        return "point_ids dtype"
    if not np.array_equal(got.point_ids, want.point_ids):
        return "point_ids"
    return None


@pytest.mark.parametrize("rule", RULE_NAMES)
def test_many_and_packed_equal_one_by_one(rule: str) -> None:
    polygons, points = _polygons_with_points(11, 60)
    one_by_one = [triangulate(p, points=q, rule=rule) for p, q in zip(polygons, points)]
    many = triangulate_many(polygons, points=points, rule=rule)
    counts = np.array([0 if q is None else len(q) for q in points], dtype=np.int64)
    flat = np.concatenate([np.zeros((0, 3))] + [q for q in points if q is not None])
    packed = triangulate_packed(PackedPolygons.of(polygons), points=(flat, counts), rule=rule)
    np.testing.assert_array_equal(packed.point_count, counts)
    for number, want in enumerate(one_by_one):
        assert _same(many[number], want) is None, number
        assert _same(packed[number], want) is None, number
        assert _same(packed.to_list()[number], want) is None, number
    order = np.array([5, 2, 59, 8, 0], dtype=np.int64)
    taken = packed.take(order)
    for got, number in zip(taken.to_list(), order.tolist()):
        assert _same(got, one_by_one[number]) is None, number


def test_packed_without_points_stays_as_before() -> None:
    polygons, _ = _polygons_with_points(4, 10)
    packed = triangulate_packed(PackedPolygons.of(polygons))
    assert packed.point_ids.shape == (0,)
    np.testing.assert_array_equal(packed.point_count, np.zeros(10, dtype=np.int64))
    assert all(result.point_ids.shape == (0,) for result in packed.to_list())


def test_packed_points_of_a_failed_polygon_are_unused() -> None:
    bow_tie = [np.array([(0, 0), (4, 4), (4, 0), (0, 4)], dtype=float)]
    square = [np.array([(0, 0), (4, 0), (4, 4), (0, 4)], dtype=float)]
    coordinates = np.array([(1, 2), (3, 3), (2, 1)], dtype=float)
    packed = triangulate_packed(
        PackedPolygons.of([bow_tie, square]),
        points=(coordinates, np.array([2, 1])),
        on_error="return",
    )
    assert isinstance(packed[0], TriangulationError)
    np.testing.assert_array_equal(packed.point_ids, [-1, -1, 4])
    np.testing.assert_array_equal(packed[1].point_ids, [4])


def test_packed_point_counts_are_checked() -> None:
    polygons = PackedPolygons.of([[[(0, 0), (4, 0), (0, 4)]]])
    with pytest.raises(ValueError, match="add up"):
        triangulate_packed(polygons, points=(np.zeros((2, 3)), np.array([1])))
    with pytest.raises(ValueError, match="counts for"):
        triangulate_packed(polygons, points=(np.zeros((2, 3)), np.array([1, 1])))


def test_nearest_vertices_match_a_brute_force_search() -> None:
    rnd = random.Random(5)
    grid = [(float(i), float(j)) for i in range(12) for j in range(12)]
    scattered = [(rnd.uniform(-1, 12), rnd.uniform(-1, 12)) for _ in range(150)]
    far = [(1e6, 1e6), (-3e5, 2.5)]
    xy = np.array(grid + scattered + far + grid[:5])  # repeats: exact ties at distance 0
    x, y = xy[:, 0], xy[:, 1]
    ids = np.arange(len(xy), dtype=np.int64)
    queries = np.array([*rnd.sample(range(len(xy)), 120), len(xy) - 1], dtype=np.int64)
    got = nearest_vertices(x, y, ids, queries)
    for query, near in zip(queries.tolist(), got.tolist()):
        others = [v for v in range(len(xy)) if v != query]
        d2 = [exact_sq_distance(x[v], y[v], x[query], y[query]) for v in others]
        assert near == min(zip(d2, others))[1]


def test_grid_points_with_random_points_under_rule_delaunay() -> None:
    # DEM-like cell centres, with their many exact distance ties, plus scattered points: the
    # points join in the order of their nearest vertices
    rnd = random.Random(11)
    outer = [(0.0, 0.0), (41.0, 0.0), (41.0, 41.0), (20.5, 30.0), (0.0, 41.0)]
    island = [(10.2, 10.2), (10.2, 14.8), (14.8, 14.8), (14.8, 10.2)]
    centres = [(i + 0.5, j + 0.5) for i in range(40) for j in range(40)]
    scattered = [(rnd.uniform(0, 41), rnd.uniform(0, 41)) for _ in range(300)]
    points = np.array(centres + scattered)
    rings = [outer, island]
    result = triangulate(rings, points=points, rule="delaunay")
    check_with_points(rings, points, result, "delaunay")


@pytest.mark.parametrize("seed", range(3))
def test_point_order_links_have_empty_diametral_circles(seed: int) -> None:
    # each link may be the bridge of either end: no vertex strictly inside its circle (exact)
    rnd = random.Random(seed)
    ring = [(float(i), 0.0) for i in range(20)] + [(20.0, 20.0), (0.0, 20.0)]
    grid = [(i + 0.5, j + 0.5) for i in range(0, 20, 2) for j in range(0, 20, 2)]
    scattered = [(rnd.uniform(0.1, 19.9), rnd.uniform(0.1, 19.9)) for _ in range(150)]
    xy = np.array(ring + grid + scattered)
    x, y = xy[:, 0], xy[:, 1]
    vids = list(range(len(ring), len(xy)))
    order = PointOrder(x, y, np.arange(len(xy), dtype=np.int64), [vid + 1000 for vid in vids], vids)
    vid_of = {vid + 1000: vid for vid in vids}
    links = {(vid_of[slot], near) for targets in order.links.values() for slot, near in targets}
    assert {a for a, _ in links} == set(vids)  # every point is linked
    for a, b in links:
        ax, ay, bx, by = (Fraction(float(c)) for c in (x[a], y[a], x[b], y[b]))
        for w in range(len(xy)):
            wx, wy = Fraction(float(x[w])), Fraction(float(y[w]))
            assert (wx - ax) * (wx - bx) + (wy - ay) * (wy - by) >= 0, (a, b, w)


def _near_ties(seed: int, origin: float, cell: float, count: int) -> list[np.ndarray]:
    """(a, b, c, d) coordinate arrays with |a - b| and |c - d| equal in the reals before the
    coordinates were rounded (b = d a cell centre, c = a turned by 90 degrees about it), some
    of them then moved by one unit in the last place."""
    rng = np.random.default_rng(seed)
    bx = origin + (rng.integers(0, 100, count) + 0.5) * cell
    by = 0.9 * origin + (rng.integers(0, 100, count) + 0.5) * cell
    i, j = rng.integers(-3, 4, count), rng.integers(-3, 4, count)
    ax, ay, cx, cy = bx + i * cell, by + j * cell, bx - j * cell, by + i * cell
    for values in (ax, cy, bx):
        moved = rng.random(count) < 0.2
        values[moved] = np.nextafter(values[moved], np.inf if seed % 2 else -np.inf)
    return [ax, ay, bx, by, cx, cy, bx.copy(), by.copy()]


@pytest.mark.parametrize(
    ("origin", "cell"), [(0.0, 1.0), (1e7, 0.5), (1e7, 3.0), (3.0e5, 82.3), (6.2e6, 82.3)]
)
def test_compare_sq_distances_is_exact_on_near_ties(origin: float, cell: float) -> None:
    # the float comparison of these distances is often wrong; the exact one must not be
    cases = _near_ties(int(origin) % 7 + int(cell), origin, cell, 3000)
    got = compare_sq_distances_many(*cases)
    want = [
        (u > v) - (u < v)
        for u, v in (
            (exact_sq_distance(*row[:4]), exact_sq_distance(*row[4:]))
            for row in zip(*(c.tolist() for c in cases))
        )
    ]
    assert got.tolist() == want
    assert 0 in want and 1 in want and -1 in want
    ax, ay, bx, by, cx, cy, dx, dy = cases
    floats = np.sign((ax - bx) ** 2 + (ay - by) ** 2 - (cx - dx) ** 2 - (cy - dy) ** 2)
    assert (floats != np.array(want)).any()  # the test needs the exact path


def test_compare_sq_distances_falls_back_where_differences_round() -> None:
    # the first two: exact coordinate differences whose sum is not (the eight-term sum
    # decides); then differences that are not exact in float, huge and tiny ones (integers)
    tiny = 2.0**-52
    ax = np.array([1.0 + tiny, 1.0 + tiny, 1e300, 1e-320, 1.0, 1e16, 0.1, -1e200])
    ay = np.array([0.0, 0.0, 0.0, 0.0, 1e-30, 3.0, 0.2, 1e200])
    bx = np.array([0.0, 0.0, -1e300, 0.0, -1e-30, -1.0, 0.3, 1e200])
    by = np.array([0.0, 0.0, 0.0, 5e-324, 0.0, 0.0, 0.1, -1e200])
    cx, cy, dx, dy = by.copy(), ax.copy(), ay.copy(), bx.copy()
    cx[:2], cy[:2] = [2.0**-60, 3 * 2.0**-58], [1.0 + tiny, 1.0]
    got = compare_sq_distances_many(ax, ay, bx, by, cx, cy, dx, dy)
    for k in range(len(ax)):
        u = exact_sq_distance(ax[k], ay[k], bx[k], by[k])
        v = exact_sq_distance(cx[k], cy[k], dx[k], dy[k])
        assert got[k] == (u > v) - (u < v), k


@pytest.mark.parametrize(("few", "all_pairs"), [(10**9, 16), (0, 16), (0, 0)])
@pytest.mark.parametrize("origin", [0.5, 1e7, 6.2e6])
def test_nearest_vertices_on_near_tied_cell_centres(
    monkeypatch: pytest.MonkeyPatch, origin: float, few: int, all_pairs: int
) -> None:
    # cell centres, some moved by one unit in the last place: many nearest candidates are
    # equally far in float but not exactly; the three ways of the exact choice (integer keys,
    # all pairs at once, a knockout) agree with a brute force over Fractions (ties to the
    # smallest id)
    monkeypatch.setattr(points_module, "_FEW_PAIRS", few)
    monkeypatch.setattr(points_module, "_ALL_PAIRS", all_pairs)
    rng = np.random.default_rng(int(origin) % 97)
    cell = 0.5 if origin > 1e6 else 1.0
    xy = np.array([(origin + i * cell, origin + j * cell) for i in range(14) for j in range(14)])
    xy = xy[rng.permutation(len(xy))]
    for column in (0, 1):
        moved = rng.random(len(xy)) < 0.25
        xy[moved, column] = np.nextafter(xy[moved, column], np.inf if column else -np.inf)
    x, y = xy[:, 0], xy[:, 1]
    ids = np.arange(len(xy), dtype=np.int64)
    queries = rng.choice(len(xy), 80, replace=False).astype(np.int64)
    got = nearest_vertices(x, y, ids, queries)
    for query, near in zip(queries.tolist(), got.tolist()):
        others = [v for v in range(len(xy)) if v != query]
        d2 = [exact_sq_distance(x[v], y[v], x[query], y[query]) for v in others]
        assert near == min(zip(d2, others))[1]


@pytest.mark.parametrize("reach", [1, 2, 8, None])
def test_nearest_vertices_in_a_town_in_a_wide_frame_reach_as_far_with_finer_cells(
    reach: int | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a dense cluster of small rings and a few far vertices: the grid's cells are made finer
    # where its occupied cells hold many, and a search stops at the same distance as before
    rng = np.random.default_rng(3)
    town = rng.uniform(0.0, 40.0, (3000, 2))
    far = np.array([[5000.0, 0.0], [0.0, 3000.0], [5000.0, 3000.0], [2500.0, 1500.0]])
    xy = np.concatenate([town, far])
    x, y = xy[:, 0], xy[:, 1]
    labels = np.arange(len(xy), dtype=np.int64) // 5  # rings of five vertices
    ids = np.arange(len(xy), dtype=np.int64)
    queries = np.arange(0, len(xy), 7, dtype=np.int64)
    grid = points_module.VertexGrid(x, y, ids)
    assert grid.finer > 1
    got, bound = grid.nearest(queries, labels, max_reach=reach)
    monkeypatch.setattr(points_module, "_PER_CELL", 10**9)
    plain = points_module.VertexGrid(x, y, ids)
    assert plain.finer == 1
    expected, expected_bound = plain.nearest(queries, labels, max_reach=reach)
    assert np.array_equal(got, expected) and bound == expected_bound
