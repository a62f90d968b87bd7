"""The BSP trees of many polygons read off their inserted meshes at once (rule "delaunay" with
interior points, docs/algorithm.md, section 5b).

``points_batch.insert_points`` leaves each polygon's constrained Delaunay triangulation with
its points; here the one-polygon builder's reading (``breadth_first``) takes every tree at
once, and its checks (the ring edges, the edges shared by two triangles, the
triangles reached, the areas) run on all polygons together.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..geometry.delaunay_mesh import delaunay_faults, edge_links
from ..geometry.points import as_point_array, first_occurrences
from ..geometry.predicates import area_surely_clear, shoelace_products
from ..geometry.rings import normalise_rings, xy_mirror
from ..geometry.rings_batch import ragged_index, ring_edge_keys
from ..triangulation import Triangulation, TriangulationError
from .breadth_first import breadth_first
from .one_polygon import AREA_TOLERANCE
from .points_batch import InsertedMesh


def trees_of_inserted(
    polygons: Sequence[Sequence[object]],
    ring_meshes: Sequence[Triangulation | None],
    points: Sequence[object],
    inserted: Sequence[InsertedMesh | None],
    plane: str = "auto",
    rough: Sequence[bool] | None = None,
) -> list[Triangulation | None]:
    """Per polygon (as :func:`insert_points` takes them, with its results; ``plane`` as
    given to the engine; ``rough``: per polygon, whether its ring triangulation is any one,
    from ``rough_rings``): the BSP tree read
    off its inserted mesh by the one-polygon builder's walk (``delaunay_points.tree_of_cdt``),
    for all polygons at once, or None where the polygon is not plainly one the batch path
    took or a check fails (the one-polygon builder then decides and names what is wrong).

    Checked as that builder checks: each edge's two sides linked (the insertion's links where
    every polygon has them, else no directed edge used twice), the edges with one triangle
    all ring edges and as many as the ring edges, every triangle reached by the walk, the
    used points no repeats, and the triangles' absolute areas adding up to the polygon's
    (half its tolerance here; with the links, this is the check that catches a triangle
    turned over, beyond that tolerance, as in the one-polygon builder)."""
    found: list[Triangulation | None] = [None] * len(polygons)
    pieces = []
    for number, (ring_mesh, done) in enumerate(zip(ring_meshes, inserted)):
        if ring_mesh is None or done is None:
            continue
        piece = _Piece.of(number, polygons[number], points[number], done, plane)
        if piece is None or not np.array_equal(np.concatenate(piece.rings), ring_mesh.vertices):
            continue
        if not (done.point_ids >= 0).any():
            # no point used: the rings' own tree, as the one-polygon builder makes it (a
            # rough ring mesh is not: that builder decides)
            if rough is None or not rough[number]:
                found[number] = replace(ring_mesh, point_ids=done.point_ids)
        else:
            pieces.append(piece)
    _read_trees(pieces, found, known=False)
    return found


def trees_of_known(
    polygons: Sequence[Sequence[object]],
    points: Sequence[object],
    meshes: Sequence[object],
    plane: str,
) -> list[Triangulation | None]:
    """Per polygon with interior points and its mesh given (``mesh`` of
    :func:`~bsp_triangulate.api.triangulate`): the tree read off that mesh, for all polygons at
    once, where it is what the one-polygon builder takes from it; else None (that builder
    then decides). Taken where the polygon works in XY, its points repeat none and every
    one is a vertex of the mesh, the mesh passes the one-polygon builder's checks of a known
    mesh (every triangle strictly counter-clockwise, every directed edge once, every interior
    edge locally Delaunay under the tie rule, exactly) and of :func:`trees_of_inserted`,
    and the polygon's area is surely not negligible."""
    found: list[Triangulation | None] = [None] * len(polygons)
    pieces = []
    for number, (rings, given, mesh) in enumerate(zip(polygons, points, meshes)):
        if mesh is None or given is None or not len(given):
            continue
        try:
            triangles = np.asarray(mesh, dtype=np.int64)
        except (TypeError, ValueError):
            continue
        piece = _Piece.of(number, rings, given, None, plane)
        if piece is None or triangles.ndim != 2 or triangles.shape[1] != 3 or not len(triangles):
            continue
        ring_count = sum(len(ring) for ring in piece.rings)
        count = ring_count + len(piece.given)
        if triangles.min() < 0 or triangles.max() >= count:
            continue
        if np.count_nonzero(np.bincount(triangles.ravel(), minlength=count)[ring_count:]) != len(
            piece.given
        ):
            continue  # a point the mesh leaves out: the one-polygon builder decides why
        piece.mesh = InsertedMesh(
            triangles,
            ring_count + np.arange(len(piece.given)),
            xy_mirror(piece.rings) < 0,
        )
        pieces.append(piece)
    _read_trees(pieces, found, known=True)
    return found


