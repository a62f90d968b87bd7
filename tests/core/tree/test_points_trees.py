"""The trees of many polygons read off their inserted meshes at once: the one-polygon
builder's results field by field, and every polygon whose mesh fails a check left to it."""

from __future__ import annotations

import random
import warnings
from dataclasses import replace

import numpy as np
import pytest

from bsp_triangulate import TriangulationError, triangulate, triangulate_many
from bsp_triangulate.geometry.delaunay_mesh import edge_links
from bsp_triangulate.geometry.predicates import orient_many
from bsp_triangulate.tree import one_polygon
from bsp_triangulate.tree.batch import triangulate_batch
from bsp_triangulate.tree.points_batch import insert_points
from bsp_triangulate.tree.points_trees import trees_of_inserted, trees_of_known

from ..random_polygons import random_polygon
from ..test_points import random_points
from .test_delaunay_points import assert_same_fields


def polygons_with_points(seed: int, count: int = 10) -> tuple[list, list]:
    """Random polygons with islands, some clockwise, and points inside, on and outside."""
    rnd = random.Random(seed)
    polygons = [random_polygon(rnd, islands=rnd.randint(0, 2)) for _ in range(count)]
    polygons[1] = [ring[::-1] for ring in polygons[1]]  # clockwise: x mirrored
    points = [random_points(rnd, rings, rnd.choice((5, 40))) for rings in polygons]
    return polygons, points


def read_at_once(polygons: list, points: list) -> tuple[list, list, list]:
    """The batch path's ring meshes, the points inserted, and the trees read at once."""
    ring_meshes = list(triangulate_batch(polygons, "delaunay"))
    inserted = insert_points(polygons, ring_meshes, points)
    return ring_meshes, inserted, trees_of_inserted(polygons, ring_meshes, points, inserted)


@pytest.mark.parametrize("seed", range(4))
def test_trees_read_at_once_equal_one_polygon_at_a_time(seed: int) -> None:
    polygons, points = polygons_with_points(seed)
    _, _, trees = read_at_once(polygons, points)
    for rings, given, tree in zip(polygons, points, trees):
        assert tree is not None
        assert_same_fields(tree, triangulate(rings, points=given, rule="delaunay"))


