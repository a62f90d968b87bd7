"""MeshSet: points inserted in batches into many regions give the triangles that DelaunayMesh
gives one point at a time (the constrained Delaunay triangulation is unique under the tie
rule), with a consistent neighbour table, whatever the batches and the start triangles."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.geometry.delaunay_batch import MeshSet
from bsp_triangulate.geometry.delaunay_mesh import DelaunayMesh
from bsp_triangulate.geometry.predicates import orient_many

OUTER = np.array([(0.0, 0.0), (40.0, 0.0), (40.0, 30.0), (20.0, 15.0), (0.0, 40.0)])
ISLAND = np.array([(10.5, 10.5), (10.5, 14.5), (14.5, 14.5), (14.5, 10.5)])


def coordinate_triangles(x: np.ndarray, y: np.ndarray, triangles: np.ndarray) -> list:
    """Triangles as sorted triples of coordinate pairs, sorted: ids left out."""
    return sorted(tuple(sorted((x[i], y[i]) for i in row)) for row in triangles.tolist())


def check_links(mesh: MeshSet) -> None:
    """Counter-clockwise triangles; each slot's neighbour links back over the same edge."""
    count = mesh.triangle_count
    vertex, across = mesh.vertex[: 3 * count], mesh.across[: 3 * count]
    slot = np.arange(3 * count)
    k, base = slot % 3, slot - slot % 3
    start, end = vertex[base + (k + 1) % 3], vertex[base + (k + 2) % 3]
    linked = across >= 0
    other = across[linked]
    assert (across[other] == slot[linked]).all()
    assert (vertex[other - other % 3 + (other % 3 + 1) % 3] == end[linked]).all()
    assert (vertex[other - other % 3 + (other % 3 + 2) % 3] == start[linked]).all()
    tri = vertex.reshape(-1, 3)
    x, y = mesh.x, mesh.y
    corners = [c[tri[:, j]] for j in range(3) for c in (x, y)]
    assert (orient_many(*corners) > 0).all()


