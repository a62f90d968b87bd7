"""The BSP trees of many polygons read off their inserted meshes at once (rule "delaunay" with
interior points, docs/algorithm.md, section 5b).

``points_batch.insert_points`` leaves each polygon's constrained Delaunay triangulation with
its points; here the one-polygon builder's depth-first walk (``delaunay_points``) reads every
tree in one loop, and its checks (the ring edges, the edges shared by two triangles, the
triangles reached, the areas) run on all polygons together.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..geometry.delaunay_mesh import edge_links
from ..geometry.points import as_point_array
from ..geometry.predicates import shoelace_products
from ..geometry.rings import normalise_rings
from ..geometry.rings_batch import ragged_index
from ..triangulation import Triangulation, TriangulationError
from .delaunay_points import depth_first
from .one_polygon import AREA_TOLERANCE
from .points_batch import InsertedMesh, swapped_links


def trees_of_inserted(
    polygons: Sequence[Sequence[object]],
    ring_meshes: Sequence[Triangulation | None],
    points: Sequence[object],
    inserted: Sequence[InsertedMesh | None],
) -> list[Triangulation | None]:
    """Per polygon (as :func:`insert_points` takes them, with its results): the BSP tree read
    off its inserted mesh by the one-polygon builder's walk (``delaunay_points.tree_of_cdt``),
    for all polygons at once, or None where the polygon is not plainly one the batch path
    took or a check fails (the one-polygon builder then decides and names what is wrong).

    Checked as that builder checks: each edge's two sides linked (the insertion's links where
    every polygon has them, else no directed edge used twice), the edges with one triangle
    exactly the ring edges, every triangle reached by the walk, the used points no repeats,
    and the triangles' absolute areas adding up to the polygon's (half its tolerance here:
    with the links, that is what rules out a triangle turned over)."""
    found: list[Triangulation | None] = [None] * len(polygons)
    for number, (ring_mesh, done) in enumerate(zip(ring_meshes, inserted)):
        if ring_mesh is not None and done is not None and not (done.point_ids >= 0).any():
            # no point used: the rings' own tree, as the one-polygon builder makes it
            found[number] = replace(ring_mesh, point_ids=done.point_ids)
    parts = _Parts.of(polygons, ring_meshes, points, inserted, found)
    if parts is None:
        return found
    n = len(parts.x)
    tri = parts.triangles
    owner = parts.region
    good = np.ones(len(parts.kept), dtype=bool)
    start, end = tri[:, [1, 2, 0]].ravel(), tri[:, [2, 0, 1]].ravel()
    if parts.across is None:
        across, repeated = edge_links(tri, n)
        good[owner[np.flatnonzero(repeated) // 3]] = False
    else:
        # the insertion's links: each pairs two slots of the same edge, opposite ways
        across = parts.across
        linked = np.flatnonzero(across >= 0)
        twin = across[linked]
        wrong = (
            (across[twin] != linked) | (start[twin] != end[linked]) | (end[twin] != start[linked])
        )
        good[owner[linked[wrong] // 3]] = False
    # the edges with one triangle are the ring edges, each once
    rim = np.flatnonzero(across < 0)
    rim_keys = np.minimum(start[rim], end[rim]) * n + np.maximum(start[rim], end[rim])
    ring_keys = parts.ring_edge_keys()
    rim_owner = owner[rim // 3]
    good[rim_owner[~np.isin(rim_keys, ring_keys)]] = False
    good &= np.bincount(rim_owner, minlength=len(good)) == parts.ring_edge_counts
    # the root: the outer ring's first edge, from its vertex 0 to 1
    first = parts.offsets[owner]
    root_slots = np.flatnonzero((start == np.repeat(first, 3)) & (end == np.repeat(first, 3) + 1))
    roots = np.full(len(good), -1, dtype=np.int64)
    roots[owner[root_slots // 3]] = root_slots
    good &= (roots >= 0) & (np.bincount(owner[root_slots // 3], minlength=len(good)) == 1)
    good &= parts.points_first & _areas_add_up(parts)
    if not good.any():
        return found
    (slot, parent, depth, side), reached = depth_first(across.tolist(), roots[good].tolist())
    taken = np.flatnonzero(good)
    good[taken[reached != parts.triangle_counts[taken]]] = False
    node_starts = np.cumsum(reached) - reached
    t, k = np.divmod(slot, 3)
    a, b, c = tri[t, (k + 1) % 3], tri[t, (k + 2) % 3], tri[t, k]
    for number, at, size in zip(taken.tolist(), node_starts.tolist(), reached.tolist()):
        if not good[number]:
            continue
        nodes = slice(at, at + size)
        offset = parts.offsets[number]
        ends = (a[nodes] - offset, b[nodes] - offset, c[nodes] - offset)
        mirrored = parts.mirror[number] < 0
        up = parent[nodes]
        found[parts.kept[number]] = Triangulation(
            vertices=parts.vertices[number],
            triangles=np.column_stack([ends[1], ends[0], ends[2]] if mirrored else ends),
            parent=np.where(up >= 0, up - at, -1),
            depth=depth[nodes].copy(),
            side=side[nodes].astype(np.int8),
            point_ids=parts.point_ids[number],
        )
    return found


@dataclass
class _Parts:
    """The polygons :func:`trees_of_inserted` takes (``kept``, their numbers), laid out one
    after another: per polygon its output ``vertices`` (ring vertices, then the used points in
    the order given), ``point_ids`` and ``mirror`` (-1.0: x mirrored in the working plane);
    all vertices' working coordinates ``x``, ``y``; all ``triangles`` (counter-clockwise in
    the working plane) and their ``region`` (polygon); per polygon its first vertex
    (``offsets``), ring vertices, triangles, whether its used points repeat none; per ring
    its polygon, first vertex, size and whether it is the outer ring."""

    kept: list[int]
    vertices: list[np.ndarray]
    point_ids: list[np.ndarray]
    mirror: np.ndarray
    x: np.ndarray
    y: np.ndarray
    triangles: np.ndarray
    across: np.ndarray | None
    region: np.ndarray
    offsets: np.ndarray
    ring_edge_counts: np.ndarray
    triangle_counts: np.ndarray
    points_first: np.ndarray
    ring_owner: np.ndarray
    ring_starts: np.ndarray
    ring_sizes: np.ndarray
    outer: np.ndarray

    @classmethod
    def of(
        cls,
        polygons: Sequence[Sequence[object]],
        ring_meshes: Sequence[Triangulation | None],
        points: Sequence[object],
        inserted: Sequence[InsertedMesh | None],
        found: Sequence[Triangulation | None],
    ) -> _Parts | None:
        """The polygons with a ring mesh and points inserted that are not ``found`` yet."""
        kept, vertices, point_ids, mirror, sizes, triangles, given_xy = [], [], [], [], [], [], []
        links: list[np.ndarray] | None = []
        for number, (ring_mesh, done) in enumerate(zip(ring_meshes, inserted)):
            if ring_mesh is None or done is None or found[number] is not None:
                continue
            try:
                clean, _ = normalise_rings(polygons[number], "xy")
                given = as_point_array(points[number])
            except TriangulationError:
                continue
            ring_sizes = [len(ring) for ring in clean]
            ring_count = len(ring_mesh.vertices)
            used = done.point_ids >= 0
            if (
                min(ring_sizes) < 3
                or len(done.point_ids) != len(given)
                or not np.array_equal(np.concatenate(clean), ring_mesh.vertices)
                or not np.array_equal(done.point_ids[used], ring_count + np.arange(int(used.sum())))
            ):
                continue
            m = -1.0 if done.mirrored else 1.0
            kept.append(number)
            vertices.append(np.concatenate([ring_mesh.vertices, given[used]]))
            point_ids.append(done.point_ids)
            mirror.append(m)
            sizes.append(ring_sizes)
            triangles.append(done.triangles[:, [1, 0, 2]] if m < 0 else done.triangles)
            if links is not None and (
                done.across is None
                or len(done.across) != 3 * len(done.triangles)
                or not len(done.across)
                or done.across.max() >= len(done.across)
            ):
                links = None  # linked below from the triangles
            elif links is not None:
                links.append(swapped_links(done.across) if m < 0 else done.across)
            given_xy.append(given[:, :2])
        if not kept:
            return None
        counts = np.array([len(v) for v in vertices], dtype=np.int64)
        offsets = np.cumsum(counts) - counts
        mirror_array = np.array(mirror)
        every = np.concatenate(vertices)
        triangle_counts = np.array([len(t) for t in triangles], dtype=np.int64)
        ring_sizes = np.array([size for per in sizes for size in per], dtype=np.int64)
        ring_owner = np.repeat(np.arange(len(kept)), [len(per) for per in sizes])
        within = np.concatenate([np.cumsum(per) - per for per in sizes]).astype(np.int64)
        return cls(
            kept=kept,
            vertices=vertices,
            point_ids=point_ids,
            mirror=mirror_array,
            x=every[:, 0] * np.repeat(mirror_array, counts),
            y=every[:, 1].copy(),
            triangles=np.concatenate(triangles) + np.repeat(offsets, triangle_counts)[:, None],
            across=None if links is None else _linked(links, triangle_counts),
            region=np.repeat(np.arange(len(kept)), triangle_counts),
            offsets=offsets,
            ring_edge_counts=np.array([sum(per) for per in sizes], dtype=np.int64),
            triangle_counts=triangle_counts,
            points_first=_used_points_first(given_xy, point_ids),
            ring_owner=ring_owner,
            ring_starts=offsets[ring_owner] + within,
            ring_sizes=ring_sizes,
            outer=within == 0,
        )

    def ring_edge_keys(self) -> np.ndarray:
        """Every ring edge as the integer min * n + max of its ends (n vertices in all)."""
        n = len(self.x)
        start = ragged_index(self.ring_starts, self.ring_sizes)
        end = start + 1
        last = np.cumsum(self.ring_sizes) - 1
        end[last] = self.ring_starts
        return np.minimum(start, end) * n + np.maximum(start, end)


def _linked(links: list[np.ndarray], triangle_counts: np.ndarray) -> np.ndarray:
    """Per-polygon links (slots from 0 in each) as one array over all their slots."""
    across = np.concatenate(links)
    starts = np.cumsum(triangle_counts) - triangle_counts
    base = np.repeat(3 * starts, 3 * triangle_counts)
    return np.where(across >= 0, across + base, -1)


def _used_points_first(given_xy: list[np.ndarray], point_ids: list[np.ndarray]) -> np.ndarray:
    """Per polygon: none of its used points repeats an earlier point of its own."""
    counts = np.array([len(p) for p in given_xy], dtype=np.int64)
    good = np.ones(len(given_xy), dtype=bool)
    if not counts.sum():
        return good
    owner = np.repeat(np.arange(len(given_xy)), counts)
    xy = np.concatenate(given_xy)
    used = np.concatenate(point_ids) >= 0
    order = np.lexsort((np.arange(len(xy)), xy[:, 1], xy[:, 0], owner))
    so, sx, sy = owner[order], xy[order, 0], xy[order, 1]
    repeat = (so[1:] == so[:-1]) & (sx[1:] == sx[:-1]) & (sy[1:] == sy[:-1])
    again = order[1:][repeat]
    good[owner[again[used[again]]]] = False
    return good


def _areas_add_up(parts: _Parts) -> np.ndarray:
    """Per polygon of ``parts``: its triangles' absolute areas add up to its net area in the
    working plane (``one_polygon.check_area``'s test with half its tolerance, so that what
    passes here passes there; the rest is left to that check)."""
    count = len(parts.kept)
    ring_rows = ragged_index(parts.offsets, parts.ring_edge_counts)
    ring_owner = np.repeat(np.arange(len(parts.ring_sizes)), parts.ring_sizes)
    x0, y0 = parts.x[parts.ring_starts], parts.y[parts.ring_starts]
    x = parts.x[ring_rows] - x0[ring_owner]
    y = parts.y[ring_rows] - y0[ring_owner]
    local_starts = np.cumsum(parts.ring_sizes) - parts.ring_sizes
    left, right = shoelace_products(x, y, local_starts, local_starts + parts.ring_sizes - 1)
    rings = np.abs(np.add.reduceat(left - right, local_starts))
    net = np.bincount(
        parts.ring_owner, weights=np.where(parts.outer, rings, -rings), minlength=count
    )
    ring_magnitude = np.bincount(
        np.repeat(parts.ring_owner, parts.ring_sizes),
        weights=np.abs(left) + np.abs(right),
        minlength=count,
    )
    corners = parts.triangles
    tx, ty = parts.x[corners], parts.y[corners]
    tx -= tx[:, :1]
    ty -= ty[:, :1]
    left = tx[:, 1] * ty[:, 2]
    right = ty[:, 1] * tx[:, 2]
    total = np.bincount(parts.region, weights=np.abs(left - right), minlength=count)
    magnitude = np.bincount(parts.region, weights=np.abs(left) + np.abs(right), minlength=count)
    eps = np.finfo(np.float64).eps
    bound = 0.5 * AREA_TOLERANCE * net + 16 * eps * (magnitude + ring_magnitude)
    return (net > 0) & (np.abs(total - net) <= bound)
