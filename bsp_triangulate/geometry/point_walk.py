"""The bridged sequence of a polygon without islands and its interior points, in one walk.

Under rule "delaunay" with a known triangulation (docs/algorithm.md, sections 2a and 5b),
every point joins the sequence by the bridge to the vertex it is linked to
(``points.PointOrder``) whenever that link is an edge of the triangulation: such a bridge
crosses nothing and leaves its vertex inside exactly one occurrence's interior angle, so
neither the joining order nor the sequence at the time changes which bridges are made. Each
splice puts the new spike at the occurrence whose angle holds its direction; the finished
sequence is therefore the walk around the one face of the outer ring and the bridges, with
the polygon on the left: from each vertex the walk leaves by the first edge clockwise from
the one it came in by. This module makes that walk at once, instead of one splice per point.
"""

from __future__ import annotations

import numpy as np

# angles (radians) of two edges at a vertex closer than this are left to the splices
_ANGLE_GAP = 1e-12


def walk_sequence(
    x: np.ndarray, y: np.ndarray, outer: np.ndarray, links: np.ndarray
) -> np.ndarray | None:
    """The sequence that joining the points by ``links`` ((k, 2) vertex pairs: point,
    vertex; a forest reaching the ``outer`` ring) one by one gives, or None where the walk
    cannot tell (a repeated ring vertex, two edges at a vertex in nearly one direction, a
    link set that is not such a forest)."""
    outer = np.asarray(outer, dtype=np.int64)
    links = np.asarray(links, dtype=np.int64).reshape(-1, 2)
    n = len(outer)
    if n < 3 or len(np.unique(outer)) != n:
        return None
    # half-edges: the ring's (kept), its reverses (only to turn around), both ways of a link
    nxt_ring = np.roll(outer, -1)
    tail = np.concatenate([outer, nxt_ring, links[:, 0], links[:, 1]])
    head = np.concatenate([nxt_ring, outer, links[:, 1], links[:, 0]])
    dx, dy = x[head] - x[tail], y[head] - y[tail]
    if not ((dx != 0) | (dy != 0)).all():
        return None
    angle = np.arctan2(dy, dx)
    order = np.lexsort((angle, tail))
    t_sorted, a_sorted = tail[order], angle[order]
    first = np.r_[True, t_sorted[1:] != t_sorted[:-1]]
    starts = np.flatnonzero(first)
    group = np.cumsum(first) - 1
    ends = np.r_[starts[1:], len(order)]
    # the gaps between neighbouring directions at each vertex, the wrap-around included
    gap = np.diff(a_sorted)
    same = ~first[1:]
    if (gap[same] < _ANGLE_GAP).any():
        return None
    wrap = a_sorted[starts] + 2 * np.pi - a_sorted[ends - 1]
    if (wrap[ends - starts > 1] < _ANGLE_GAP).any():
        return None
    # position of each half-edge in the sorted order, and of its reverse
    where = np.empty(len(order), dtype=np.int64)
    where[order] = np.arange(len(order))
    base = int(max(tail.max(), head.max())) + 1  # directed edge (u, v) as u * base + v
    keys = tail * base + head
    by_key = np.argsort(keys, kind="stable")
    sorted_keys = keys[by_key]
    if (sorted_keys[1:] == sorted_keys[:-1]).any():
        return None  # an edge twice: a link along the ring or a repeated link
    reverse_keys = head * base + tail
    reverse = by_key[np.searchsorted(sorted_keys, reverse_keys)]
    # arriving by h = (u -> v), leave by the edge before (v -> u) in counter-clockwise order
    at = where[reverse]
    before = np.where(first[at], ends[group[at]] - 1, at - 1)
    following = order[before].tolist()
    total = n + 2 * len(links)
    sequence = []
    h = 0  # outer[0] -> outer[1]
    tails = tail.tolist()
    for step in range(total):
        if (n <= h < 2 * n) or (h == 0 and step):
            return None  # the walk left the polygon or closed early: not a forest inside it
        sequence.append(tails[h])
        h = following[h]
    if h != 0:
        return None
    return np.asarray(sequence, dtype=np.int64)