def polygon_mesh(shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    offset = np.array([shift, 0.0])
    t = triangulate([OUTER + offset, ISLAND + offset], rule="delaunay")
    return t.vertices[:, :2], t.triangles


@pytest.mark.parametrize("points", ["random", "lattice"])
def test_batch_insertion_gives_the_one_by_one_triangles(points: str):
    rng = np.random.default_rng(11)
    vertices, triangles = polygon_mesh()
    if points == "lattice":  # cocircular in fours, many on edges of the mesh
        xy = rng.integers(1, 40, (400, 2)).astype(float)
    else:
        xy = rng.uniform(0.0, 40.0, (400, 2))
    one_by_one = DelaunayMesh(vertices[:, 0], vertices[:, 1], triangles)
    single = one_by_one.insert_many(xy[:, 0], xy[:, 1])
    mesh = MeshSet(vertices[:, 0], vertices[:, 1], triangles, np.zeros(len(triangles), int))
    batch = mesh.insert(xy[:, 0], xy[:, 1], np.zeros(len(xy), int))
    # outside the polygon, in the island, on a vertex or a repeat: -1 both ways
    np.testing.assert_array_equal(batch >= 0, single >= 0)
    assert (batch < 0).any() and (batch >= 0).sum() > 200
    check_links(mesh)
    n = mesh.vertex_count
    assert coordinate_triangles(mesh.x[:n], mesh.y[:n], mesh.triangles()) == (
        coordinate_triangles(np.array(one_by_one.x), np.array(one_by_one.y), one_by_one.triangles())
    )


def test_many_regions_in_several_batches():
    rng = np.random.default_rng(12)
    parts = [polygon_mesh(100.0 * r) for r in range(12)]
    sizes = [len(v) for v, _ in parts]
    offsets = np.cumsum([0, *sizes[:-1]])
    vertices = np.concatenate([v for v, _ in parts])
    triangles = np.concatenate([t + o for (_, t), o in zip(parts, offsets)])
    region = np.repeat(np.arange(12), [len(t) for _, t in parts])
    mesh = MeshSet(vertices[:, 0], vertices[:, 1], triangles, region)
    singles = [DelaunayMesh(v[:, 0], v[:, 1], t) for v, t in parts]
    for _ in range(4):
        xy = rng.integers(1, 40, (12, 30, 2)).astype(float)
        xy[..., 0] += 100.0 * np.arange(12)[:, None]
        for single, points in zip(singles, xy):
            single.insert_many(points[:, 0], points[:, 1])
        # each region's points start from its first triangle
        first = np.unique(mesh.region[: mesh.triangle_count], return_index=True)[1]
        mesh.insert(xy[..., 0].ravel(), xy[..., 1].ravel(), np.repeat(first, 30))
        check_links(mesh)
    n = mesh.vertex_count
    got = coordinate_triangles(mesh.x[:n], mesh.y[:n], mesh.triangles())
    want = sorted(
        row
        for single in singles
        for row in coordinate_triangles(np.array(single.x), np.array(single.y), single.triangles())
    )
    assert got == want
    # triangles stay in their regions
    tri = mesh.triangles()
    assert (np.floor(mesh.x[tri[:, 0]] / 100.0) == mesh.region[: mesh.triangle_count]).all()


def test_points_on_edges_and_the_boundary_split_them():
    # a unit square in two triangles: a point on the diagonal (2 -> 4), one on the
    # boundary (1 -> 2), one on a corner (refused), one outside (refused)
    x, y = np.array([0.0, 1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0, 1.0])
    mesh = MeshSet(x, y, np.array([[0, 1, 2], [0, 2, 3]]), np.zeros(2, int))
    ids = mesh.insert(
        np.array([0.5, 0.5, 1.0, 2.0]), np.array([0.5, 0.0, 1.0, 0.5]), np.zeros(4, int)
    )
    assert sorted(ids[:2].tolist()) == [4, 5] and ids[2:].tolist() == [-1, -1]
    assert mesh.x[ids[:2]].tolist() == [0.5, 0.5] and mesh.y[ids[:2]].tolist() == [0.5, 0.0]
    assert mesh.triangle_count == 2 + 2 + 1
    check_links(mesh)
    assert (mesh.across[: 3 * mesh.triangle_count] < 0).sum() == 5  # the boundary edges


def test_fixed_edges_are_not_flipped():
    # a thin quadrilateral: its Delaunay diagonal (1, 3), or the other one (0, 2) fixed; the
    # points either side of the diagonal keep it only where it is fixed
    x, y = np.array([0.0, 1.0, 2.0, 1.0]), np.array([0.0, -0.1, 0.0, 0.1])
    px, py = np.array([1.5, 0.5]), np.array([0.01, -0.01])
    for fixed in (None, np.array([[2, 0]])):
        if fixed is None:
            triangles = np.array([[0, 1, 3], [1, 2, 3]])
        else:
            triangles = np.array([[0, 1, 2], [0, 2, 3]])
        mesh = MeshSet(x, y, triangles, np.zeros(2, int), fixed)
        assert mesh.insert(px, py, np.array([1, 0])).tolist() == [4, 5]
        check_links(mesh)
        one_by_one = DelaunayMesh(x, y, triangles, [] if fixed is None else [(0, 2)])
        one_by_one.insert_many(px, py)
        n = mesh.vertex_count
        assert coordinate_triangles(mesh.x[:n], mesh.y[:n], mesh.triangles()) == (
            coordinate_triangles(
                np.array(one_by_one.x), np.array(one_by_one.y), one_by_one.triangles()
            )
        )
        edges = {
            frozenset(e) for row in mesh.triangles().tolist() for e in zip(row, row[1:] + row[:1])
        }
        assert (frozenset((0, 2)) in edges) == (fixed is not None)


@pytest.mark.parametrize("seed", range(12))
def test_random_polygons_random_starts_several_batches(seed: int):
    # islands, lattice points (on edges, on vertices, repeated) or random ones, each batch
    # from random start triangles: the same triangles and the same points refused
    import random

    from tests.core.random_polygons import random_polygon

    rnd, rng = random.Random(seed), np.random.default_rng(seed)
    t = triangulate(random_polygon(rnd, islands=seed % 4, integer=seed % 2 == 0), rule="delaunay")
    v = t.vertices[:, :2]
    one_by_one = DelaunayMesh(v[:, 0], v[:, 1], t.triangles)
    mesh = MeshSet(v[:, 0], v[:, 1], t.triangles, np.zeros(len(t.triangles), int))
    low, high = v.min(axis=0), v.max(axis=0)
    for _ in range(3):
        xy = rng.uniform(low, high, (80, 2))
        if seed % 3 == 0:
            xy = np.round(xy)
        single = one_by_one.insert_many(xy[:, 0], xy[:, 1])
        start = rng.integers(0, mesh.triangle_count, len(xy))
        np.testing.assert_array_equal(mesh.insert(xy[:, 0], xy[:, 1], start) >= 0, single >= 0)
    check_links(mesh)
    n = mesh.vertex_count
    assert coordinate_triangles(mesh.x[:n], mesh.y[:n], mesh.triangles()) == (
        coordinate_triangles(np.array(one_by_one.x), np.array(one_by_one.y), one_by_one.triangles())
    )


def test_points_in_levels_from_hints_across_a_notch(monkeypatch):
    # a U: the points alternate between its two arms, so the point before each in the order
    # (the level's hint) is across the notch, where a walk is blocked by the boundary; the
    # walk then starts again from the point's own start triangle, and no region is scanned
    from bsp_triangulate.geometry.delaunay_mesh import containing_triangles

    outer = np.array(
        [(0.0, 0.0), (30, 0), (30, 40), (20, 40), (20, 10), (10, 10), (10, 40), (0, 40)]
    )
    t = triangulate([outer], rule="delaunay")
    v, triangles = t.vertices[:, :2], t.triangles
    rng = np.random.default_rng(3)
    left = np.column_stack([rng.uniform(0.5, 9.5, 300), rng.uniform(11, 39.5, 300)])
    right = left + np.array([20.0, 0.0])
    xy = np.stack([left, right], axis=1).reshape(-1, 2)  # left, right, left, ...
    start = containing_triangles(v[:, 0], v[:, 1], triangles, xy[:, 0], xy[:, 1])
    assert (start >= 0).all()
    scans = []
    original = MeshSet._scan
    monkeypatch.setattr(MeshSet, "_scan", lambda self, *a: scans.append(1) or original(self, *a))
    mesh = MeshSet(v[:, 0], v[:, 1], triangles, np.zeros(len(triangles), int))
    ids = mesh.insert(xy[:, 0], xy[:, 1], start)
    assert (ids >= 0).all() and not scans
    one_by_one = DelaunayMesh(v[:, 0], v[:, 1], triangles)
    one_by_one.insert_many(xy[:, 0], xy[:, 1])
    check_links(mesh)
    n = mesh.vertex_count
    assert coordinate_triangles(mesh.x[:n], mesh.y[:n], mesh.triangles()) == (
        coordinate_triangles(np.array(one_by_one.x), np.array(one_by_one.y), one_by_one.triangles())
    )
