"""Rule delaunay: bridges between rings found for all islands at once (docs/algorithm.md,
"Rule delaunay").

A bridge under rule delaunay must be an edge of the constrained Delaunay triangulation of
the rings. A segment between vertices of two rings is one of every such triangulation when
its closed diametral circle holds no other vertex (a Gabriel edge) and it crosses no ring
edge. Two such segments never cross, nor cross any other constrained Delaunay edge.

Each vertex's nearest vertex of another ring is the candidate: a vertex of another ring in
that circle would be nearer, so only the vertex's own ring can spoil it.
So one nearest search over all vertices, one box query per candidate and one segment test
give, for every island at once, the links along which it may join: either end may be in the
sequence first. The caller walks them breadth-first from the outer ring.
"""

from __future__ import annotations

import numpy as np

from .bridge_plan import inside_open_angle, segments_clear
from .points import VertexGrid
from .spatial_index import SegmentGrid

# polygons with more islands than this take the links (the batch path leaves them to the
# one-polygon builder, so that both give the same bridges)
LINKED_ISLANDS = 16
# float test of (w - h) . (w - v) > 0 (w outside the closed circle on h-v): relative bound
_DOT_BOUND = 8.0 * 2.0**-53
# nearest searches reach this many grid cells around each vertex (farther: no link)
_REACH = 8
# vertices searched from, or segments tested, per numpy pass
_AT_ONCE = 1 << 14


class RingLinks:
    """Per vertex id, the islands that may be joined by a bridge to it: (slot, index of the
    island's own bridge vertex). Built from :func:`delaunay_links`; :meth:`ready` hands out
    each vertex's links once, when the vertex enters the sequence."""

    def __init__(self, links: dict[int, list[tuple[int, int]]]) -> None:
        self.links = links

    def ready(self, vids: list[int]) -> list[tuple[int, int, int]]:
        """(slot, island vertex index, target vertex id) of the links at ``vids``."""
        found: list[tuple[int, int, int]] = []
        links = self.links
        for vid in vids:
            for slot, index in links.pop(vid, ()):
                found.append((slot, index, vid))
        return found


