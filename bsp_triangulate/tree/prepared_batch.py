"""Small polygons that the batch path leaves to the engine (rings that touch, under rule
delaunay islands waiting for a Delaunay bridge, ...): prepared and bridged one by one exactly
as the engine does (``one_polygon.bridged_sequence``), their trees then built together by the
lock-step builder, which gives the engine's tree for any sequence (touching points included,
as for the sub-polygons of ``subtrees.py``) without a Python step per triangle. A polygon
whose tree the lock-step builder does not complete, or which fails the engine's area check,
is left to the engine, which then builds or reports it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..triangulation import Triangulation, TriangulationError
from .batch import sequence_twins
from .lockstep import build_trees
from .one_polygon import bridged_sequence, check_area
from .subtrees import LOCKSTEP_BREADTH, MAX_POSITIONS, worth_lockstep


def triangulate_prepared(
    polygons: Sequence[Sequence[object]], rule: str, invalid: str, plane: str = "auto"
) -> dict[int, Triangulation]:
    """The engine's results (``one_polygon._triangulate`` without points or snapping, equal
    field by field) of the ``polygons`` decided here, by their index; the others are left
    out. Sequences of at most ``subtrees.MAX_POSITIONS`` positions are built, and only
    where they are many enough for the lock-step rounds."""
    if rule not in LOCKSTEP_BREADTH:
        return {}
    found = []
    for index, rings in enumerate(polygons):
        if _surely_long(rings):
            continue  # the engine's (a large polygon's bridges are not searched twice)
        prepared = bridged_sequence(rings, rule=rule, invalid=invalid, plane=plane)
        if prepared is not None and len(prepared[1]) < MAX_POSITIONS:
            found.append((index, *prepared))
    if not worth_lockstep([len(sequence) for _, _, sequence, _ in found], rule):
        return {}
    trees = _trees([sequence for _, _, sequence, _ in found], [p for _, p, _, _ in found], rule)
    results: dict[int, Triangulation] = {}
    unused = np.zeros(0, dtype=np.int64)
    for k, (index, prepared, sequence, axes) in enumerate(found):
        count = int(trees.count[k])
        if not trees.ok[k] or count != len(sequence) - 2:
            continue
        rows = slice(int(trees.start[k]), int(trees.start[k]) + count)
        result = Triangulation(
            vertices=prepared.vertices,
            triangles=trees.triangles[rows],
            parent=trees.parent[rows],
            depth=trees.depth[rows],
            side=trees.side[rows],
            point_ids=unused,
        )
        if invalid != "as_given":
            try:
                check_area(prepared, result, axes)
            except TriangulationError:
                continue  # the engine reports it
        results[index] = result
    return results


def _surely_long(rings: Sequence[object]) -> bool:
    """The rings' sequence surely has too many positions to be built here: every point of
    a ring but its closing repeat becomes a position (a bridge adds its two ends again).
    Only where the preparation drops many repeated points is the sequence shorter; the
    engine then builds it, with the same result."""
    try:
        return sum(len(ring) - 1 for ring in rings) >= MAX_POSITIONS
    except TypeError:
        return False


def _trees(sequences: list[np.ndarray], prepared: list, rule: str) -> object:
    """The lock-step trees of the bridged ``sequences`` (vertex ids of their ``prepared``
    rings), each laid out with its closing repeat, as the engine's tree reads it."""
    lengths = np.array([len(s) for s in sequences], dtype=np.int64)
    ext_len = lengths + 1
    ext_start = np.cumsum(ext_len) - ext_len
    closed = [np.concatenate([s, s[:1]]) for s in sequences]
    local = np.concatenate(closed)
    # vertex ids unique across the polygons, for the bridge ends' twins
    counts = np.array([len(p.vertices) for p in prepared], dtype=np.int64)
    offset = np.repeat(np.cumsum(counts) - counts, ext_len)
    sx = np.concatenate([p.x[c] for p, c in zip(prepared, closed)])
    sy = np.concatenate([p.y[c] for p, c in zip(prepared, closed)])
    sz = np.concatenate([p.vertices[c, 2] for p, c in zip(prepared, closed)])
    mirrored = np.array([p.mirrored for p in prepared], dtype=bool)
    name = rule
    if rule == "elevation" and np.all(sz == sz[0]):
        name = "first"  # every candidate equally close: the first correct one, as rule first
    return build_trees(
        local,
        sequence_twins(local + offset, ext_start),
        sx,
        sy,
        sz,
        ext_start,
        lengths,
        mirrored,
        name,
    )
