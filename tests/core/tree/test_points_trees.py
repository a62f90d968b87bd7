"""The trees of many polygons read off their inserted meshes at once: the one-polygon
builder's results field by field, and every polygon whose mesh fails a check left to it."""

from __future__ import annotations

import random
from dataclasses import replace

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.tree.batch import triangulate_batch
from bsp_triangulate.tree.points_batch import insert_points
from bsp_triangulate.tree.points_trees import trees_of_inserted

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
