"""Rule "delaunay" with interior points, built by insertion (docs/algorithm.md, section 5b).

The constrained Delaunay triangulation of a polygon's rings is made from any triangulation of
them by flips; the points are then inserted one at a time with flips
(``geometry/delaunay_mesh.py``, the ring edges as constraints), and the BSP tree is read off
the finished triangulation level by level from the outer ring's first edge
(``breadth_first.py``), never across a ring edge: the interior edges it does not cross are
the bridges of the sequence the tree stands for, so that no bridge has to be searched for.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..geometry.delaunay_mesh import DelaunayMesh, edge_links, slot_keys
from ..triangulation import Triangulation
from .breadth_first import breadth_first


def points_mesh(
    x: np.ndarray,
    y: np.ndarray,
    ring_triangles: np.ndarray,
    ring_count: int,
    mirrored: bool,
    tick: Callable[[float], None] | None = None,
    ring_edges: list[tuple[int, int]] = (),
) -> np.ndarray | None:
    """(t, 3) vertex ids, counter-clockwise in the working plane: the constrained Delaunay
    triangulation of the rings (``ring_triangles``, any triangulation of them, flipped until
    locally Delaunay; ``ring_edges``: the vertex pairs never flipped) with every point (the
    vertices from ``ring_count`` on) inserted, or None where a point could not be inserted."""
    triangles = np.asarray(ring_triangles, dtype=np.int64)
    if mirrored:
        triangles = triangles[:, [1, 0, 2]]  # counter-clockwise in the working plane
    mesh = DelaunayMesh(x[:ring_count], y[:ring_count], triangles, ring_edges)
    mesh.make_delaunay()  # the rings' constrained Delaunay triangulation
    if tick is not None:
        tick(0.0)
    ids = mesh.insert_many(x[ring_count:], y[ring_count:])
    if (ids < 0).any():
        return None
    # mesh ids are in insertion order: back to the vertex rows
    vertex_of = np.arange(ring_count + len(ids), dtype=np.int64)
    vertex_of[ids] = ring_count + np.arange(len(ids))
    return vertex_of[mesh.triangles()]


def tree_of_cdt(
    triangles: np.ndarray,
    vertices: np.ndarray,
    walls: tuple[np.ndarray, np.ndarray],
    mirrored: bool,
    tick: Callable[[float], None] | None = None,
) -> Triangulation | None:
    """The BSP tree of a triangulation of a polygon (``triangles`` counter-clockwise in the
    working plane, rows of ``vertices``), as a :class:`Triangulation`; ``walls``: the start and
    end vertex of every ring edge, the polygon on its left. None where some ring edge is not
    an edge of the triangulation, another edge is not shared by two triangles, a directed edge
    is used twice, or the triangles are not all reached from the root.

    The tree grows breadth-first over the triangles (docs/algorithm.md, section 5b): the root
    on the outer ring's first edge, each node's left child across its new side at V1, its
    right child across the one at V2, never across a ring edge nor into a triangle already in
    the tree. The interior edges it does not cross are the bridges of the sequence it stands
    for.
    """
    if tick is not None:
        tick(0.9)
    tri = np.asarray(triangles, dtype=np.int64)
    count, n = len(tri), len(vertices)
    starts, ends = walls
    if count == 0 or not len(starts):
        return None
    # slot 3 t + k: the directed edge from corner k + 1 to corner k + 2 of triangle t
    across, repeated = edge_links(tri, n)
    if repeated.any():
        return None
    keys = slot_keys(tri, n)
    rims = starts * n + ends
    wall = np.isin(keys, rims)
    # every edge is a ring edge or shared by two triangles: no gap, nothing left over
    if not np.isin(rims, keys).all() or (~wall & (across < 0)).any():
        return None
    twins = across[wall]
    across[wall] = -1
    across[twins[twins >= 0]] = -1
    root = int(np.flatnonzero(keys == rims[0])[0])
    (slot, parent, depth, side), sizes = breadth_first(across, np.array([root]))
    if sizes[0] != count:
        return None
    t, k = np.divmod(slot, 3)
    a, b, c = tri[t, (k + 1) % 3], tri[t, (k + 2) % 3], tri[t, k]
    return Triangulation(
        vertices=vertices,
        triangles=np.column_stack([b, a, c] if mirrored else [a, b, c]),
        parent=parent,
        depth=depth,
        side=side.astype(np.int8),
    )