@dataclass
class _Piece:
    """One polygon to read a tree for: its number, normalised rings (XY working plane), given
    points as (m, 3) and mesh."""

    number: int
    rings: list[np.ndarray]
    given: np.ndarray
    mesh: InsertedMesh | None

    @classmethod
    def of(
        cls, number: int, rings: object, points: object, mesh: InsertedMesh | None, plane: str
    ) -> _Piece | None:
        """The piece, or None where the rings or points do not normalise, the working plane
        is not XY, a ring has fewer than 3 vertices or the mesh's point rows are not the used
        points' in the order given."""
        try:
            clean, axes = normalise_rings(rings, plane)
            given = as_point_array(points)
        except TriangulationError:
            return None
        if axes != (0, 1) or not clean or min(len(ring) for ring in clean) < 3:
            return None
        if mesh is not None:
            used = mesh.point_ids >= 0
            ring_count = sum(len(ring) for ring in clean)
            if len(mesh.point_ids) != len(given) or not np.array_equal(
                mesh.point_ids[used], ring_count + np.arange(int(used.sum()))
            ):
                return None
        return cls(number, clean, given, mesh)


def _read_trees(pieces: list[_Piece], found: list[Triangulation | None], known: bool) -> None:
    """Into ``found``: the tree of every piece whose mesh passes the checks (``known``: also
    the known-mesh checks of :func:`trees_of_known`)."""
    parts = _Parts.of(pieces)
    if parts is None:
        return
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
    if known:
        good[owner[np.flatnonzero(delaunay_faults(parts.x, parts.y, tri, ties=True))]] = False
    # the edges with one triangle are the ring edges, each once
    rim = np.flatnonzero(across < 0)
    rim_keys = np.minimum(start[rim], end[rim]) * n + np.maximum(start[rim], end[rim])
    ring_keys = ring_edge_keys(parts.ring_starts, parts.ring_sizes, n)
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
        return
    (slot, parent, depth, side), reached = breadth_first(across, roots[good])
    taken = np.flatnonzero(good)
    good[taken[reached != parts.triangle_counts[taken]]] = False
    node_starts = np.cumsum(reached) - reached
    # every node's triangle in the output's XY (base vertices swapped where mirrored), its
    # parent numbered within its polygon: one pass over all, then a slice per polygon
    node_owner = np.repeat(taken, reached)
    k = slot % 3
    corner = tri.ravel()
    base = slot - k
    start_v, end_v = corner[base + _NEXT[k]], corner[base + _AFTER_NEXT[k]]
    swap = parts.mirror[node_owner] < 0
    local = np.empty((len(slot), 3), dtype=np.int64)
    shift = parts.offsets[node_owner]
    local[:, 0] = np.where(swap, end_v, start_v) - shift
    local[:, 1] = np.where(swap, start_v, end_v) - shift
    local[:, 2] = corner[slot] - shift
    parent = np.where(parent >= 0, parent - np.repeat(node_starts, reached), -1)
    side = side.astype(np.int8)
    for number, at, size in zip(taken.tolist(), node_starts.tolist(), reached.tolist()):
        if not good[number]:
            continue
        nodes = slice(at, at + size)
        found[parts.kept[number]] = Triangulation(
            vertices=parts.vertices[number],
            triangles=local[nodes],
            parent=parent[nodes],
            depth=depth[nodes],
            side=side[nodes],
            point_ids=parts.point_ids[number],
        )


