"""Vectorised batch path of ``triangulate_many``: many small polygons in lock-step.

Contract of :func:`triangulate_batch`:

- ``triangulate_batch(polygons, rule)`` returns one entry per polygon, in input order: a
  :class:`Triangulation` equal field by field to what ``engine.triangulate(rings, rule=rule)``
  returns (``planar_tolerance`` 0), or None where the polygon is left to the engine.
- None is returned for anything the batch path does not decide exactly like the engine:
  polygons with more than ``max_vertices`` vertices, rings that touch each other or
  themselves (shared points, a vertex on an edge), islands with fewer than 3 points or zero
  area, outer rings of zero or near-zero area, polygons whose net area may be negligible
  (``engine.negligible_area``), steep faces (working plane other than XY),
  nearly equal bridge distances, unusual input (empty rings, non-finite or malformed points),
  rules other than "first" and "elevation", and polygons the engine would reject (its error
  message comes from the engine).
- The result arrays are slices of arrays shared by the batch (disjoint per polygon).
- Speed comes from many polygons per call: every round of the tree costs a fixed number of
  numpy calls, so calls of a few polygons gain little; thousands per call is the intent.
- Polygons of ``max_vertices`` to ``MID_VERTICES`` vertices are batched too, in groups of their
  own sorted by size, when a call has at least ``MID_MIN_COUNT`` of them: their trees are deep
  (a round per fan triangle), so they pay off only in numbers (measured: 200 concave polygons
  of 300 vertices 5x faster than the engine, 100 of 600 2.3x; 6 irregular ones 3x slower).

Pipeline: ``batch_rings`` (normalisation), ``batch_bridges`` (islands), ``batch_bsp`` (tree).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .batch_bridges import bridge_sequences
from .batch_bsp import build_trees
from .batch_rings import clear_area, flatten_rings, ragged_index, touching_polygons
from .triangulation import Triangulation
from .validity import proven_valid_rings

# Larger polygons go to the engine (its grid index beats the all-edges tests there)...
MAX_VERTICES = 256
# ... unless a call has many of them up to this size: they are batched among themselves
MID_VERTICES = 640
MID_MIN_COUNT = 32
_RULES = {"first": False, "elevation": True}
# polygons per internal group; vertices per group of mid-size polygons
_GROUP = 10_000
_MID_GROUP_VERTICES = 200_000
# polygons with at least this many vertices are first offered to the validity proof
_PROOF_VERTICES = 16


def triangulate_batch(
    polygons: Sequence[Sequence[object]],
    rule: str = "first",
    max_vertices: int = MAX_VERTICES,
    proven: Sequence[bool] | None = None,
) -> list[Triangulation | None]:
    """Triangulations of ``polygons`` (each ``[outer ring, island, ...]``); None where the
    polygon is left to the engine (see the module docstring).

    ``proven``: per polygon, True where the caller has proven it valid with
    ``validity.proven_valid`` (no two of its vertices coincide, none lies on an edge other
    than its own two); the batch path then does not look for touching rings in it.
    """
    results: list[Triangulation | None] = [None] * len(polygons)
    if rule not in _RULES:
        return results
    known = np.zeros(len(polygons), dtype=bool)
    if proven is not None:
        known[:] = np.asarray(proven, dtype=bool)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        # groups of moderate size keep the working arrays in the cache
        for first in range(0, len(polygons), _GROUP):
            group = polygons[first : first + _GROUP]
            results[first : first + len(group)] = _triangulate(
                group,
                _RULES[rule],
                max_vertices,
                [None] * len(group),
                known[first : first + len(group)],
            )
        if max_vertices < MID_VERTICES:
            _triangulate_mid_size(polygons, _RULES[rule], max_vertices, results, known)
    return results


def _triangulate_mid_size(
    polygons: Sequence[Sequence[object]],
    exhaustive: bool,
    max_vertices: int,
    results: list[Triangulation | None],
    known: np.ndarray,
) -> None:
    """Batch the polygons of more than ``max_vertices`` and at most ``MID_VERTICES`` points
    left so far, in groups of similar size, if there are at least ``MID_MIN_COUNT``."""
    sizes = {}
    for index, done in enumerate(results):
        if done is None:
            count = _point_count(polygons[index])
            if max_vertices < count <= MID_VERTICES:
                sizes[index] = count
    if len(sizes) < MID_MIN_COUNT:
        return
    order = sorted(sizes, key=sizes.__getitem__)
    start = 0
    while start < len(order):
        stop, total = start, 0
        while stop < len(order) and (stop == start or total < _MID_GROUP_VERTICES):
            total += sizes[order[stop]]
            stop += 1
        chosen = order[start:stop]
        done = _triangulate(
            [polygons[i] for i in chosen],
            exhaustive,
            MID_VERTICES,
            [None] * len(chosen),
            known[chosen],
        )
        for index, result in zip(chosen, done):
            results[index] = result
        start = stop


def _point_count(rings: object) -> int:
    """Points in all rings of a polygon as given (closing points included), or -1."""
    try:
        if isinstance(rings, np.ndarray) and rings.ndim == 2:
            return len(rings)
        return sum(len(ring) for ring in rings)
    except TypeError:
        return -1


def _twins(ext: np.ndarray, ext_start: np.ndarray) -> np.ndarray:
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


def _triangulate(
    polygons: Sequence[Sequence[object]],
    exhaustive: bool,
    max_vertices: int,
    results: list[Triangulation | None],
    known: np.ndarray,
) -> list[Triangulation | None]:
    flat = flatten_rings(polygons, max_vertices)
    wx = np.where(np.repeat(flat.mirrored[flat.ring_poly], flat.ring_len), -flat.vx, flat.vx)
    wy = flat.vy
    vertices = flat.vertices
    handled = flat.handled.copy()
    # a polygon proven valid (by the caller, or here) has no touching rings: the search is
    # left to the others (the proof pays off where the search is costly, on polygons of more
    # than a few vertices)
    undecided = handled & ~flat.empty & ~known
    undecided &= ~proven_valid_rings(
        flat.vx,
        flat.vy,
        flat.ring_start,
        flat.ring_len,
        flat.ring_poly,
        undecided & (flat.poly_vcount >= _PROOF_VERTICES),
    )
    handled &= ~touching_polygons(flat, wx, undecided)
    # the engine gives slivers of negligible net area no triangles: left to it
    handled &= clear_area(flat, wx) | flat.empty
    for p in np.flatnonzero(handled & flat.empty).tolist():
        s = int(flat.poly_vstart[p])
        results[p] = Triangulation(vertices=vertices[s : s + int(flat.poly_vcount[p])])
    polys = np.flatnonzero(handled & ~flat.empty)
    if len(polys) == 0:
        return results
    seq, seq_start, seq_len, bridged = bridge_sequences(flat, wx, wy, polys)
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
        _twins(ext, ext_start),
        wx[ext],
        wy[ext],
        flat.vz[ext],
        ext_start,
        seq_len,
        flat.mirrored[polys_ok],
        exhaustive,
    )
    starts = trees.start.tolist()
    counts = trees.count.tolist()
    vstarts = flat.poly_vstart[polys_ok].tolist()
    vcounts = flat.poly_vcount[polys_ok].tolist()
    good = trees.ok.tolist()
    for i, p in enumerate(polys_ok.tolist()):
        if not good[i]:
            continue
        s, n, vs = starts[i], counts[i], vstarts[i]
        results[p] = Triangulation(
            vertices=vertices[vs : vs + vcounts[i]],
            triangles=trees.triangles[s : s + n],
            parent=trees.parent[s : s + n],
            depth=trees.depth[s : s + n],
            side=trees.side[s : s + n],
        )
    return results
