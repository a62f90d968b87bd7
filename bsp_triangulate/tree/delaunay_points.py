"""Rule "delaunay" with interior points, built by insertion (docs/algorithm.md, section 5b).

The constrained Delaunay triangulation of a polygon's rings is made from any triangulation of
them by flips; the points are then inserted one at a time with flips
(``geometry/delaunay_mesh.py``, the ring edges as constraints), and the
BSP tree is read off the finished triangulation: the root on the sequence's first edge, each
node's children the triangles across its two new sides, stopping at the sequence's edges.
With the tie rule of ``predicates.cocircular_sign`` the triangulation is unique, so this gives
the tree the recursion builds over the bridged sequence, node for node, whenever the
sequence's bridges are edges of it (it checks; the caller builds the recursion otherwise).
The triangulation is built before the sequence: its edges spare the bridges' segment tests
(``bridges.MeshEdges``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..geometry.delaunay_mesh import DelaunayMesh
from ..triangulation import Triangulation


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


def tree_of_triangles(
    triangles: np.ndarray,
    vertices: np.ndarray,
    sequence: np.ndarray,
    mirrored: bool,
    tick: Callable[[float], None] | None = None,
) -> Triangulation | None:
    """The tree of :func:`tree_of_mesh` over ``sequence`` as a :class:`Triangulation` (rows of
    ``vertices``), or None."""
    if tick is not None:
        tick(0.9)
    rows = tree_of_mesh(triangles.tolist(), sequence.tolist(), mirrored, len(vertices))
    if rows is None:
        return None
    tri, parent, depth, side = rows
    return Triangulation(
        vertices=vertices,
        triangles=np.array(tri, dtype=np.int64).reshape(-1, 3),
        parent=np.array(parent, dtype=np.int64),
        depth=np.array(depth, dtype=np.int64),
        side=np.array(side, dtype=np.int8),
    )


def tree_of_mesh(
    triangles: list[list[int]], sequence: list[int], mirrored: bool, n: int
) -> tuple[list[tuple[int, int, int]], list[int], list[int], list[int]] | None:
    """The BSP tree of a triangulation of the bridged ``sequence`` (triangles counter-
    clockwise in the working plane, over ``n`` vertices): rows (triangle, parent, depth,
    side) in pre-order, as the recursion of docs/algorithm.md section 3 records them; None
    when the triangulation does not have every edge of the sequence or its triangles do not
    form one tree."""
    m = len(sequence)
    if m < 3 or len(triangles) != m - 2:
        return None
    # directed edge (a, b) as the integer a * n + b
    owner: dict[int, int] = {}
    for t, (a, b, c) in enumerate(triangles):
        owner[a * n + b] = t
        owner[b * n + c] = t
        owner[c * n + a] = t
    walls = set()
    for i in range(m):
        u, v = sequence[i], sequence[(i + 1) % m]
        if u * n + v not in owner and v * n + u not in owner:
            return None
        walls.add(u * n + v)
        walls.add(v * n + u)
    used = [False] * len(triangles)
    out: list[tuple[int, int, int]] = []
    parent: list[int] = []
    depth: list[int] = []
    side: list[int] = []
    get = owner.get
    # (chord a -> b with the sub-polygon on its left, V1 at a, parent, depth, side)
    stack = [(sequence[0], sequence[1], True, -1, 0, 0)]
    pop, push = stack.pop, stack.append
    while stack:
        a, b, v1_at_a, par, dep, sd = pop()
        t = get(a * n + b)
        if t is None or used[t]:
            return None
        used[t] = True
        p, q, r = triangles[t]
        c = r if p == a else (p if q == a else q)
        node = len(out)
        out.append((b, a, c) if mirrored else (a, b, c))
        parent.append(par)
        depth.append(dep)
        side.append(sd)
        # the right child (pushed first, taken last), then the left; upper: (a, c), V1 at a
        if v1_at_a:
            if c * n + b not in walls:
                push((c, b, False, node, dep + 1, 2))
            if a * n + c not in walls:
                push((a, c, True, node, dep + 1, 1))
        else:
            if a * n + c not in walls:
                push((a, c, True, node, dep + 1, 2))
            if c * n + b not in walls:
                push((c, b, False, node, dep + 1, 1))
    if len(out) != m - 2:
        return None
    return out, parent, depth, side