def test_no_point_used_gives_the_rings_own_tree() -> None:
    square = [[(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]]
    wide = [[(0.0, 0.0), (9.0, 0.0), (9.0, 1.0), (0.0, 1.0)]]
    outside = np.array([(5.0, 5.0, 1.0), (2.0, 0.0, 1.0), (4.0, 4.0, 1.0)])  # out, edge, vertex
    inside = np.array([(3.0, 0.5, 2.0)])
    _, _, trees = read_at_once([square, wide], [outside, inside])
    np.testing.assert_array_equal(trees[0].point_ids, [-1, -1, -1])
    assert_same_fields(trees[0], triangulate(square, points=outside, rule="delaunay"))
    assert_same_fields(trees[1], triangulate(wide, points=inside, rule="delaunay"))


@pytest.mark.parametrize("fault", ["missing", "doubled", "repeat used", "links", "no links"])
def test_a_mesh_that_fails_a_check_is_left_to_the_one_polygon_builder(fault: str) -> None:
    polygons, points = polygons_with_points(5, count=4)
    ring_meshes = list(triangulate_batch(polygons, "delaunay"))
    used = int(np.flatnonzero(insert_points(polygons, ring_meshes, points)[2].point_ids >= 0)[0])
    points[2] = np.concatenate([points[2], points[2][used : used + 1]])  # a used point again
    ring_meshes, inserted, _ = read_at_once(polygons, points)
    mesh = inserted[2]
    assert mesh.point_ids[-1] == -1
    if fault == "missing":
        mesh = replace(mesh, triangles=mesh.triangles[1:])
    elif fault == "doubled":
        mesh = replace(mesh, triangles=np.concatenate([mesh.triangles, mesh.triangles[:1]]))
    elif fault == "links":
        # two slots that are no edge's two sides linked together
        across = mesh.across.copy()
        inner = np.flatnonzero(across >= 0)
        across[inner[0]], across[inner[1]] = across[inner[1]], across[inner[0]]
        mesh = replace(mesh, across=across)
    elif fault == "no links":
        # links unknown (one polygon): linked from the triangles, its own tree still read
        mesh = replace(mesh, across=None)
    else:
        # the repeat used instead of the first (rows still in the order given)
        ids = mesh.point_ids.copy()
        ids[-1], ids[used] = ids[used], -1
        ids[ids >= 0] = np.sort(ids[ids >= 0])
        mesh = replace(mesh, point_ids=ids)
    inserted[2] = mesh
    trees = trees_of_inserted(polygons, ring_meshes, points, inserted)
    if fault == "no links":
        assert_same_fields(trees[2], triangulate(polygons[2], points=points[2], rule="delaunay"))
    else:
        assert trees[2] is None
    for number in (0, 1, 3):
        want = triangulate(polygons[number], points=points[number], rule="delaunay")
        assert_same_fields(trees[number], want)


def known_meshes(polygons: list, points: list) -> tuple[list, list]:
    """Per polygon its points inside only, and the mesh triangulate makes with them."""
    inside, meshes = [], []
    for rings, given in zip(polygons, points):
        result = triangulate(rings, points=given, rule="delaunay")
        kept = given[result.point_ids >= 0]
        inside.append(kept)
        meshes.append(triangulate(rings, points=kept, rule="delaunay").triangles)
    return inside, meshes


@pytest.mark.parametrize("seed", range(3))
def test_trees_read_off_known_meshes_equal_one_polygon_at_a_time(seed: int) -> None:
    polygons, points = polygons_with_points(seed)
    points, meshes = known_meshes(polygons, points)
    trees = trees_of_known(polygons, points, meshes, "auto")
    for rings, given, mesh, tree in zip(polygons, points, meshes, trees):
        if not len(given):
            assert tree is None  # no points: not a mesh with points, the batch path's
            continue
        assert_same_fields(tree, triangulate(rings, points=given, rule="delaunay", mesh=mesh))


@pytest.mark.parametrize("fault", ["not delaunay", "a point left out", "steep", "rows"])
def test_a_known_mesh_the_one_polygon_builder_would_not_take_is_left_to_it(fault: str) -> None:
    polygons, points = polygons_with_points(8, count=4)
    points, meshes = known_meshes(polygons, points)
    if fault == "not delaunay":
        # an interior edge turned the other way: a valid triangulation, not a Delaunay one
        mesh = meshes[2].copy()
        across, _ = edge_links(mesh, int(mesh.max()) + 1)
        for slot in np.flatnonzero(across >= 0):
            t, k = divmod(int(slot), 3)
            u, j = divmod(int(across[slot]), 3)
            a, b, c, d = mesh[t, k], mesh[t, (k + 1) % 3], mesh[t, (k + 2) % 3], mesh[u, j]
            flipped = np.array([[a, b, d], [a, d, c]])
            px, py = polygons_xy(polygons[2], points[2])
            corners = [c[flipped[:, i]] for i in range(3) for c in (px, py)]
            if (orient_many(*corners) > 0).all():
                mesh[t], mesh[u] = flipped
                break
        meshes[2] = mesh
    elif fault == "a point left out":
        points[2] = np.vstack([points[2], points[2][:1] + np.array([1e-3, 1e-3, 0.0])])
    elif fault == "steep":
        # the same polygon stood up in XZ: its working plane is not XY
        polygons[2] = [[(x, 0.0, y) for x, y, *_ in ring] for ring in polygons[2]]
        points[2] = points[2][:, [0, 2, 1]]
    else:
        meshes[2] = meshes[2] + 1  # rows off by one: the last is no vertex
    trees = trees_of_known(polygons, points, meshes, "auto")
    assert trees[2] is None
    for number in (0, 1, 3):
        want = triangulate(polygons[number], points=points[number], rule="delaunay")
        assert_same_fields(trees[number], want)


def polygons_xy(rings: list, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The x and y of the rings' vertices (as the engine keeps them), then of the points."""
    result = triangulate(rings, points=points, rule="delaunay")
    return result.vertices[:, 0], result.vertices[:, 1]


@pytest.mark.parametrize(
    "bad", [[[float("nan"), 1.0]], [[9.0, 9.0, float("nan")]], [[9.0, 9.0, 0.0, 0.0]]]
)
def test_points_that_do_not_parse_fail_as_one_by_one_even_when_none_is_used(bad: list) -> None:
    square = [[(0, 0), (4, 0), (4, 4), (0, 4)]]
    given = np.array(bad)
    with pytest.raises(TriangulationError):
        triangulate(square, points=given, rule="delaunay")
    results = triangulate_many(
        [square, square], points=[given, given], rule="delaunay", on_error="return"
    )
    assert all(isinstance(result, TriangulationError) for result in results)


def test_a_known_mesh_of_a_sliver_with_subnormal_products_is_negligible_as_one_by_one() -> None:
    # coordinates so small that the shoelace products underflow unless scaled first
    ring = [
        (0.0, 0.0),
        (9.382931509201358e-158,) * 2,
        (4.691465754600679e-158, 4.691465754600683e-158),
    ]
    given = np.array([(4.691465754600679e-158, 4.6914657546006804e-158, 0.0)])
    mesh = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3]])
    want = triangulate([ring], points=given, rule="delaunay", mesh=mesh)
    got = triangulate_many(
        [[ring], [ring]], points=[given, given], meshes=[mesh, mesh], rule="delaunay"
    )
    assert len(want.triangles) == 0
    for result in got:
        assert_same_fields(result, want)


