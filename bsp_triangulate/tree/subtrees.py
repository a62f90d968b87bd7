"""The small sub-polygons of one large polygon's BSP tree, built all at once by the lock-step
builder.

A node of the tree on the base (s_hi, s_lo) owns the sub-polygon s_lo ... s_hi; its subtree
depends on those positions alone. Laid out as the sequence (s_hi, s_lo, s_lo+1, ..., s_hi-1),
whose root has the same base and the same candidates in the same order, it is one more
polygon for :func:`.lockstep.build_trees`, which decides thousands of them in one pass of
numpy rounds instead of one Python step per triangle.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .lockstep import build_trees

# largest sub-polygon (positions, both base corners included) handed to the lock-step builder
# (its tests are quadratic in the sub-polygon's size)
MAX_POSITIONS = 256
# ... under rule delaunay (its lock-step guess tables stay bounded per call)
DELAUNAY_POSITIONS = 1024
# positions per lock-step call
GROUP_POSITIONS = 200_000
# the lock-step builder pays a round per tree level: it is worth it only when this many
# sequences' worth of positions advance together (a deep chain alone costs a numpy round per
# triangle); rule first's one-step search is the cheapest, so it needs more of them
LOCKSTEP_BREADTH = {"first": 16, "elevation": 8, "delaunay": 8}


# rule first: where the sub-polygons of more than this many positions hold few nodes in all the
# requests of one lock-step call, the trees split them further, down to sub-polygons of at most
# this many, before asking (worth_refining)
REFINED_POSITIONS = 128
# ... at most this many nodes (a level of the deepest subtree costs a round of about 0.35 ms
# whatever the number of sub-polygons; a node built by the one-step search instead of the
# rounds, about 2 us more)
REFINE_NODES = 16_000


# what a polygon's tree asks the lock-step builder for: the arguments of build_subtrees
# (its sequence's ids, x, y, z, the spans, whether mirrored, the rule)
SubtreeRequest = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool, str]


class Refine:
    """Sent to a tree's steps instead of its subtrees: split the sub-polygons of more than
    ``REFINED_POSITIONS`` positions further, down to sub-polygons of at most that many, and
    ask again."""


REFINE = Refine()


def worth_lockstep(sizes: list[int], rule: str) -> bool:
    """Sequences of these ``sizes`` are many enough beside the largest of them (whose depth
    bounds the lock-step rounds) to be built in lock-step under ``rule`` rather than one step
    at a time."""
    return bool(sizes) and sum(sizes) >= LOCKSTEP_BREADTH[rule] * max(sizes)


def worth_refining(requests: list[SubtreeRequest]) -> bool:
    """The rule first ``requests`` of one lock-step call hold sub-polygons of more than
    ``REFINED_POSITIONS`` positions, with at most ``REFINE_NODES`` nodes in all: built
    further by the trees' one-step search, they leave the rounds shallower (a round per
    level of the deepest subtree, whatever their number), which pays where the rounds are
    shared by few sub-polygons (a large polygon alone: water-huge3, a wavy coast), not where
    thousands share them (a long river's, a layer's)."""
    if not requests or requests[0][6] != "first":
        return False
    moved = 0
    for request in requests:
        span = request[4][:, 1] - request[4][:, 0]
        moved += int((span[span >= REFINED_POSITIONS] - 1).sum())
    return 0 < moved <= REFINE_NODES


@dataclass
class Subtrees:
    """Triangles (output vertex ids), local parent (-1 at the root), depth from the root and
    side of the subtrees, those of span k at rows ``start[k]:start[k] + count[k]``; ``ok[k]``
    False where the lock-step builder found no tree (to be built one step at a time)."""

    triangles: np.ndarray
    parent: np.ndarray
    depth: np.ndarray
    side: np.ndarray
    start: np.ndarray
    count: np.ndarray
    ok: np.ndarray


def _twins(ext: np.ndarray, owner: np.ndarray, ext_start: np.ndarray) -> np.ndarray:
    """Per position: the other position of the same vertex in its sequence, or -1 (position
    0 of each sequence and vertices seen three times or more are left out)."""
    key = owner * (int(ext.max(initial=0)) + 1) + ext
    key[ext_start] = -1
    valid = np.flatnonzero(key >= 0)
    order = valid[np.argsort(key[valid], kind="stable")]
    keys = key[order]
    fresh = np.concatenate([[True], keys[1:] != keys[:-1]])
    group = np.cumsum(fresh) - 1
    sizes = np.bincount(group)
    paired = order[sizes[group] == 2]
    twin = np.full(len(ext), -1, dtype=np.int64)
    twin[paired[0::2]] = paired[1::2]
    twin[paired[1::2]] = paired[0::2]
    return twin


def built_if_worth(
    requests: list[SubtreeRequest], alive: Callable[[], None] | None = None
) -> list[Subtrees | None]:
    """The subtrees of each request (of one rule), built in shared lock-step calls
    (:func:`build_subtrees_many`, ``alive`` called every round) where all their
    sub-polygons together are worth the rounds (:func:`worth_lockstep`); else None for each
    (to be built one step at a time)."""
    spans = np.concatenate([request[4] for request in requests])
    if worth_lockstep((spans[:, 1] - spans[:, 0]).tolist(), requests[0][6]):
        return build_subtrees_many(requests, alive)
    return [None] * len(requests)


def build_subtrees_many(
    requests: list[SubtreeRequest], alive: Callable[[], None] | None = None
) -> list[Subtrees]:
    """:func:`build_subtrees` of each request (of one rule), in shared lock-step calls: the
    sequences laid end to end (their vertex ids apart), each request's spans moved with its
    sequence. A sub-polygon's tree depends on its positions alone, so each request gets the
    subtrees it would get alone; the rounds, whose fixed cost is most of a polygon's
    subtrees', are shared."""
    if len(requests) < 2:
        return [build_subtrees(*request, alive=alive) for request in requests]
    rule = requests[0][6]
    lengths = [len(request[1]) for request in requests]
    offsets = np.cumsum([0, *lengths[:-1]])
    id_span = [int(request[0].max(initial=-1)) + 1 for request in requests]
    id_offsets = np.cumsum([0, *id_span[:-1]])
    spans = [request[4] + offset for request, offset in zip(requests, offsets)]
    counts = np.array([len(span) for span in spans], dtype=np.int64)
    joined = build_subtrees(
        np.concatenate([request[0] + shift for request, shift in zip(requests, id_offsets)]),
        np.concatenate([request[1] for request in requests]),
        np.concatenate([request[2] for request in requests]),
        np.concatenate([request[3] for request in requests]),
        np.concatenate(spans),
        np.repeat([request[5] for request in requests], counts),
        rule,
        alive,
    )
    found = []
    first = 0
    for count, shift in zip(counts.tolist(), id_offsets.tolist()):
        start, number = joined.start[first : first + count], joined.count[first : first + count]
        rows = slice(int(start[0]), int(start[-1] + number[-1])) if count else slice(0, 0)
        found.append(
            Subtrees(
                joined.triangles[rows] - shift,
                joined.parent[rows],
                joined.depth[rows],
                joined.side[rows],
                start - rows.start,
                number,
                joined.ok[first : first + count],
            )
        )
        first += count
    return found


