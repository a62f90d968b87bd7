"""DelaunayMesh: points inserted one at a time keep a valid constrained Delaunay triangulation.

After insertions every triangle is counter-clockwise, the neighbour table is symmetric, the
triangles tile the same area (exact rational sums), every unconstrained interior edge is
locally Delaunay under the symbolic tie rule (so the whole mesh is constrained Delaunay), and
the result depends only on the point set: not on the insertion order, and equal to the
engine's rule "delaunay" with the same points.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.geometry.delaunay_mesh import DelaunayMesh, hilbert_order
from bsp_triangulate.geometry.predicates import incircle_sos, orient

SQUARE_X = [0.0, 1.0, 1.0, 0.0]
SQUARE_Y = [0.0, 0.0, 1.0, 1.0]
SQUARE_TRIANGLES = [[0, 1, 2], [0, 2, 3]]

OUTER = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
HOLES = [
    [(2.0, 2.0), (2.0, 7.0), (4.0, 7.0), (4.0, 2.0)],
    [(6.0, 5.5), (7.5, 8.0), (8.5, 4.0)],
]
U_SHAPE = [(0.0, 0.0), (3.0, 0.0), (3.0, 3.0), (2.0, 3.0), (2.0, 1.0), (1.0, 1.0), (1.0, 3.0)]


def _square() -> DelaunayMesh:
    return DelaunayMesh(SQUARE_X, SQUARE_Y, SQUARE_TRIANGLES)


def _polygon_mesh(rings: list) -> DelaunayMesh:
    t = triangulate(rings, rule="delaunay")
    return DelaunayMesh.of_triangulation(t.vertices, t.triangles)


def _twice_area(mesh: DelaunayMesh) -> Fraction:
    x, y = mesh.x, mesh.y
    total = Fraction(0)
    for a, b, c in mesh.triangles().tolist():
        ax, ay, bx, by, cx, cy = (Fraction(v) for v in (x[a], y[a], x[b], y[b], x[c], y[c]))
        total += (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return total


def _check_mesh(mesh: DelaunayMesh) -> None:
    """Counter-clockwise triangles, a symmetric neighbour table and locally Delaunay edges."""
    tri, nbr = mesh.triangles(), mesh.neighbours()
    x, y = mesh.x, mesh.y
    assert tri.shape == nbr.shape == (mesh.triangle_count, 3)
    fixed = {tuple(e) for e in mesh.constrained_edges().tolist()}
    for t, (corners, across) in enumerate(zip(tri.tolist(), nbr.tolist())):
        a, b, c = corners
        assert orient(x[a], y[a], x[b], y[b], x[c], y[c]) > 0, t
        for k, u in enumerate(across):
            if u < 0:
                continue
            i, j = corners[(k + 1) % 3], corners[(k + 2) % 3]
            other = tri[u].tolist()
            assert list(nbr[u]).count(t) == 1
            m = other.index(j)
            assert other[(m + 1) % 3] == i  # the same edge, reversed
            if (min(i, j), max(i, j)) in fixed:
                continue
            d = other[(m + 2) % 3]
            w = corners[k]
            assert incircle_sos(x[w], y[w], x[i], y[i], x[j], y[j], x[d], y[d]) < 0, (t, k)


def _triangle_set(mesh_or_result, vertices=None) -> set:
    """Triangles as sorted triples of coordinate pairs."""
    if vertices is None:
        vertices = np.column_stack([mesh_or_result.x, mesh_or_result.y])
        tri = mesh_or_result.triangles()
    else:
        tri = mesh_or_result
    xy = [tuple(p) for p in np.asarray(vertices)[:, :2].tolist()]
    return {tuple(sorted(xy[v] for v in row)) for row in tri.tolist()}


def _inside_polygon(rng: np.random.Generator, count: int) -> np.ndarray:
    """Random points strictly inside OUTER and outside HOLES (with a margin)."""
    points = rng.uniform(0.05, 9.95, size=(4 * count, 2))
    keep = np.ones(len(points), dtype=bool)
    for hole in HOLES:
        h = np.asarray(hole)
        lo, hi = h.min(axis=0) - 0.05, h.max(axis=0) + 0.05
        keep &= ~((points >= lo) & (points <= hi)).all(axis=1)
    return points[keep][:count]


def test_random_points_in_square_keep_a_valid_delaunay_mesh():
    mesh = _square()
    area = _twice_area(mesh)
    points = np.random.default_rng(1).uniform(0.0, 1.0, size=(600, 2))
    for i, (px, py) in enumerate(points.tolist()):
        assert mesh.insert(px, py, start=i % mesh.triangle_count) == 4 + i
    assert mesh.vertex_count == 604
    assert mesh.triangle_count == 2 + 2 * 600
    assert _twice_area(mesh) == area
    _check_mesh(mesh)


def test_random_points_in_polygon_with_holes_keep_a_valid_delaunay_mesh():
    mesh = _polygon_mesh([OUTER, *HOLES])
    before, area = mesh.triangle_count, _twice_area(mesh)
    points = _inside_polygon(np.random.default_rng(2), 400)
    hint = 0
    for px, py in points.tolist():
        v = mesh.insert(px, py, start=hint)
        hint = mesh.triangle_count - 1 if v % 2 else 0
    assert mesh.triangle_count == before + 2 * len(points)
    assert _twice_area(mesh) == area
    _check_mesh(mesh)


def test_insert_many_skips_points_outside_and_repeated_points():
    mesh = _polygon_mesh([OUTER, *HOLES])
    before, area = mesh.triangle_count, _twice_area(mesh)
    inside = _inside_polygon(np.random.default_rng(3), 300)
    outside = np.array([[3.0, 4.0], [-1.0, 5.0], [7.5, 5.5], [11.0, 11.0]])
    repeated = np.array([inside[0], [0.0, 0.0], [2.0, 7.0]])
    points = np.concatenate([inside, outside, repeated])
    ids = mesh.insert_many(points[:, 0], points[:, 1])
    assert (ids[len(inside) :] == -1).all()
    assert sorted(ids[: len(inside)].tolist()) == list(range(11, 11 + len(inside)))
    assert np.array_equal(np.column_stack([mesh.x, mesh.y])[ids[: len(inside)]], inside)
    assert mesh.triangle_count == before + 2 * len(inside)
    assert _twice_area(mesh) == area
    _check_mesh(mesh)


@pytest.mark.parametrize("kind", ["random", "grid"])
def test_insertion_order_does_not_change_the_triangulation(kind: str):
    rng = np.random.default_rng(4)
    if kind == "random":
        points = rng.uniform(0.0, 1.0, size=(300, 2))
    else:
        # every 4 neighbours are exactly cocircular, and the square's corners are on the grid
        ticks = np.arange(0, 17) / 16
        points = np.array([(a, b) for a in ticks for b in ticks])
        corner = np.isin(points, [0.0, 1.0]).all(axis=1)
        points = points[~corner]
    results = []
    for _ in range(3):
        mesh = _square()
        for px, py in rng.permutation(points).tolist():
            mesh.insert(px, py)
        _check_mesh(mesh)
        results.append(_triangle_set(mesh))
    assert results[0] == results[1] == results[2]
    # insert_many (Hilbert order) agrees with one at a time
    mesh = _square()
    assert (mesh.insert_many(points[:, 0], points[:, 1]) >= 0).all()
    assert _triangle_set(mesh) == results[0]


def test_equals_the_engines_constrained_delaunay_triangulation():
    rings = [OUTER, HOLES[0]]
    points = np.random.default_rng(5).uniform(0.0, 10.0, size=(400, 2))
    h = np.asarray(HOLES[0])
    in_hole = ((points >= h.min(axis=0) - 0.01) & (points <= h.max(axis=0) + 0.01)).all(axis=1)
    points = points[~in_hole][:200]
    engine = triangulate(rings, points=points, rule="delaunay")
    assert (engine.point_ids >= 0).all()
    mesh = _polygon_mesh(rings)
    for px, py in points.tolist():
        mesh.insert(px, py)
    _check_mesh(mesh)
    assert _triangle_set(mesh) == _triangle_set(engine.triangles, engine.vertices)


def test_make_delaunay_flips_the_first_rule_into_the_delaunay_rule():
    rings = [OUTER, *HOLES]
    first = triangulate(rings, rule="first")
    delaunay = triangulate(rings, rule="delaunay")
    mesh = DelaunayMesh.of_triangulation(first.vertices, first.triangles)
    assert mesh.make_delaunay() > 0
    _check_mesh(mesh)
    assert _triangle_set(mesh) == _triangle_set(delaunay.triangles, delaunay.vertices)
    assert mesh.make_delaunay() == 0


def test_points_on_edges_split_them():
    mesh = _square()
    # on the diagonal (an interior edge): 2 -> 4 each
    for k in range(1, 8):
        mesh.insert(k / 8, k / 8)
    assert mesh.triangle_count == 2 + 2 * 7
    # on the boundary: 1 -> 2, and the halves stay boundary
    mesh.insert(0.5, 0.0)
    mesh.insert(1.0, 0.25)
    assert mesh.triangle_count == 2 + 2 * 7 + 2
    assert (mesh.neighbours() == -1).sum() == 4 + 2
    _check_mesh(mesh)
    assert _twice_area(mesh) == 2


def test_a_split_constrained_edge_stays_constrained():
    mesh = DelaunayMesh(SQUARE_X, SQUARE_Y, SQUARE_TRIANGLES, constrained=[(2, 0)])
    mesh.insert(0.5, 0.5)
    mesh.insert(0.25, 0.25)
    # points next to the diagonal that would flip it away if it were free
    for px, py in [(0.6, 0.3), (0.3, 0.6), (0.8, 0.7), (0.1, 0.2)]:
        mesh.insert(px, py)
    assert mesh.constrained_edges().tolist() == [[0, 5], [2, 4], [4, 5]]
    for i, j in [(0, 5), (5, 4), (4, 2)]:
        assert mesh.has_edge(i, j)
        assert mesh.has_edge(j, i)
    assert not mesh.has_edge(1, 3)
    _check_mesh(mesh)
    assert mesh.make_delaunay() == 0


def test_a_point_on_a_vertex_raises_and_leaves_the_mesh_unchanged():
    mesh = _square()
    mesh.insert(0.5, 0.25)
    tables = (mesh.triangles(), mesh.neighbours(), list(mesh.x), list(mesh.y))
    for px, py in [(0.5, 0.25), (1.0, 1.0), (0.0, 0.0)]:
        with pytest.raises(ValueError, match="is vertex"):
            mesh.insert(px, py)
    assert np.array_equal(mesh.triangles(), tables[0])
    assert np.array_equal(mesh.neighbours(), tables[1])
    assert (mesh.x, mesh.y) == (tables[2], tables[3])


def test_a_point_outside_raises():
    mesh = _polygon_mesh([OUTER, *HOLES])
    count = mesh.triangle_count
    for px, py in [(-0.5, 5.0), (10.0, 10.5), (3.0, 4.0), (7.5, 5.5), (float("nan"), 1.0)]:
        with pytest.raises(ValueError, match="outside"):
            mesh.insert(px, py)
        with pytest.raises(ValueError, match="outside"):
            mesh.locate(px, py)
    assert mesh.triangle_count == count
    assert mesh.vertex_count == 11


def test_locate_falls_back_to_a_scan_where_the_walk_is_blocked():
    mesh = _polygon_mesh([U_SHAPE])
    x, y = mesh.x, mesh.y
    tri = mesh.triangles()
    # a triangle at the top of the left arm, a point at the top of the right arm
    start = next(
        t
        for t, row in enumerate(tri.tolist())
        if max(x[v] for v in row) <= 1.0 and sum(y[v] for v in row) > 3.0
    )
    assert mesh._walk(2.5, 2.5, start) is None  # the notch blocks the walk
    t, edge = mesh.locate(2.5, 2.5, start)
    a, b, c = tri[t].tolist()
    assert edge == -1
    assert orient(x[a], y[a], x[b], y[b], 2.5, 2.5) > 0
    assert orient(x[b], y[b], x[c], y[c], 2.5, 2.5) > 0
    assert orient(x[c], y[c], x[a], y[a], 2.5, 2.5) > 0
    v = mesh.insert(2.5, 2.5, start)
    assert mesh.has_edge(v, 2) and mesh.has_edge(v, 3)
    _check_mesh(mesh)


def test_locate_reports_the_edge_a_point_lies_on():
    mesh = _square()
    t, edge = mesh.locate(0.5, 0.5)
    row = mesh.triangles()[t].tolist()
    assert edge >= 0
    assert {row[(edge + 1) % 3], row[(edge + 2) % 3]} == {0, 2}
    assert mesh.locate(0.9, 0.1) == (0, -1)


def test_bad_tables_are_refused():
    with pytest.raises(ValueError, match="counter-clockwise"):
        DelaunayMesh(SQUARE_X, SQUARE_Y, [[0, 2, 1], [0, 2, 3]])
    with pytest.raises(ValueError, match="not an edge"):
        DelaunayMesh(SQUARE_X, SQUARE_Y, SQUARE_TRIANGLES, constrained=[(1, 3)])
    with pytest.raises(ValueError, match="does not exist"):
        DelaunayMesh(SQUARE_X, SQUARE_Y, [[0, 1, 4]])


def test_hilbert_order_is_a_permutation_that_keeps_neighbours_close():
    rng = np.random.default_rng(6)
    points = rng.uniform(0.0, 1.0, size=(2000, 2))
    order = hilbert_order(points[:, 0], points[:, 1])
    assert sorted(order.tolist()) == list(range(2000))
    steps = np.hypot(*np.diff(points[order], axis=0).T)
    assert steps.mean() < 0.05
    assert len(hilbert_order(np.zeros(0), np.zeros(0))) == 0


@pytest.mark.parametrize("origin", [1e7, 3.0e5])
def test_near_cocircular_points_far_from_the_origin_are_decided_exactly(origin: float):
    # a grid (every 4 neighbours cocircular) with some points moved by one unit in the last
    # place: the float in-circle values are all within rounding of 0, the flip filter of
    # _restore must leave them to the exact test
    rng = np.random.default_rng(11)
    ticks = origin + np.arange(1, 16) * 0.5
    points = np.array([(a, b) for a in ticks for b in ticks])
    nudge = rng.random(len(points)) < 0.3
    points[nudge, 0] = np.nextafter(points[nudge, 0], np.inf)
    nudge = rng.random(len(points)) < 0.3
    points[nudge, 1] = np.nextafter(points[nudge, 1], -np.inf)
    lo, hi = origin, origin + 8.0
    sets = []
    for order in (np.arange(len(points)), rng.permutation(len(points))):
        mesh = DelaunayMesh([lo, hi, hi, lo], [lo, lo, hi, hi], SQUARE_TRIANGLES)
        assert (mesh.insert_many(points[order, 0], points[order, 1]) >= 0).all()
        _check_mesh(mesh)
        sets.append(_triangle_set(mesh))
    assert sets[0] == sets[1]


@pytest.mark.parametrize(("centre", "radius"), [(0.5, 0.4), (1e7, 9e6)])
def test_points_rounded_onto_a_circle_are_decided_exactly(centre: float, radius: float):
    # cocircular up to the rounding of their coordinates: the float in-circle value often has
    # the wrong sign, so the flip filter of _restore must pass those to the exact test
    angles = np.random.default_rng(3).uniform(0.0, 2 * np.pi, 400)
    px, py = centre + radius * np.cos(angles), centre + radius * np.sin(angles)
    lo, hi = centre - 1.5 * radius, centre + 1.5 * radius
    sets = []
    for order in (np.arange(len(px)), np.argsort(angles)):
        mesh = DelaunayMesh([lo, hi, hi, lo], [lo, lo, hi, hi], SQUARE_TRIANGLES)
        assert (mesh.insert_many(px[order], py[order]) >= 0).all()
        _check_mesh(mesh)
        sets.append(_triangle_set(mesh))
    assert sets[0] == sets[1]


def test_huge_coordinates_leave_the_flip_test_to_the_exact_predicate():
    # the lifts' products overflow: the inlined filter must not decide
    scale = 1e100
    mesh = DelaunayMesh([0.0, scale, scale, 0.0], [0.0, 0.0, scale, scale], SQUARE_TRIANGLES)
    points = np.random.default_rng(5).uniform(0.05, 0.95, size=(200, 2)) * scale
    assert (mesh.insert_many(points[:, 0], points[:, 1]) >= 0).all()
    _check_mesh(mesh)
