"""Vectorised batch path of ``triangulate_many``: many small polygons in lock-step.

Contract of :func:`triangulate_batch`:

- ``triangulate_batch(polygons, rule)`` returns one entry per polygon, in input order: a
  :class:`Triangulation` equal field by field to what ``api.triangulate(rings, rule=rule)``
  returns (``planar_tolerance`` 0), or None where the polygon is left to the engine.
- None is returned for anything the batch path does not decide exactly like the engine:
  polygons with more than ``max_vertices`` vertices, rings that touch each other or
  themselves (shared points, a vertex on an edge), islands with fewer than 3 points or zero
  area, outer rings of zero or near-zero area, polygons whose net area may be negligible
  (``one_polygon.negligible_area``), steep faces (working plane other than XY),
  nearly equal bridge distances, unusual input (empty rings, non-finite or malformed points),
  rules other than "first", "elevation" and "delaunay", under rule "delaunay" islands that
  would wait for a Delaunay bridge (docs/algorithm.md 5a), and polygons the engine would
  reject (its error message comes from the engine).
- The result arrays are slices of arrays shared by the batch (disjoint per polygon).
- Speed comes from many polygons per call: every round of the tree costs a fixed number of
  numpy calls, so calls of a few polygons gain little; thousands per call is the intent.
- Polygons of ``max_vertices`` to ``MID_VERTICES`` vertices are batched too, in groups of their
  own sorted by size, when a call has at least ``MID_MIN_COUNT`` of them: their trees are deep
  (a round per fan triangle), so they pay off only in numbers; a few are faster one by one in
  the one-polygon builder.

Pipeline: ``geometry.rings_batch`` (normalisation), ``geometry.bridges_batch`` (islands),
``tree.lockstep`` (tree).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry.bridges_batch import bridge_sequences
from ..geometry.delaunay_links import LINKED_ISLANDS
from ..geometry.rings_batch import (
    FlatRings,
    as_xyz,
    clear_area,
    covers_in_order,
    flatten_points,
    flatten_rings,
    net_areas,
    ragged_index,
    touching_polygons,
)
from ..geometry.validity import proven_valid_rings
from ..packed import PackedPolygons, PackedTriangulations, Piece
from ..triangulation import Triangulation
from .lockstep import Trees, build_trees
from .one_polygon import AREA_TOLERANCE

# Larger polygons go to the engine (its grid index beats the all-edges tests there)...
MAX_VERTICES = 256
# ... unless a call has many of them up to this size: they are batched among themselves
MID_VERTICES = 640
MID_MIN_COUNT = 32
_RULES = ("first", "elevation", "delaunay")
# polygons per internal group; vertices per group of mid-size polygons (their trees take a
# round per fan triangle, hundreds of rounds of fixed cost: fewer, larger groups pay off)
_GROUP = 10_000
_MID_GROUP_VERTICES = 500_000
# polygons with at least this many vertices are first offered to the validity proof
_PROOF_VERTICES = 16


def triangulate_batch(
    polygons: Sequence[Sequence[object]],
    rule: str = "first",
    max_vertices: int = MAX_VERTICES,
    proven: Sequence[bool] | None = None,
    plane: str = "auto",
) -> list[Triangulation | None]:
    """Triangulations of ``polygons`` (each ``[outer ring, island, ...]``); None where the
    polygon is left to the engine (see the module docstring).

    ``proven``: per polygon, True where the caller has proven it valid with
    ``validity.proven_valid`` (no two of its vertices coincide, none lies on an edge other
    than its own two); the batch path then does not look for touching rings in it.
    ``plane``: "xy" works every polygon in XY, "auto" leaves steep faces to the engine.
    """
    xy = plane == "xy"

    def flatten(index: np.ndarray, limit: int) -> FlatRings:
        if len(index) and index[-1] - index[0] == len(index) - 1:
            return flatten_rings(polygons[int(index[0]) : int(index[-1]) + 1], limit, xy)
        return flatten_rings([polygons[i] for i in index.tolist()], limit, xy)

    def point_counts(index: np.ndarray) -> np.ndarray:
        return np.array([_point_count(polygons[i]) for i in index.tolist()], dtype=np.int64)

    pieces = batch_pieces(len(polygons), flatten, point_counts, rule, max_vertices, proven)
    # each result is a slice of its piece's arrays: no copy of them all into one
    results: list[Triangulation | None] = [None] * len(polygons)
    for piece in pieces:
        for index, result in zip(piece.index.tolist(), piece.results.to_list()):
            results[index] = result
    return results


def triangulate_batch_packed(
    polygons: PackedPolygons,
    rule: str = "first",
    max_vertices: int = MAX_VERTICES,
    proven: Sequence[bool] | None = None,
    plane: str = "auto",
    alive: Callable[[], None] | None = None,
) -> list[Piece]:
    """:func:`triangulate_batch` of packed polygons: the results of the polygons it decides,
    as pieces (the others are left to the engine); ``alive``: called every lock-step round
    (it may raise to stop)."""
    ring_start = polygons.ring_start
    first_ring = polygons.first_ring
    # a polygon with an empty ring or no ring at all is left to the engine
    empty_ring = np.zeros(len(polygons), dtype=bool)
    owner = np.repeat(np.arange(len(polygons)), polygons.ring_count)
    empty_ring[owner[polygons.ring_len == 0]] = True
    usable_counts = np.where(empty_ring | (polygons.ring_count == 0), -1, polygons.ring_count)
    points = as_xyz(polygons.points)

    def flatten(index: np.ndarray, limit: int) -> FlatRings:
        counts = usable_counts[index]
        rings = ragged_index(first_ring[index], np.maximum(counts, 0))
        lengths = polygons.ring_len[rings]
        if len(rings) and rings[-1] - rings[0] == len(rings) - 1:
            start = int(ring_start[rings[0]])
            raw = points[start : start + int(lengths.sum())]
        else:
            raw = points[ragged_index(ring_start[rings], lengths)]
        return flatten_points(raw, lengths, counts, limit, xy=plane == "xy")

    sizes = np.bincount(owner, weights=polygons.ring_len, minlength=len(polygons))

    def point_counts(index: np.ndarray) -> np.ndarray:
        return np.where(usable_counts[index] > 0, sizes[index].astype(np.int64), -1)

    return batch_pieces(len(polygons), flatten, point_counts, rule, max_vertices, proven, alive)


def batch_pieces(
    count: int,
    flatten: Callable[[np.ndarray, int], FlatRings],
    point_counts: Callable[[np.ndarray], np.ndarray],
    rule: str,
    max_vertices: int,
    proven: Sequence[bool] | None,
    alive: Callable[[], None] | None = None,
) -> list[Piece]:
    """The batch path over ``count`` polygons: ``flatten(index, max_vertices)`` normalises
    the polygons ``index`` (increasing), ``point_counts(index)`` gives their points as given
    (-1: unusual). Returns the pieces of the polygons decided here (indices of the call)."""
    pieces: list[Piece] = []
    if rule not in _RULES:
        return pieces
    known = np.zeros(count, dtype=bool)
    if proven is not None:
        known[:] = np.asarray(proven, dtype=bool)
    decided = np.zeros(count, dtype=bool)
    again: list[np.ndarray] = []

    def parts(index: np.ndarray, limit: int) -> list[tuple[np.ndarray, FlatRings, str]]:
        """The polygons ``index`` normalised, as (polygons, rings, rule) to triangulate:
        under rule elevation, the level polygons (one z) apart under rule first, which gives
        them the same apexes (all candidates equally close: the first correct one taken)
        with far fewer tests."""
        flat = flatten(index, limit)
        if rule != "elevation":
            return [(index, flat, rule)]
        level = _level(flat)
        if level.all() or not level.any():
            return [(index, flat, "first" if level.all() else rule)]
        return [
            (part, flatten(part, limit), name)
            for part, name in ((index[level], "first"), (index[~level], rule))
        ]

    def run(index: np.ndarray, limit: int) -> None:
        for part, rings, name in parts(index, limit):
            group = _triangulate(rings, name, known[part], alive=alive)
            # a tree to build again keeps its place (and its incomplete rows) in the piece
            pieces.append(_globalised(group.piece(), part))
            decided[pieces[-1].index] = True
            again.append(part[group.again()])

    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        # groups of moderate size keep the working arrays in the cache
        for first in range(0, count, _GROUP):
            run(np.arange(first, min(first + _GROUP, count), dtype=np.int64), max_vertices)
        if max_vertices < MID_VERTICES:
            for index in _mid_size_groups(np.flatnonzero(~decided), point_counts, max_vertices):
                run(index, MID_VERTICES)
        redo = np.sort(np.concatenate(again)) if again else np.zeros(0, dtype=np.int64)
        if len(redo):
            # the trees that the proven-valid shortcut left incomplete, with every table, all
            # in one group (a few such trees would keep each group going for as many rounds
            # as a whole group)
            for part, rings, name in parts(redo, MID_VERTICES):
                valid = np.ones(len(part), dtype=bool)
                fixed = _triangulate(rings, name, valid, False, alive).piece()
                fixed = _globalised(fixed, part)
                for k, wanted in enumerate(again):
                    mine = wanted[np.isin(wanted, part)]
                    if len(mine):
                        pieces[k] = _take_over(pieces[k], mine, fixed)
    return pieces


def _level(flat: FlatRings) -> np.ndarray:
    """Per polygon of ``flat``: all its vertices have the same z (exactly)."""
    count = flat.poly_vcount
    level = np.ones(len(count), dtype=bool)
    some = np.flatnonzero(count > 0)
    if len(some):
        start = flat.poly_vstart[some]
        high = np.maximum.reduceat(flat.vz, start)
        low = np.minimum.reduceat(flat.vz, start)
        level[some] = high == low
    return level


def _take_over(piece: Piece, wanted: np.ndarray, fixed: Piece) -> Piece:
    """``piece`` with the trees of its polygons ``wanted`` (call indices) from ``fixed``; a
    polygon that ``fixed`` does not hold leaves the piece."""
    mine = np.searchsorted(piece.index, wanted)
    at = np.minimum(np.searchsorted(fixed.index, wanted), max(len(fixed.index) - 1, 0))
    r, f = piece.results, fixed.results
    found = np.zeros(len(wanted), dtype=bool)
    if len(fixed.index):
        found = fixed.index[at] == wanted
        found[found] = r.triangle_count[mine[found]] == f.triangle_count[at[found]]
    m, t = mine[found], at[found]
    rows = ragged_index(r.triangle_start[m], r.triangle_count[m])
    source = ragged_index(f.triangle_start[t], f.triangle_count[t])
    for name in ("triangles", "parent", "depth", "side"):
        getattr(r, name)[rows] = getattr(f, name)[source]
    if found.all():
        return piece
    keep = np.ones(len(piece.index), dtype=bool)
    keep[mine[~found]] = False
    kept = np.flatnonzero(keep)
    return Piece(piece.index[kept], r.take(kept))


def _globalised(piece: Piece, index: np.ndarray) -> Piece:
    piece.index = index[piece.index]
    return piece


def _mid_size_groups(
    left: np.ndarray, point_counts: Callable[[np.ndarray], np.ndarray], max_vertices: int
) -> list[np.ndarray]:
    """Groups of similar size (each in polygon order) of the polygons of more than
    ``max_vertices`` and at most ``MID_VERTICES`` points among ``left``, if there are at
    least ``MID_MIN_COUNT``."""
    counts = point_counts(left)
    mid = (counts > max_vertices) & (counts <= MID_VERTICES)
    if int(mid.sum()) < MID_MIN_COUNT:
        return []
    chosen_all = left[mid]
    sizes = counts[mid]
    order = np.argsort(sizes, kind="stable")
    chosen_all, sizes = chosen_all[order], sizes[order].tolist()
    groups = []
    start = 0
    while start < len(chosen_all):
        stop, total = start, 0
        while stop < len(chosen_all) and (stop == start or total < _MID_GROUP_VERTICES):
            total += sizes[stop]
            stop += 1
        # flatten wants increasing indices
        groups.append(np.sort(chosen_all[start:stop]))
        start = stop
    return groups


def _point_count(rings: object) -> int:
    """Points in all rings of a polygon as given (closing points included), or -1."""
    try:
        if isinstance(rings, np.ndarray) and rings.ndim == 2:
            return len(rings)
        return sum(len(ring) for ring in rings)
    except TypeError:
        return -1


def sequence_twins(ext: np.ndarray, ext_start: np.ndarray) -> np.ndarray:
    """Per position: the other position of the same vertex in its sequence (bridge ends), or
    -1; position 0 of each sequence (never inside a sub-polygon) and triples are left out."""
    ids = ext.copy()
    ids[ext_start] = -1
    valid = ids >= 0
    counts = np.bincount(ids[valid], minlength=int(ext.max(initial=0)) + 1)
    twin = np.full(len(ext), -1, dtype=np.int64)
    paired = np.flatnonzero(valid & (counts[np.maximum(ids, 0)] == 2))
    paired = paired[np.argsort(ids[paired], kind="stable")]
    first, second = paired[0::2], paired[1::2]
    twin[first] = second
    twin[second] = first
    return twin


@dataclass
class _Group:
    """The results of one group of polygons (``flat``): the polygons ``empties`` (no
    triangles) and the ``trees`` of the polygons ``polys`` (indices into ``flat``)."""

    flat: FlatRings
    empties: np.ndarray
    polys: np.ndarray
    trees: Trees | None

    def again(self) -> np.ndarray:
        """The polygons whose trees are to be built again with every table."""
        if self.trees is None:
            return np.zeros(0, dtype=np.int64)
        return self.polys[self.trees.again]

    def piece(self) -> Piece:
        """The piece of the polygons without triangles and of those whose trees completed or
        are to be built again."""
        trees = self.trees
        if trees is None:
            return _piece(self.flat, self.empties, self.polys, None, None)
        kept = trees.ok | trees.again
        return _piece(self.flat, self.empties, self.polys[kept], trees, kept)


def _triangulate(
    flat: FlatRings,
    rule: str,
    known: np.ndarray,
    shortcut: bool = True,
    alive: Callable[[], None] | None = None,
) -> _Group:
    """The polygons of ``flat`` that the batch path decides; the trees of proven-valid
    polygons that did not complete with the shortcut are marked ``again`` (built with every
    table later); ``shortcut=False`` builds every tree with every table; ``alive``: called
    every lock-step round."""
    wx = np.where(np.repeat(flat.mirrored[flat.ring_poly], flat.ring_len), -flat.vx, flat.vx)
    wy = flat.vy
    handled = flat.handled.copy()
    # a polygon proven valid (by the caller, or here) has no touching rings: the search is
    # left to the others (the proof pays off where the search is costly, on polygons of more
    # than a few vertices)
    undecided = handled & ~flat.empty & ~known
    proven = known | proven_valid_rings(
        flat.vx,
        flat.vy,
        flat.ring_start,
        flat.ring_len,
        flat.ring_poly,
        undecided & (flat.poly_vcount >= _PROOF_VERTICES),
    )
    undecided &= ~proven
    handled &= ~touching_polygons(flat, wx, undecided)
    # the engine gives slivers of negligible net area no triangles: left to it
    areas = net_areas(flat, wx)
    handled &= clear_area(flat, wx, areas) | flat.empty
    if rule == "delaunay":  # their bridges follow links (geometry/delaunay_links.py)
        handled &= flat.poly_rings - 1 <= LINKED_ISLANDS
    empties = np.flatnonzero(handled & flat.empty)
    polys = np.flatnonzero(handled & ~flat.empty)
    if len(polys) == 0:
        return _Group(flat, empties, polys, None)
    seq, seq_start, seq_len, bridged = bridge_sequences(flat, wx, wy, polys, rule == "delaunay")
    polys_ok = polys[bridged]
    seq_start, seq_len = seq_start[bridged], seq_len[bridged]
    # each sequence with its closing repeat of position 0
    ext_len = seq_len + 1
    ext_start = np.cumsum(ext_len) - ext_len
    ext = np.empty(int(ext_len.sum()), dtype=np.int64)
    ext[ragged_index(ext_start, seq_len)] = seq[ragged_index(seq_start, seq_len)]
    ext[ext_start + seq_len] = seq[seq_start]
    ext_owner = np.repeat(np.arange(len(polys_ok), dtype=np.int64), ext_len)
    local = ext - flat.poly_vstart[polys_ok][ext_owner]
    trees = build_trees(
        local,
        sequence_twins(ext, ext_start),
        wx[ext],
        wy[ext],
        flat.vz[ext],
        ext_start,
        seq_len,
        flat.mirrored[polys_ok],
        rule,
        proven[polys_ok] if shortcut else None,
        alive,
    )
    # a tree whose triangles do not cover its polygon exactly is left to the engine, which
    # reports it (none is expected: every triangle passed exact tests)
    trees.ok &= _areas_add_up(flat, wx, areas, polys_ok, trees)
    return _Group(flat, empties, polys_ok, trees)


def _areas_add_up(
    flat: FlatRings, wx: np.ndarray, areas: tuple, polys: np.ndarray, trees: Trees
) -> np.ndarray:
    """Per tree of ``polys``: its triangles' absolute areas add up to its polygon's net
    area (``one_polygon.check_area``'s test, with the same tolerance); ``areas``: the
    polygons' ``net_areas``."""
    good = np.zeros(len(polys), dtype=bool)
    done = np.flatnonzero(trees.ok)
    if len(done) == 0:
        return good
    count = trees.count[done]
    if len(done) == len(polys) and covers_in_order(trees.start, trees.count, len(trees.triangles)):
        corners = trees.triangles.copy()
    else:
        corners = trees.triangles[ragged_index(trees.start[done], count)]
    first = np.cumsum(count) - count
    corners += np.repeat(flat.poly_vstart[polys[done]], count)[:, None]
    x, y = wx[corners], flat.vy[corners]
    x -= x[:, :1]
    y -= y[:, :1]
    left = x[:, 1] * y[:, 2]
    right = y[:, 1] * x[:, 2]
    total = np.add.reduceat(np.abs(left - right), first)
    np.abs(left, out=left)
    np.abs(right, out=right)
    left += right
    magnitude = np.add.reduceat(left, first)
    net, ring_magnitude = areas
    area = np.abs(net[polys[done]])
    eps = np.finfo(np.float64).eps
    bound = AREA_TOLERANCE * area + 16 * eps * (magnitude + ring_magnitude[polys[done]])
    good[done] = np.abs(total - area) <= bound
    return good


def _piece(
    flat: FlatRings,
    empties: np.ndarray,
    tree_polys: np.ndarray,
    trees: Trees | None,
    kept: np.ndarray | None,
) -> Piece:
    """The results of the polygons ``empties`` (no triangles) and ``tree_polys`` (the
    sequences ``kept`` of ``trees``, in order)."""
    decided = np.zeros(len(flat.handled), dtype=bool)
    decided[empties] = True
    decided[tree_polys] = True
    index = np.flatnonzero(decided)
    vertex_count = flat.poly_vcount[index]
    if len(index) == len(decided):
        vertices = flat.vertices
    else:
        vertices = flat.vertices[ragged_index(flat.poly_vstart[index], vertex_count)]
    if trees is None or not len(tree_polys):
        return Piece(index, PackedTriangulations.without_triangles(vertices, vertex_count))
    triangle_count = np.zeros(len(index), dtype=np.int64)
    triangle_count[np.searchsorted(index, tree_polys)] = trees.count[kept]
    triangles, parent, depth, side = trees.triangles, trees.parent, trees.depth, trees.side
    if not kept.all():
        rows = ragged_index(trees.start[kept], trees.count[kept])
        triangles, parent, depth, side = triangles[rows], parent[rows], depth[rows], side[rows]
    return Piece(
        index,
        PackedTriangulations(
            vertices, vertex_count, triangles, triangle_count, parent, depth, side
        ),
    )