def build_subtrees(
    ids: np.ndarray,
    sx: np.ndarray,
    sy: np.ndarray,
    sz: np.ndarray,
    spans: np.ndarray,
    mirrored: bool | np.ndarray,
    rule: str,
    alive: Callable[[], None] | None = None,
) -> Subtrees:
    """The subtrees of the sub-polygons ``spans`` (rows (lo, hi) of positions) of one bridged
    sequence: ``ids`` its output vertex ids per position, ``sx``, ``sy``, ``sz`` its working
    coordinates and elevations (position m repeating position 0), the root of each subtree
    with V1 at s_hi; ``mirrored``: for all spans or per span; ``rule`` "first",
    "elevation" or "delaunay". Built in groups of about
    ``GROUP_POSITIONS`` positions, which bounds the lock-step builder's memory."""
    length = spans[:, 1] - spans[:, 0] + 1
    group = np.cumsum(length) // GROUP_POSITIONS
    cuts = np.flatnonzero(np.diff(group)) + 1
    flags = np.broadcast_to(np.asarray(mirrored, dtype=bool), (len(spans),))
    parts = [
        _build_group(ids, sx, sy, sz, part, flag, rule, alive)
        for part, flag in zip(np.split(spans, cuts), np.split(flags, cuts))
        if len(part)
    ]
    count = np.concatenate([part.count for part in parts])
    return Subtrees(
        np.concatenate([part.triangles for part in parts]),
        np.concatenate([part.parent for part in parts]),
        np.concatenate([part.depth for part in parts]),
        np.concatenate([part.side for part in parts]),
        np.cumsum(count) - count,
        count,
        np.concatenate([part.ok for part in parts]),
    )


def _build_group(
    ids: np.ndarray,
    sx: np.ndarray,
    sy: np.ndarray,
    sz: np.ndarray,
    spans: np.ndarray,
    mirrored: np.ndarray,
    rule: str,
    alive: Callable[[], None] | None = None,
) -> Subtrees:
    """:func:`build_subtrees` of one group of spans (``mirrored`` per span), in one
    lock-step call (``alive`` called every round)."""
    lo, hi = spans[:, 0], spans[:, 1]
    length = hi - lo + 1  # positions of the sub-polygon
    ext_len = length + 1  # with the closing repeat of s_hi
    ext_start = np.cumsum(ext_len) - ext_len
    owner = np.repeat(np.arange(len(spans), dtype=np.int64), ext_len)
    step = np.arange(int(ext_len.sum()), dtype=np.int64) - np.repeat(ext_start, ext_len)
    # s_hi, then s_lo ... s_hi-1, then s_hi again
    position = lo[owner] + step - 1
    position[ext_start] = hi
    position[ext_start + length] = hi
    ext = ids[position]
    trees = build_trees(
        ext,
        _twins(ext, owner, ext_start),
        sx[position],
        sy[position],
        sz[position],
        ext_start,
        length,
        mirrored,
        rule,
        None,
        alive,
    )
    return Subtrees(
        trees.triangles,
        trees.parent,
        trees.depth,
        trees.side,
        trees.start,
        trees.count,
        trees.ok,
    )