def test_huge_coordinates_with_known_meshes_raise_no_warning() -> None:
    scale = 1e155
    square = [[(0.0, 0.0), (4 * scale, 0.0), (4 * scale, 4 * scale), (0.0, 4 * scale)]]
    given = np.array([[scale, scale, 0.0], [2 * scale, 1.5 * scale, 0.0]])
    mesh = triangulate(square, points=given, rule="delaunay").triangles
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        results = triangulate_many(
            [square, square], points=[given, given], meshes=[mesh, mesh], rule="delaunay"
        )
    assert_same_fields(results[0], triangulate(square, points=given, rule="delaunay", mesh=mesh))


def test_an_empty_mesh_counts_as_none_and_the_points_are_inserted_at_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # as a packed count of 0 does: the polygon joins the others' insertion
    polygons, points = polygons_with_points(3, count=4)
    own = []
    original = one_polygon._delaunay_mesh
    monkeypatch.setattr(one_polygon, "_delaunay_mesh", lambda *a: own.append(1) or original(*a))
    empty = [np.zeros((0, 3), dtype=np.int64)] * len(polygons)
    results = triangulate_many(polygons, points=points, meshes=empty, rule="delaunay")
    assert not own
    for rings, given, result in zip(polygons, points, results):
        assert_same_fields(result, triangulate(rings, points=given, rule="delaunay"))


def wavy_polygon(count: int, clockwise: bool = False) -> list[np.ndarray]:
    """An outer ring of ``count`` vertices (more than the batch path takes) around a square
    island."""
    angle = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
    radius = 50.0 + 8.0 * np.sin(7 * angle)
    outer = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(count)])
    island = np.array([(-5.0, -5.0, 0.0), (-5.0, 5.0, 0.0), (5.0, 5.0, 0.0), (5.0, -5.0, 0.0)])
    rings = [np.round(outer, 3), island]
    return [ring[::-1] for ring in rings] if clockwise else rings


def test_large_polygons_take_a_rough_ring_mesh_and_the_one_polygon_results(monkeypatch) -> None:
    # rings the batch path leaves (over 256 vertices) are triangulated under rule first and
    # flipped by the insertion: the same fields as one polygon at a time, without the engine
    from bsp_triangulate import api

    rng = np.random.default_rng(4)
    polygons = [wavy_polygon(400), wavy_polygon(300, clockwise=True), wavy_polygon(20)]
    wall = [np.column_stack([np.linspace(0, 40, 300), np.zeros(300), np.zeros(300)])]
    wall[0] = np.vstack([wall[0], [(40.0, 0.0, 10.0), (0.0, 0.0, 10.0)]])
    polygons.append(wall)  # steep: a working plane other than XY, left to the engine
    points = [np.column_stack([rng.uniform(-30, 30, (200, 2)), rng.uniform(0, 9, 200)])] * 3
    points.append(np.array([(10.0, 0.0, 5.0), (20.0, 0.0, 5.0)]))
    engine = []
    original = api._engine_result
    monkeypatch.setattr(
        api,
        "_engine_result",
        lambda rings, *a, **k: engine.append(len(rings[0])) or original(rings, *a, **k),
    )
    results = triangulate_many(polygons, points=points, rule="delaunay")
    assert engine == [302]
    for rings, given, result in zip(polygons, points, results):
        assert_same_fields(result, triangulate(rings, points=given, rule="delaunay"))