def delaunay_links(
    x: np.ndarray,
    y: np.ndarray,
    rings: list[np.ndarray],
    vertex_ids: np.ndarray,
    edges: SegmentGrid,
    edge_a: np.ndarray,
    edge_b: np.ndarray,
) -> RingLinks:
    """The links between the outer ring and the islands of 3 vertices or more, and between
    those islands: segments from a vertex to its nearest vertex of another ring that are
    Gabriel edges crossing no ring edge, and that leave both vertices inside their rings'
    interior angles (exact tests). ``vertex_ids``: every vertex of ``rings``; ``edges``,
    ``edge_a``, ``edge_b``: the grid and the end vertex ids of every ring edge."""
    taking = [slot for slot in range(len(rings)) if slot == 0 or len(rings[slot]) >= 3]
    vids = np.concatenate([rings[slot] for slot in taking])
    lengths = np.array([len(rings[slot]) for slot in taking], dtype=np.int64)
    slot_of = np.repeat(np.array(taking, dtype=np.int64), lengths)
    starts = np.cumsum(lengths) - lengths
    index = np.arange(len(vids), dtype=np.int64) - np.repeat(starts, lengths)
    # the ring neighbours of each position, for the angle tests
    ring_start = np.repeat(starts, lengths)
    ring_length = np.repeat(lengths, lengths)
    nxt = vids[ring_start + (index + 1) % ring_length]
    prv = vids[ring_start + (index - 1) % ring_length]
    # a vertex id at more than one position (a ring through it twice, or touching rings
    # sharing it) takes no link: its ring and position are not one
    seen = np.bincount(np.concatenate(rings), minlength=len(x))
    once = seen[vids] == 1
    vids, slot_of, index, nxt, prv = vids[once], slot_of[once], index[once], nxt[once], prv[once]
    if len(vids) == 0:
        return RingLinks({})
    labels = -1 - np.arange(len(x), dtype=np.int64)  # any other vertex: a ring of its own
    labels[vids] = slot_of
    position = np.full(len(x), -1, dtype=np.int64)
    position[vids] = np.arange(len(vids), dtype=np.int64)
    grid = VertexGrid(x, y, vertex_ids)
    # from the islands' vertices only: the outer ring's are many and often far from any
    asking = np.flatnonzero(slot_of > 0)
    near = np.full(len(vids), -1, dtype=np.int64)
    for lo in range(0, len(asking), _AT_ONCE):  # bounded tables
        part = asking[lo : lo + _AT_ONCE]
        near[part] = grid.nearest(vids[part], labels, max_reach=_REACH)[0]
    h = np.flatnonzero(near >= 0)
    v_vid = near[h]
    v = position[v_vid]
    keep = v >= 0
    h, v = h[keep], v[keep]
    # each segment once, from its smaller position
    pairs = np.unique(np.column_stack([np.minimum(h, v), np.maximum(h, v)]), axis=0)
    h, v = pairs[:, 0], pairs[:, 1]
    hv, vv = vids[h], vids[v]
    hx, hy, vx, vy = x[hv], y[hv], x[vv], y[vv]
    # both ends: the segment leaves inside the ring's open interior angle (two rings at one
    # point touch: they join there, not along a link)
    ok = inside_open_angle(x, y, prv[h], hv, nxt[h], vx, vy) & inside_open_angle(
        x, y, prv[v], vv, nxt[v], hx, hy
    )
    ok &= (hx != vx) | (hy != vy)
    h, v, hv, vv = h[ok], v[ok], hv[ok], vv[ok]
    ok = np.concatenate(
        [
            _gabriel(x, y, grid, hv[k : k + _AT_ONCE], vv[k : k + _AT_ONCE])
            for k in range(0, len(hv), _AT_ONCE)
        ]
        or [np.zeros(0, dtype=bool)]
    )
    h, v, hv, vv = h[ok], v[ok], hv[ok], vv[ok]
    ok = segments_clear(x, y, edges, edge_a, edge_b, x[hv], y[hv], x[vv], y[vv])
    h, v = h[ok], v[ok]
    links: dict[int, list[tuple[int, int]]] = {}
    for a, b in zip(h.tolist(), v.tolist()):
        for end, other in ((a, b), (b, a)):
            slot = int(slot_of[end])
            if slot:  # the island of ``end`` may join by a bridge to the vertex at ``other``
                links.setdefault(int(vids[other]), []).append((slot, int(index[end])))
    return RingLinks(links)


def _gabriel(
    x: np.ndarray, y: np.ndarray, grid: VertexGrid, h: np.ndarray, v: np.ndarray
) -> np.ndarray:
    """Per segment h-v: every other vertex is surely outside its closed diametral circle
    (float values beyond their error bound; an unsure one counts as inside)."""
    hx, hy, vx, vy = x[h], y[h], x[v], y[v]
    with np.errstate(over="ignore", invalid="ignore"):
        mx, my = 0.5 * (hx + vx), 0.5 * (hy + vy)
        r = 0.5 * np.hypot(vx - hx, vy - hy) * (1 + 1e-9)
    # a circle beyond the float range is not tested: no link
    clear = np.isfinite(r) & np.isfinite(mx) & np.isfinite(my)
    box, w = grid.pairs_in_boxes(mx - r, my - r, mx + r, my + r, clear)
    other = (w != h[box]) & (w != v[box])
    box, w = box[other], w[other]
    with np.errstate(over="ignore", invalid="ignore"):
        ax, ay = x[w] - hx[box], y[w] - hy[box]
        bx, by = x[w] - vx[box], y[w] - vy[box]
        dot = ax * bx + ay * by
        bound = _DOT_BOUND * (np.abs(ax * bx) + np.abs(ay * by)) + 1e-300
        # inside, on the circle, unsure or not a number: the segment is no sure link
        inside = ~(dot > bound)
    clear[box[inside]] = False
    return clear