# the triangle's slots k + 1 and k + 2 (mod 3) from its slot k
_NEXT = np.array([1, 2, 0])
_AFTER_NEXT = np.array([2, 0, 1])


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
    def of(cls, pieces: list[_Piece]) -> _Parts | None:
        """The pieces laid out one after another, or None where there are none."""
        if not pieces:
            return None
        kept, vertices, point_ids, mirror, sizes, triangles, given_xy = [], [], [], [], [], [], []
        links: list[np.ndarray] | None = []
        for piece in pieces:
            done = piece.mesh
            used = done.point_ids >= 0
            m = -1.0 if done.mirrored else 1.0
            kept.append(piece.number)
            vertices.append(np.concatenate([*piece.rings, piece.given[used]]))
            point_ids.append(done.point_ids)
            mirror.append(m)
            sizes.append([len(ring) for ring in piece.rings])
            triangles.append(done.triangles[:, [1, 0, 2]] if m < 0 else done.triangles)
            if links is not None and (
                done.across is None
                or len(done.across) != 3 * len(done.triangles)
                or not len(done.across)
                or done.across.max() >= len(done.across)
            ):
                links = None  # linked below from the triangles
            elif links is not None:
                links.append(done.across)
            given_xy.append(piece.given[:, :2])
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
    good[owner[used & ~first_occurrences(xy[:, 0], xy[:, 1], owner)]] = False
    return good


def _areas_add_up(parts: _Parts) -> np.ndarray:
    """Per polygon of ``parts``: its triangles' absolute areas add up to its net area in the
    working plane (``one_polygon.check_area``'s test with half its tolerance, so that what
    passes here passes there; the rest is left to that check), and that area is surely not
    negligible (``one_polygon.negligible_area``, with a margin for any summation order)."""
    count = len(parts.kept)
    # every vertex from its polygon's first, as the engine's guard takes them, scaled by a
    # power of two (exact) that keeps the products away from underflow and overflow
    sizes = np.diff(np.append(parts.offsets, len(parts.x)))
    owner = np.repeat(np.arange(count), sizes)
    x = parts.x - parts.x[parts.offsets][owner]
    y = parts.y - parts.y[parts.offsets][owner]
    span = np.maximum.reduceat(np.maximum(np.abs(x), np.abs(y)), parts.offsets)
    spread = (span > 0) & np.isfinite(span)
    scale = np.ldexp(1.0, -np.frexp(np.where(spread, span, 1.0))[1])
    x *= scale[owner]
    y *= scale[owner]
    ring_rows = ragged_index(parts.offsets, parts.ring_edge_counts)
    vertex_owner = owner[ring_rows]
    local_starts = np.cumsum(parts.ring_sizes) - parts.ring_sizes
    left, right = shoelace_products(
        x[ring_rows], y[ring_rows], local_starts, local_starts + parts.ring_sizes - 1
    )
    rings = np.abs(np.add.reduceat(left - right, local_starts))
    net = np.bincount(
        parts.ring_owner, weights=np.where(parts.outer, rings, -rings), minlength=count
    )
    ring_magnitude = np.bincount(
        vertex_owner, weights=np.abs(left) + np.abs(right), minlength=count
    )
    clear = spread & area_surely_clear(net, ring_magnitude, parts.ring_edge_counts)
    corners = parts.triangles
    tx, ty = x[corners], y[corners]
    tx -= tx[:, :1]
    ty -= ty[:, :1]
    left = tx[:, 1] * ty[:, 2]
    right = ty[:, 1] * tx[:, 2]
    total = np.bincount(parts.region, weights=np.abs(left - right), minlength=count)
    magnitude = np.bincount(parts.region, weights=np.abs(left) + np.abs(right), minlength=count)
    eps = np.finfo(np.float64).eps
    bound = 0.5 * AREA_TOLERANCE * net + 16 * eps * (magnitude + ring_magnitude)
    return clear & (net > 0) & (np.abs(total - net) <= bound)