def test_mirrors_read_off_the_first_triangle_or_the_ring() -> None:
    from bsp_triangulate.geometry.rings import xy_mirror
    from bsp_triangulate.tree.points_batch import _mirrors

    rnd = random.Random(8)
    polygons = [random_polygon(rnd, islands=1) for _ in range(6)]
    polygons[1::2] = [[ring[::-1] for ring in rings] for rings in polygons[1::2]]
    meshes = [triangulate(rings, rule="delaunay") for rings in polygons]
    # a mesh whose first row is not on the outer ring's first edge: the ring decides
    meshes[2] = replace(meshes[2], triangles=meshes[2].triangles[::-1].copy())
    meshes[3] = replace(meshes[3], triangles=meshes[3].triangles[::-1].copy())
    expected = [xy_mirror(rings) for rings in polygons]
    assert sorted(set(expected)) == [-1.0, 1.0]
    assert _mirrors(polygons, meshes, list(range(6))).tolist() == expected


@pytest.mark.parametrize(
    "case", ["island vertex on the outer edge", "clockwise", "through a vertex"]
)
def test_rings_that_touch_along_an_edge_are_left_to_the_one_polygon_builder(case: str) -> None:
    # a rough ring mesh (rule first) splits the edge the other ring touches: its outline is
    # not the ring edges, so the polygon is not inserted at once (it was, and then failed)
    outer = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
    island = [(5.0, 0.0), (4.0, 2.0), (6.0, 2.0)]
    if case == "through a vertex":
        outer = [(0.0, 0.0), (5.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
        island = [(4.0, 0.0), (6.0, 0.0), (5.0, 2.0)][::-1]
    rings = [outer, island]
    if case == "clockwise":
        rings = [ring[::-1] for ring in rings]
    points = np.array([(2.0, 5.0), (7.5, 6.0)])
    result = triangulate_many([rings], points=[points], rule="delaunay", on_error="return")[0]
    assert_same_fields(result, triangulate(rings, points=points, rule="delaunay"))


def test_clockwise_grid_polygon_with_a_cocircular_bridge() -> None:
    """Found by the fuzz run: a clockwise outer ring (x mirrored) and two islands whose
    vertices (16, 32), (16, 36), (20, 36) and (20, 32) are the corners of one square. The
    batch path's rings-only tree bridges along the diagonal (16, 32) - (20, 36), whose
    diametral circle holds the other two corners on it, not inside; the tie rule takes the
    other diagonal. The points go into the ring triangulation only after it is flipped under
    the tie rule, so that the polygon gets the one-polygon builder's triangles."""
    rings = [
        [(24, 48), (32, 48), (32, 40), (40, 40), (40, 36), (40, 32), (32, 32), (24, 32),
         (24, 28), (24, 24), (16, 24), (16, 32), (12, 32), (8, 32), (8, 40), (8, 44),
         (8, 48), (16, 48)],
        [(14, 36), (16, 36), (22, 40), (18, 38)],
        [(21, 34), (22, 36), (20, 36), (20, 32)],
    ]  # fmt: skip
    rings = [np.array(ring, dtype=np.float64) for ring in rings]
    points = np.array([(24.0, 30.0), (24.0, 42.0), (32.0, 42.0), (32.0, 36.0), (24.0, 36.0)])
    many = triangulate_many([rings], points=[points], rule="delaunay")[0]
    single = triangulate(rings, points=points, rule="delaunay")
    assert_same_fields(many, single)
    diagonals = {tuple(sorted(pair)) for t in single.triangles.tolist() for pair in
                 ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}  # fmt: skip
    index = {tuple(v): k for k, v in enumerate(single.vertices[:, :2].tolist())}
    assert tuple(sorted((index[(16.0, 36.0)], index[(20.0, 32.0)]))) in diagonals
