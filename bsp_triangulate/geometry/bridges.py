"""Islands: split touching edges and join every island to the outer ring by a bridge.

See docs/algorithm.md section 2 for the exact rules implemented here.
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from collections.abc import Callable
from fractions import Fraction

import numpy as np

from ..triangulation import TriangulationError
from .bridge_cells import BridgeCells
from .bridge_plan import blocking_pairs, inside_open_angle, plan_targets
from .delaunay_links import LINKED_ISLANDS, delaunay_links
from .points import delaunay_point_bridge, nearest_point_bridge, point_order, strictly_outside
from .predicates import exact_sq_distance, orient, orient_many, strictly_between
from .rings import ring_label
from .shared_points import point_numbers, touching_islands
from .spatial_index import PointColumns, SegmentGrid, chunks

# relative margin within which float squared distances are re-compared exactly
_DISTANCE_MARGIN = 1e-9
# rule delaunay: rounds of widening the neighbourhood that may bound a bridge's length, and
# the margin on its angles (radians) and distances (relative)
_GAP_ROUNDS = 3
_GAP_MARGIN = 1e-6
# witnesses that leave a gap this close to 180 degrees (radians) or wider bound nothing
_OPEN_GAP = 1e-3
# ... and witnesses nearer than this to h (subnormal products) are left out
_LEAST_OFFSET = 2.0**-960
# vertices near h tried as the one strictly inside a bridge's diametral circle
_NEAREST_WITNESSES = 16
# vertices within a witness bound whose diametral circles are tested exactly before a
# search (find_delaunay_bridge)
_FEW_DISKS = 64
# island vertices whose witness bounds are kept for the later rounds (memory: a few MB)
_BOUNDS_KEPT = 1 << 16
# islands up to this many vertices are spliced element by element (no numpy calls)
_FEW = 32
# bridge candidates tested together after the nearest: doubling from the first block size up to
# the last
_FIRST_BLOCK = 8
_LAST_BLOCK = 1024
# edges that blocked segments to one island's vertex, tried first for its next segments
_KNOWN_BLOCKERS = 16
# segments to an island's vertex are first tested against the ring edges along their first
# stretches of these many grid cells from their other end, where at least _LONG_SEGMENTS are
# over _LONG_SHARE times that long
_NEAR_CELLS = (16, 128)
_LONG_SHARE = 2
_LONG_SEGMENTS = 8


def ring_edges(rings: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Start and end vertex ids of every ring edge, ring by ring."""
    starts = np.concatenate(rings)
    lengths = np.fromiter((len(r) for r in rings), dtype=np.int64, count=len(rings))
    ends_at = np.cumsum(lengths)
    # each edge ends at the next vertex of its ring, the last one at the ring's first
    following = np.arange(1, len(starts) + 1, dtype=np.int64)
    following[ends_at[lengths > 0] - 1] = (ends_at - lengths)[lengths > 0]
    return starts, starts[following]


def split_touching(
    x: np.ndarray,
    y: np.ndarray,
    rings: list[np.ndarray],
    alive: Callable[[], None] | None = None,
) -> list[np.ndarray]:
    """Split every ring edge at the vertices (of any ring) lying in its relative interior
    (``alive``: called between the search's passes; it may raise to stop)."""
    starts, ends = ring_edges(rings)
    edge, vertex = _touching_pairs(x, y, starts, ends, alive)
    if len(edge) == 0:
        return rings
    hits: dict[int, list[int]] = {}
    for e, v in zip(edge.tolist(), vertex.tolist()):
        hits.setdefault(e, []).append(v)
    ring_offsets = np.cumsum([0] + [len(r) for r in rings])
    result = []
    for number, ring in enumerate(rings):
        base = int(ring_offsets[number])
        if not any(base + t in hits for t in range(len(ring))):
            result.append(ring)
            continue
        out: list[int] = []
        for t, vid in enumerate(ring.tolist()):
            out.append(vid)
            inside = hits.get(base + t)
            if inside:
                out.extend(_order_along(x, y, vid, int(ring[(t + 1) % len(ring)]), inside))
        result.append(np.asarray(out, dtype=np.int64))
    return result


# candidate (edge, vertex) pairs tested at once: bounds the memory of the vectorised tests
_PAIR_CHUNK = 1 << 16


def _touching_pairs(
    x: np.ndarray,
    y: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    alive: Callable[[], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(edge, vertex) pairs of the vertices in the relative interior of edges (exact)."""
    vertex_ids = _vertex_ids(starts, len(x))
    points = PointColumns(x[vertex_ids], y[vertex_ids])
    near_ids = vertex_ids[points.order]  # vertex ids in the order of the points' cells
    ax, ay, bx, by = x[starts], y[starts], x[ends], y[ends]
    edges_found, vertices_found = [], []
    for edge_lo, edge_hi in chunks(points.column_spans(ax, bx), _PAIR_CHUNK):
        window = slice(edge_lo, edge_hi)
        segment, first, last = points.segment_columns(
            ax[window], ay[window], bx[window], by[window]
        )
        counts = last - first
        keep = counts > 0
        segment, first, counts = segment[keep] + edge_lo, first[keep], counts[keep]
        for lo, hi in chunks(counts, _PAIR_CHUNK):
            if alive is not None:
                alive()
            part = counts[lo:hi]
            offsets = np.arange(int(part.sum()), dtype=np.int64) - np.repeat(
                np.cumsum(part) - part, part
            )
            edge = np.repeat(segment[lo:hi], part)
            vertex = near_ids[np.repeat(first[lo:hi], part) + offsets]
            a, b = starts[edge], ends[edge]
            # cheap exact pre-filter: the vertex must be in the edge's bounding box
            near = strictly_between(x[vertex], y[vertex], x[a], y[a], x[b], y[b])
            edge, vertex, a, b = edge[near], vertex[near], a[near], b[near]
            on_line = orient_many(x[a], y[a], x[b], y[b], x[vertex], y[vertex]) == 0
            edges_found.append(edge[on_line])
            vertices_found.append(vertex[on_line])
    if not edges_found:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(edges_found), np.concatenate(vertices_found)


def _vertex_ids(ids: np.ndarray, count: int) -> np.ndarray:
    """``np.unique(ids)`` of vertex ids below ``count``, by counting instead of sorting."""
    return np.flatnonzero(np.bincount(ids, minlength=count))


def _order_along(x: np.ndarray, y: np.ndarray, a: int, b: int, inside: list[int]) -> list[int]:
    """Collinear points strictly inside segment a-b, ordered from a to b, one per position."""
    sx = 1.0 if x[b] >= x[a] else -1.0
    sy = 1.0 if y[b] >= y[a] else -1.0
    ordered = sorted(set(inside), key=lambda v: (sx * x[v], sy * y[v], v))
    kept: list[int] = []
    for v in ordered:
        if kept and x[kept[-1]] == x[v] and y[kept[-1]] == y[v]:
            continue
        kept.append(v)
    return kept


class _Bridger:
    """Joins islands one by one into the sequence (outer ring first).

    The sequence is a cyclic linked list of occurrences (nodes), so that a splice costs the
    island's length, not the sequence's: ``vid[node]`` is the vertex, ``nxt``/``prv`` link the
    nodes, node 0 is the sequence's first element (the last one links back to it). The order
    of two nodes, rarely needed (which of a vertex's occurrences comes first), is found by
    walking the list (:meth:`earliest`).
    """

    def __init__(
        self,
        x: np.ndarray,
        y: np.ndarray,
        rings: list[np.ndarray],
    ) -> None:
        self.x, self.y = x, y
        starts, ends = ring_edges(rings)
        self.edge_a, self.edge_b = starts, ends
        self.edges = SegmentGrid(x[starts], y[starts], x[ends], y[ends])
        # point grid (zero-length segments) over every vertex of the sequence-to-be
        self.point_ids = _vertex_ids(starts, len(x))
        px, py = x[self.point_ids], y[self.point_ids]
        self.points = SegmentGrid(px, py, px, py)
        self.in_seq = np.zeros(len(x), dtype=bool)
        # bridges made so far, (start, end) vertex ids: one at most per island
        self.bridges = np.empty((len(rings), 2), dtype=np.int64)
        self.bridge_count = 0
        self.bridge_cells = BridgeCells(
            self.points.x0, self.points.y0, self.points.size_x, self.points.size_y
        )
        # per island vertex whose whole search found no valid target, the node count then
        # (see find_bridge)
        self._hopeless: dict[int, int] = {}
        # some search has found no valid target among all the vertices of the sequence (kept
        # when _hopeless is forgotten)
        self.searched_in_vain = False
        # per island vertex, :meth:`_disk_never_empty_beyond` (it reads every vertex of the
        # rings, joined or not: it does not change), for at most _BOUNDS_KEPT of them
        self._disk_bounds: dict[int, tuple[float, np.ndarray]] = {}
        # the edges (vertex id pairs) that blocked segments to vertex _known_to
        self._known_to = -1
        self._known = np.zeros((0, 2), dtype=np.int64)
        # per vertex the number of its point, and per point whether it is in the sequence
        self.point_of = point_numbers(x, y)
        self.point_in_seq = np.zeros(len(x), dtype=bool)
        capacity = len(starts) + 2 * len(rings)
        self.vid = np.empty(capacity, dtype=np.int64)
        self.nxt = np.empty(capacity, dtype=np.int64)
        self.prv = np.empty(capacity, dtype=np.int64)
        self.count = 0
        # first occurrence of each vertex (-1: not in the sequence) and any further ones
        self.first = np.full(len(x), -1, dtype=np.int64)
        self.more: dict[int, list[int]] = {}
        outer = rings[0]
        nodes = self._new_nodes(outer)
        self.nxt[nodes] = np.roll(nodes, -1)
        self.prv[nodes] = np.roll(nodes, 1)
        self._add_points(outer)

    def _new_nodes(self, vids: np.ndarray) -> np.ndarray:
        """Nodes for the vertices ``vids`` (not linked yet), registered as occurrences."""
        nodes = np.arange(self.count, self.count + len(vids), dtype=np.int64)
        self.count += len(vids)
        self.vid[nodes] = vids
        self.in_seq[vids] = True
        unique, index = np.unique(vids, return_index=True)
        fresh = self.first[unique] < 0
        self.first[unique[fresh]] = nodes[index[fresh]]
        extra = np.flatnonzero(self.first[vids] != nodes)
        for node, vid in zip(nodes[extra].tolist(), vids[extra].tolist()):
            self.more.setdefault(vid, []).append(node)
        return nodes

    def _insert_after(self, node: int, vids: np.ndarray) -> None:
        """Insert the vertices ``vids`` into the sequence right after ``node``."""
        nodes = self._new_nodes(vids)
        after = int(self.nxt[node])
        self.nxt[nodes[:-1]] = nodes[1:]
        self.prv[nodes[1:]] = nodes[:-1]
        self.nxt[node], self.prv[nodes[0]] = nodes[0], node
        self.nxt[nodes[-1]], self.prv[after] = after, nodes[-1]

    def _insert_few_after(self, node: int, vids: list[int]) -> None:
        """:meth:`_insert_after` of a few vertices, element by element (no numpy calls on tiny
        arrays); the same occurrences and the same order."""
        nxt, prv = self.nxt, self.prv
        after = int(nxt[node])
        first, more, vid, in_seq = self.first, self.more, self.vid, self.in_seq
        previous = node
        for v in vids:
            new = self.count
            self.count += 1
            vid[new] = v
            in_seq[v] = True
            if first[v] < 0:
                first[v] = new
            else:
                more.setdefault(v, []).append(new)
            nxt[previous], prv[new] = new, previous
            previous = new
        nxt[previous], prv[after] = after, previous

    def _order(self) -> np.ndarray:
        """The sequence's nodes in order."""
        nxt = self.nxt[: self.count].tolist()
        order = [0] * self.count
        node = 0
        for index in range(1, self.count):
            node = nxt[node]
            order[index] = node
        return np.array(order, dtype=np.int64)

    def _before(self, a: int, b: int) -> bool:
        """Node ``a`` comes before node ``b`` (another one) in the sequence: walks from both
        go forward in turn until one meets the other or passes the sequence's end, so the
        cost is about twice the shorter of the two."""
        if a == 0 or b == 0:
            return a == 0
        nxt = self.nxt
        p, q = a, b
        while True:
            p = int(nxt[p])
            if p == b or p == 0:
                return p == b
            q = int(nxt[q])
            if q == a or q == 0:
                return q == 0

    def earliest(self, nodes: list[int]) -> int:
        """The node of ``nodes`` (distinct) that comes first in the sequence."""
        best = nodes[0]
        for node in nodes[1:]:
            if self._before(node, best):
                best = node
        return best

    @property
    def seq(self) -> np.ndarray:
        """The sequence of vertex ids."""
        return self.vid[self._order()]

    def _add_points(self, ring: np.ndarray) -> None:
        self.point_in_seq[self.point_of[ring]] = True

    def occurrences(self, vid: int) -> list[int]:
        """The nodes of ``vid`` in the sequence."""
        return [int(self.first[vid]), *self.more.get(vid, ())]

    # -- validity -------------------------------------------------------------------------
    def _inside_angle(self, k: int, tx: float, ty: float, closed: bool = False) -> bool:
        """The direction from occurrence (node) k towards (tx, ty) lies in S's interior angle there
        (the open angle, or the closed one with ``closed=True``)."""
        vid, x, y = self.vid, self.x, self.y
        v, p, n = int(vid[k]), int(vid[self.prv[k]]), int(vid[self.nxt[k]])
        vx, vy = x[v], y[v]
        turn = orient(x[p], y[p], vx, vy, x[n], y[n])
        least = 0 if closed else 1
        after_next = orient(vx, vy, x[n], y[n], tx, ty) >= least
        after_prev = orient(x[p], y[p], vx, vy, tx, ty) >= least
        if turn > 0:
            return after_next and after_prev
        if turn < 0:
            return after_next or after_prev
        if (x[n] - vx) * (x[p] - vx) + (y[n] - vy) * (y[p] - vy) < 0:
            return after_next  # straight angle
        # spike: everything but the spike's own ray
        on_ray = orient(vx, vy, x[n], y[n], tx, ty) == 0 and (
            (tx - vx) * (x[n] - vx) + (ty - vy) * (y[n] - vy) > 0
        )
        return closed or not on_ray

    def _segment_clear(self, u: int, w: int) -> bool:
        """No ring edge or earlier bridge meets the open segment u-w, no vertex lies on it."""
        x, y = self.x, self.y
        ux, uy, wx, wy = x[u], y[u], x[w], y[w]
        found = self.edges.query_triangle(np.array([ux, wx]), np.array([uy, wy]))
        a = self.edge_a[found]
        b = self.edge_b[found]
        if self.bridge_count:
            extra = self.bridges[: self.bridge_count]
            # only bridges whose bounding box meets the segment's can meet it (exact)
            bxa, bya, bxb, byb = x[extra[:, 0]], y[extra[:, 0]], x[extra[:, 1]], y[extra[:, 1]]
            near = (
                (np.maximum(bxa, bxb) >= min(ux, wx))
                & (np.minimum(bxa, bxb) <= max(ux, wx))
                & (np.maximum(bya, byb) >= min(uy, wy))
                & (np.minimum(bya, byb) <= max(uy, wy))
            )
            if near.any():
                a = np.concatenate([a, extra[near, 0]])
                b = np.concatenate([b, extra[near, 1]])
        if len(a) == 0:
            return True
        o1 = orient_many(ux, uy, wx, wy, x[a], y[a])
        o2 = orient_many(ux, uy, wx, wy, x[b], y[b])
        if (
            (o1 == 0) & strictly_between(x[a], y[a], ux, uy, wx, wy)
            | (o2 == 0) & strictly_between(x[b], y[b], ux, uy, wx, wy)
        ).any():
            return False
        straddle = (o1.astype(np.int16) * o2) < 0
        if not straddle.any():
            return True
        a, b = a[straddle], b[straddle]
        o3 = orient_many(x[a], y[a], x[b], y[b], ux, uy)
        o4 = orient_many(x[a], y[a], x[b], y[b], wx, wy)
        return not ((o3.astype(np.int16) * o4) < 0).any()

    def planned(self, vid: int, island: np.ndarray, h_index: int) -> tuple[int, int] | None:
        """(node, vertex id) of the bridge to the planned target ``vid``
        (:func:`.bridge_plan.plan_targets`: the nearest vertex passing the tests that do not
        depend on the sequence), or None where the one-by-one search must decide: an earlier
        bridge crosses the segment, ``vid`` is at the island's own point, or none of its
        occurrences holds the island in its open angle. Of several occurrences that do, the
        first in the sequence, as the search takes (``_nearest_exact``: one distance, ties by
        position)."""
        if self.first[vid] < 0:
            return None
        h = int(island[h_index])
        if self.bridge_count and self._crosses_bridge(vid, h):
            return None
        if vid not in self.more:
            return int(self.first[vid]), vid
        hx, hy = float(self.x[h]), float(self.y[h])
        if self.x[vid] == hx and self.y[vid] == hy:
            return None
        ks = [k for k in self.occurrences(vid) if self._inside_angle(k, hx, hy)]
        if not ks:
            return None
        return self.earliest(ks), vid

    def linked(self, vid: int, island: np.ndarray, h_index: int) -> tuple[int, int] | None:
        """(node, vertex id) of the bridge along a link (:mod:`.delaunay_links`: a Gabriel
        edge crossing no ring edge) to ``vid``, now in the sequence: its one occurrence whose
        open angle holds the island's vertex, where no bridge made so far crosses it."""
        h = int(island[h_index])
        hx, hy = float(self.x[h]), float(self.y[h])
        ks = [k for k in self.occurrences(vid) if self._inside_angle(k, hx, hy)]
        if len(ks) != 1 or (self.bridge_count and self._crosses_bridge(vid, h)):
            return None
        return ks[0], vid

    def _crosses_bridge(self, u: int, w: int) -> bool:
        """A bridge made so far crosses the segment u-w in both open interiors (exact)."""
        x, y = self.x, self.y
        return self.bridge_cells.crosses(float(x[u]), float(y[u]), float(x[w]), float(y[w]))

    def _valid_occurrences(self, vid: int, island: np.ndarray, h_index: int) -> list[int]:
        """Occurrences (nodes) k of ``vid`` from which a bridge to the island may leave."""
        x, y = self.x, self.y
        h = int(island[h_index])
        if x[vid] == x[h] and y[vid] == y[h]:
            nxt = int(island[(h_index + 1) % len(island)])
            prv = int(island[h_index - 1])
            # the island's corner at h must lie within S's closed angle at occurrence k
            return [
                k
                for k in self.occurrences(vid)
                if self._inside_angle(k, x[nxt], y[nxt], closed=True)
                and self._inside_angle(k, x[prv], y[prv], closed=True)
            ]
        ks = [k for k in self.occurrences(vid) if self._inside_angle(k, x[h], y[h])]
        if ks and self._segment_clear(vid, h):
            return ks
        return []

    def _inside_angle_many(self, nodes: np.ndarray, tx: float, ty: float) -> np.ndarray:
        """Vectorised :meth:`_inside_angle` (open angle) of the occurrences ``nodes``."""
        vid = self.vid
        v, p, n = vid[nodes], vid[self.prv[nodes]], vid[self.nxt[nodes]]
        return inside_open_angle(self.x, self.y, p, v, n, tx, ty)

    def _segments_clear(self, us: np.ndarray, w: int) -> np.ndarray:
        """Vectorised :meth:`_segment_clear` of the segments from each vertex of ``us`` to w.

        Edges that blocked earlier segments to w often block the next ones too (an island
        with no valid bridge, inside another, is searched to the end): they are tried first,
        and only the segments they leave clear are looked up in the grid."""
        x, y = self.x, self.y
        clear = np.ones(len(us), dtype=bool)
        if len(us) == 0:
            return clear
        if self._known_to != w:
            self._known_to, self._known = w, np.zeros((0, 2), dtype=np.int64)
        known = self._known
        if len(known):
            row = np.repeat(np.arange(len(us), dtype=np.int64), len(known))
            edge = np.tile(np.arange(len(known), dtype=np.int64), len(us))
            a, b = known[edge, 0], known[edge, 1]
            hit = blocking_pairs(x, y, row, a, b, x[us], y[us], float(x[w]), float(y[w]))
            clear[row[hit]] = False
        rest = np.flatnonzero(clear)
        if len(rest):
            clear[rest] = self._segments_looked_up(us[rest], w)
        return clear

    def _segments_looked_up(self, us: np.ndarray, w: int) -> np.ndarray:
        """:meth:`_segments_clear` by the edges and bridges the grid finds near each segment;
        the edges that block the most of them join those tried first.

        Segments many grid cells long first meet the ring edges in the cells along their first
        stretches from u, ``_NEAR_CELLS`` cells long (an island with no valid bridge is tested
        against every vertex, and most of those segments leave the polygon near u): those
        blocked there are not looked up along their whole length."""
        x, y = self.x, self.y
        wx, wy = float(x[w]), float(y[w])
        clear = np.ones(len(us), dtype=bool)
        ux, uy = x[us], y[us]
        cell = max(self.edges.size_x, self.edges.size_y)
        length = np.maximum(np.abs(wx - ux), np.abs(wy - uy))
        starts, ends = [], []
        for cells in _NEAR_CELLS:
            long = np.flatnonzero(clear & (length > _LONG_SHARE * cells * cell))
            if len(long) < _LONG_SEGMENTS:
                break
            found = self._blocked_near(ux[long], uy[long], length[long], wx, wy, cells * cell)
            if found is None:
                break
            blocked, a, b = found
            clear[long[blocked]] = False
            starts.append(a)
            ends.append(b)
        rest = np.flatnonzero(clear)
        if len(rest):
            blocked, a, b = self._blocked_whole(ux[rest], uy[rest], wx, wy)
            clear[rest[blocked]] = False
            starts.append(a)
            ends.append(b)
        if not clear.all():
            # the edges that blocked the most of these segments, then those known before (ties
            # by start, then end: one integer key per edge sorts as the pairs do)
            span = len(x) + 1
            keys, count = np.unique(
                np.concatenate(starts) * span + np.concatenate(ends), return_counts=True
            )
            keys = keys[np.argsort(-count, kind="stable")]
            fresh = np.column_stack([keys // span, keys % span])
            self._known = np.concatenate([fresh, self._known])[:_KNOWN_BLOCKERS]
        return clear

    def _blocked_near(
        self,
        ux: np.ndarray,
        uy: np.ndarray,
        length: np.ndarray,
        wx: float,
        wy: float,
        reach: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The segments u-w (indices) that a ring edge in the grid cells along their first
        ``reach`` (in x or y; ``length`` the whole in x or y) from u blocks, with the blocking
        edges' ends (exact); None where a point that far along is not a finite float."""
        with np.errstate(over="ignore", invalid="ignore"):
            share = reach / length
            mx, my = ux + share * (wx - ux), uy + share * (wy - uy)
        if not (np.isfinite(mx).all() and np.isfinite(my).all()):
            return None
        row, found = self.edges.query_segments(ux, uy, mx, my)
        return self._blocking(row, self.edge_a[found], self.edge_b[found], ux, uy, wx, wy)

    def _blocked_whole(
        self, ux: np.ndarray, uy: np.ndarray, wx: float, wy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The segments u-w (indices) that a ring edge in the grid cells along them, or a
        bridge made so far, blocks, with the blocking edges' ends (exact)."""
        x, y = self.x, self.y
        row, found = self.edges.query_segments(ux, uy, np.full(len(ux), wx), np.full(len(ux), wy))
        a, b = self.edge_a[found], self.edge_b[found]
        if self.bridge_count:
            extra = self.bridges[: self.bridge_count]
            # only (segment, bridge) pairs whose bounding boxes meet can meet (exact)
            bxa, bya, bxb, byb = x[extra[:, 0]], y[extra[:, 0]], x[extra[:, 1]], y[extra[:, 1]]
            near = (
                (np.maximum(bxa, bxb) >= np.minimum(ux, wx)[:, None])
                & (np.minimum(bxa, bxb) <= np.maximum(ux, wx)[:, None])
                & (np.maximum(bya, byb) >= np.minimum(uy, wy)[:, None])
                & (np.minimum(bya, byb) <= np.maximum(uy, wy)[:, None])
            )
            pair_row, pair_bridge = np.nonzero(near)
            row = np.concatenate([row, pair_row])
            a = np.concatenate([a, extra[pair_bridge, 0]])
            b = np.concatenate([b, extra[pair_bridge, 1]])
        return self._blocking(row, a, b, ux, uy, wx, wy)

    def _blocking(
        self,
        row: np.ndarray,
        a: np.ndarray,
        b: np.ndarray,
        ux: np.ndarray,
        uy: np.ndarray,
        wx: float,
        wy: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Of the (segment ``row``, edge a-b) pairs, the segments an edge blocks (indices,
        each once) and the blocking edges' ends (``bridge_plan.blocking_pairs``)."""
        hit = blocking_pairs(self.x, self.y, row, a, b, ux, uy, wx, wy)
        blocked = np.zeros(len(ux), dtype=bool)
        blocked[row[hit]] = True
        return np.flatnonzero(blocked), a[hit], b[hit]

    def _valid_many(self, vids: np.ndarray, island: np.ndarray, h_index: int) -> list[list[int]]:
        """:meth:`_valid_occurrences` of each vertex of ``vids``, the tests vectorised."""
        if len(vids) == 1:
            return [self._valid_occurrences(int(vids[0]), island, h_index)]
        x, y = self.x, self.y
        h = int(island[h_index])
        hx, hy = float(x[h]), float(y[h])
        firsts = self.first[vids]
        inside = self._inside_angle_many(firsts, hx, hy).tolist()
        result: list[list[int]] = [[k] if ok else [] for k, ok in zip(firsts.tolist(), inside)]
        same = ((x[vids] == hx) & (y[vids] == hy)).tolist()
        more = self.more
        for index, vid in enumerate(vids.tolist()):
            if same[index]:
                result[index] = self._valid_occurrences(vid, island, h_index)
            elif vid in more:
                result[index] += [k for k in more[vid] if self._inside_angle(k, hx, hy)]
        picked = np.array(
            [index for index, ks in enumerate(result) if ks and not same[index]], dtype=np.int64
        )
        if len(picked):
            clear = self._segments_clear(vids[picked], h)
            for index in picked[~clear].tolist():
                result[index] = []
        return result

    # -- search ---------------------------------------------------------------------------
    def _in_vain(self, h: int) -> None:
        """Record that the search from h found no valid target in the whole sequence."""
        self._hopeless[h] = self.count
        self.searched_in_vain = True

    def find_bridge(
        self, island: np.ndarray, h_index: int, give_up: float = math.inf
    ) -> tuple[int, int] | None:
        """(node, vertex id) of the bridge target for the island, or None.

        The sequence's vertices near h are tested nearest first, in blocks at once, until
        the nearest valid one is known and every one within the tie margin of it. None also
        where the nearest valid one surely lies beyond ``give_up`` (the search stops there).

        Where a search from this vertex found no valid target among all the vertices of the
        sequence, none of those can be valid later (bridges only block more segments, and a
        splice only divides a vertex's angle where its bridge leaves inside it): only the
        vertices joined since are tested, and where none of them is valid either, None. A
        splice that may widen an angle (:meth:`splice`) forgets every such search.
        """
        x, y = self.x, self.y
        h = int(island[h_index])
        hx, hy = float(x[h]), float(y[h])
        since = self._hopeless.get(h)
        if since is not None:
            fresh = np.unique(self.vid[since : self.count])
            fresh = fresh[self.first[fresh] >= since]
            if not len(fresh) or not any(self._valid_many(fresh, island, h_index)):
                self._in_vain(h)
                return None
        grid = self.points
        radius = max(grid.size_x, grid.size_y)
        full = max(grid.size_x * grid.nx, grid.size_y * grid.ny) * 2.0 + radius
        tested: dict[int, list[int]] = {}
        while True:
            found = self.point_ids[
                np.unique(grid.query_box(hx - radius, hy - radius, hx + radius, hy + radius))
            ]
            found = found[self.in_seq[found]]
            d2 = (x[found] - hx) ** 2 + (y[found] - hy) ** 2
            order = np.argsort(d2, kind="stable")
            near, dist = found[order], d2[order]
            limit = radius * radius
            # beyond the radius only once the box covers everything
            end = len(near) if radius >= full else int(np.searchsorted(dist, limit, "right"))
            best = None
            position, block = 0, 1  # the nearest alone: it is valid most of the time
            while position < end:
                stop = min(position + block, end)
                if best is not None:
                    reach = best * (1 + _DISTANCE_MARGIN)
                    stop = min(end, int(np.searchsorted(dist, reach, "right")))
                    if stop <= position:
                        break
                block = _FIRST_BLOCK if block == 1 else min(2 * block, _LAST_BLOCK)
                chunk = near[position:stop]
                fresh = np.array([vid not in tested for vid in chunk.tolist()], dtype=bool)
                if fresh.any():
                    untested = chunk[fresh]
                    valid = self._valid_many(untested, island, h_index)
                    tested.update(zip(untested.tolist(), valid))
                if best is None:
                    for vid, value in zip(chunk.tolist(), dist[position:stop].tolist()):
                        if tested[vid]:
                            best = value
                            break
                position = stop
            if best is not None and (best * (1 + _DISTANCE_MARGIN) <= limit or radius >= full):
                return self._nearest_exact(tested, h, best)
            if radius >= full:
                self._in_vain(h)
                return None
            if radius >= give_up:
                return None
            radius *= 2.0

    def _nearest_exact(self, tested: dict[int, list[int]], h: int, best: float) -> tuple[int, int]:
        x, y = self.x, self.y
        options = []
        for vid, ks in tested.items():
            if not ks:
                continue
            dist = float((x[vid] - x[h]) ** 2 + (y[vid] - y[h]) ** 2)
            if dist <= best * (1 + _DISTANCE_MARGIN):
                exact = exact_sq_distance(x[vid], y[vid], x[h], y[h])
                options.extend((exact, k, vid) for k in ks)
        # ties go to the first occurrence in the sequence
        least = min(exact for exact, _, _ in options)
        nearest = {k: vid for exact, k, vid in options if exact == least}
        k = self.earliest(list(nearest))
        return k, nearest[k]

    def diametral_disk_empty(self, h: int, v: int) -> bool:
        """No vertex (of any ring) lies strictly inside the circle with diameter h-v.

        Then h-v is an edge of the constrained Delaunay triangulation of the rings (that
        circle through h and v holds no vertex at all, visible or not). Exact:
        w is strictly inside iff (w - h) . (w - v) < 0.
        """
        x, y = self.x, self.y
        hx, hy, vx, vy = float(x[h]), float(y[h]), float(x[v]), float(y[v])
        mx, my = 0.5 * (hx + vx), 0.5 * (hy + vy)
        r = 0.5 * float(np.hypot(vx - hx, vy - hy)) * (1 + 1e-9)
        found = self.point_ids[np.unique(self.points.query_box(mx - r, my - r, mx + r, my + r))]
        wx, wy = x[found], y[found]
        dot = (wx - hx) * (wx - vx) + (wy - hy) * (wy - vy)
        scale = np.abs(wx - hx) * np.abs(wx - vx) + np.abs(wy - hy) * np.abs(wy - vy)
        # not surely beyond the error bound (nor an overflow's nan): decided exactly
        unsure = ~(np.abs(dot) > 8.0 * 2.0**-53 * scale + 1e-300)
        if (dot[~unsure] < 0).any():
            return False
        for w in found[unsure].tolist():
            fx, fy = Fraction(float(x[w])), Fraction(float(y[w]))
            if (fx - Fraction(hx)) * (fx - Fraction(vx)) + (fy - Fraction(hy)) * (
                fy - Fraction(vy)
            ) < 0:
                return False
        return True

    def _disk_never_empty_beyond(self, h: int) -> tuple[float, np.ndarray]:
        """A distance beyond which no vertex v has an empty diametral circle h-v (inf if none
        is found), and the vertices near h it comes from (:func:`_witness_bound`): the least
        of the bounds of up to ``_GAP_ROUNDS`` neighbourhoods of h, each twice as wide, until
        one leaves no angular gap of 90 degrees around h (a wider one then gains little).
        Margins cover the float angles and distances."""
        known = self._disk_bounds.get(h)
        if known is not None:
            return known
        x, y = self.x, self.y
        hx, hy = float(x[h]), float(y[h])
        grid = self.points
        radius = 2.0 * max(grid.size_x, grid.size_y)
        best, witnesses = math.inf, self.point_ids[:0]
        for _ in range(_GAP_ROUNDS):
            found = self.point_ids[
                np.unique(grid.query_box(hx - radius, hy - radius, hx + radius, hy + radius))
            ]
            dx, dy = x[found] - hx, y[found] - hy
            d2 = dx * dx + dy * dy
            near = (d2 > 0) & (d2 <= radius * radius)
            if np.count_nonzero(near) >= 3:
                reach, closed = _witness_bound(dx[near], dy[near])
                if reach < best:
                    best, witnesses = reach, found[near]
                if closed:
                    break
            radius *= 2.0
        if len(witnesses) > _NEAREST_WITNESSES:  # the nearest lie in the most circles
            wx, wy = x[witnesses] - hx, y[witnesses] - hy
            witnesses = witnesses[np.argsort(wx * wx + wy * wy)[:_NEAREST_WITNESSES]]
        if len(self._disk_bounds) < _BOUNDS_KEPT:
            self._disk_bounds[h] = best, witnesses
        return best, witnesses

    def _disks_left(self, h: int, reach: float, near: np.ndarray) -> np.ndarray:
        """The vertices of the sequence within ``reach`` of h (in x and y), nearest first,
        whose diametral circle with h holds no vertex of ``near`` (the nearest witnesses,
        :meth:`_disk_never_empty_beyond`) found strictly inside (float values beyond their
        error bound): the others' bridges from h are no Delaunay edges."""
        x, y = self.x, self.y
        hx, hy = float(x[h]), float(y[h])
        found = self.point_ids[
            np.unique(self.points.query_box(hx - reach, hy - reach, hx + reach, hy + reach))
        ]
        found = found[self.in_seq[found]]
        vx, vy = x[found] - hx, y[found] - hy
        wx, wy = x[near] - hx, y[near] - hy
        # (w - h) . (v - h) - |w - h|^2 > 0, per (v, w)
        dot = wx * vx[:, None] + wy * vy[:, None]
        own = wx * wx + wy * wy
        size = np.abs(wx) * np.abs(vx[:, None]) + np.abs(wy) * np.abs(vy[:, None]) + own
        inside = dot - own > 16.0 * 2.0**-53 * size + 1e-300
        kept = np.flatnonzero(~inside.any(axis=1))
        return found[kept[np.argsort(vx[kept] ** 2 + vy[kept] ** 2, kind="stable")]]

    def find_delaunay_bridge(self, island: np.ndarray, h_index: int) -> tuple[int, int, int] | None:
        """(node, vertex id, island index) of a bridge that is a constrained Delaunay edge, or
        None: from the island's vertices in ring order starting at ``h_index`` (its leftmost),
        the first whose nearest valid target (:meth:`find_bridge`) has an empty diametral
        circle (:meth:`diametral_disk_empty`).

        A vertex h is passed over without a search where no vertex within its witness bound
        (:meth:`_disk_never_empty_beyond`) has an empty circle with it: its nearest valid
        target, wherever it is, has none (within the bound the witnesses near h, or for up
        to ``_FEW_DISKS`` vertices left the exact test, say so; beyond it the bound does)."""
        for step in range(len(island)):
            index = (h_index + step) % len(island)
            h = int(island[index])
            reach, near = self._disk_never_empty_beyond(h)
            if reach < math.inf:
                left = self._disks_left(h, reach, near)
                if len(left) <= _FEW_DISKS and not any(
                    self.diametral_disk_empty(h, v) for v in left.tolist()
                ):
                    continue  # this vertex's bridge, wherever it goes, is no Delaunay edge
            target = self.find_bridge(island, index, reach)
            if target is not None and self.diametral_disk_empty(h, target[1]):
                return target[0], target[1], index
        return None

    def splice(self, k: int, island: np.ndarray, h_index: int) -> None:
        """Join the island at occurrence (node) k (docs/algorithm.md section 2)."""
        x, y = self.x, self.y
        h = int(island[h_index])
        sk = int(self.vid[k])
        touching = x[sk] == x[h] and y[sk] == y[h]
        if self._hopeless and (touching or not self._inside_angle(k, x[h], y[h])):
            # the angle at s_k may widen (a touching island's edge along the sequence's
            # leaves a spike there, whose angle takes every direction but its own; a bridge
            # with no valid target may leave outside the angle): a vertex found no valid
            # target may become one, so the searches that found none are forgotten
            self._hopeless.clear()
        if len(island) == 1:  # an interior point: ..., s_k, p, s_k, ...
            if touching:
                parts = [h]
            else:
                self._add_bridge(sk, h)
                parts = [sk, h] if k == 0 else [h, sk]
            self._insert_few_after(int(self.prv[0]) if k == 0 else k, parts)
            self._add_points(island)
            return
        if not touching:
            self._add_bridge(sk, h)
        # k == 0: the island goes to the end, so that S keeps its first two vertices
        node = int(self.prv[0]) if k == 0 else k
        if len(island) <= _FEW:
            ring = island.tolist()
            loop = ring[h_index:] + ring[:h_index]
            if touching:
                self._insert_few_after(node, loop if k == 0 else loop[1:] + loop[:1])
            else:
                self._insert_few_after(node, [sk, *loop, h] if k == 0 else [*loop, h, sk])
        else:
            loop = np.roll(island, -h_index)
            if touching:
                arrays = [loop] if k == 0 else [loop[1:], loop[:1]]
            else:
                shared = np.array([sk], dtype=np.int64)
                arrays = [shared, loop, loop[:1]] if k == 0 else [loop, loop[:1], shared]
            self._insert_after(node, np.concatenate(arrays))
        self._add_points(island)

    def _add_bridge(self, sk: int, h: int) -> None:
        self.bridges[self.bridge_count] = (sk, h)
        self.bridge_count += 1
        x, y = self.x, self.y
        self.bridge_cells.add(float(x[sk]), float(y[sk]), float(x[h]), float(y[h]))

    def nearest_occurrence(self, h: int) -> tuple[int, int]:
        """(node, vertex id) of the occurrence nearest to vertex ``h`` (first on ties)."""
        x, y = self.x, self.y
        order = self._order()
        seq = self.vid[order]
        d2 = (x[seq] - x[h]) ** 2 + (y[seq] - y[h]) ** 2
        k = int(np.argmin(d2))
        return int(order[k]), int(seq[k])


def bridge_islands(
    x: np.ndarray,
    y: np.ndarray,
    rings: list[np.ndarray],
    ring_numbers: list[int],
    relaxed: bool = False,
    delaunay: bool = False,
    alive: Callable[[], None] | None = None,
) -> np.ndarray:
    """The single vertex sequence of the outer ring with every island joined by a bridge
    (``alive``: called every ``_ALIVE_EVERY`` islands joined; it may raise to stop).

    Islands that share a point with the sequence are joined there (zero-length bridge) before
    any other island is bridged, so that touching rings never enclose an extra face. An island
    with no valid bridge (outside the outer ring, crossing a ring) raises, unless ``relaxed``:
    then it is joined to the nearest occurrence of the sequence, crossing or not.

    ``delaunay`` (rule "delaunay"): every bridge must be a constrained Delaunay edge of the
    rings (:meth:`_Bridger.find_delaunay_bridge`); an island that has none to the sequence
    yet waits until the other islands are joined, and only then takes the usual bridge
    (docs/algorithm.md, "Rule delaunay"). Without it the bridges are those of section 2.

    Once a search has found no valid target among all the vertices of the sequence (k islands
    outside a ring of n vertices would cost k n tests), an island vertex strictly outside the
    outer ring is not searched from: under rule delaunay an island with every vertex outside
    waits for the last round, and with ``relaxed`` an island whose bridge vertex is outside
    is joined to the nearest occurrence at once. Until an island has been joined so, that is
    the search's own outcome where the outer ring is simple; a relaxed bridge may open the
    angle at its end to the outside, and a ring that crosses itself may have a lobe wound the
    other way, where the search could find a valid target that the nearest occurrence
    replaces.
    """
    if len(rings) == 1:
        return rings[0]
    bridger = _Bridger(x, y, rings)
    if alive is not None:
        alive()
    leftmost: list[tuple[float, float, int, int]] = []
    for slot in range(1, len(rings)):
        ring = rings[slot]
        # leftmost vertex: smallest x, then y, then the first in input order
        h_index = int(np.lexsort((ring, y[ring], x[ring]))[0])
        h = int(ring[h_index])
        leftmost.append((float(x[h]), float(y[h]), slot, h_index))
    leftmost.sort()
    rank = {item[2]: number for number, item in enumerate(leftmost)}
    partners = touching_islands(bridger.point_of, rings)
    plan: dict[int, int] = {}
    if not delaunay and _plannable(rings):
        joins = _join_order(len(rings), leftmost, partners, rank)
        grids = (bridger.points, bridger.point_ids, bridger.edges, bridger.edge_a, bridger.edge_b)
        plan = plan_targets(x, y, rings, joins, grids, bridger.point_of)
        if alive is not None:
            alive()
    joined = [False] * len(rings)
    touching = _TouchingQueue(partners, rank, joined)
    touching.mark(0)
    # delaunay: a point is tried as soon as a vertex linked to it is in (points.PointOrder)
    order = point_order(x, y, rings, bridger.point_ids) if delaunay else None
    ready = deque(order.ready(rings[0].tolist()) if order else ())
    # delaunay: islands along links that are constrained Delaunay edges, breadth-first
    links = None
    if delaunay and len(rings) - 1 > LINKED_ISLANDS:
        links = delaunay_links(
            x, y, rings, bridger.point_ids, bridger.edges, bridger.edge_a, bridger.edge_b
        )
    linked = deque(links.ready(rings[0].tolist()) if links else ())
    pending = iter(leftmost)
    waiting: list[tuple[float, float, int, int]] = []  # delaunay: islands with no bridge yet
    progress = False
    # once a whole search found nothing: per vertex, an island vertex strictly outside
    outside: np.ndarray | None = None
    done = 0  # islands joined
    while True:
        if outside is None and bridger.searched_in_vain:
            outside = _outside_vertices(x, y, rings)
        slot = touching.pop()
        if slot is not None:
            h_index = _touch_index(x, y, rings[slot], bridger)
            target = bridger.find_bridge(rings[slot], h_index)
        elif ready and order:
            (slot, near), h_index = ready.popleft(), 0
            if joined[slot]:
                continue
            h = int(rings[slot][0])
            target = nearest_point_bridge(bridger, h, near)
            target = target or delaunay_point_bridge(bridger, h)
            if target is None:  # it waits in pending or waiting
                continue
            progress = True
        elif linked:
            slot, h_index, near = linked.popleft()
            if joined[slot]:
                continue
            target = bridger.linked(near, rings[slot], h_index)
            if target is None:  # another link, or pending, may join it
                continue
            progress = True
        else:
            item = next((i for i in pending if not joined[i[2]]), None)
            if item is None and waiting:
                # another round over the waiting islands; the last round takes any bridge
                final = not progress
                pending, waiting, progress = iter(waiting), [], False
                item = next((i for i in pending if not joined[i[2]]), None)
            else:
                final = not delaunay
            if item is None:
                break
            slot, h_index = item[2], item[3]
            target = None
            if not final:
                if outside is not None and outside[rings[slot]].all():
                    waiting.append(item)
                    continue
                if len(rings[slot]) == 1:
                    point = delaunay_point_bridge(bridger, int(rings[slot][0]))
                    found = None if point is None else (*point, 0)
                else:
                    found = bridger.find_delaunay_bridge(rings[slot], h_index)
                if found is None:
                    waiting.append(item)
                    continue
                target, h_index = found[:2], found[2]
                progress = True
            elif not (relaxed and outside is not None and outside[rings[slot][h_index]]):
                planned = plan.get(slot)
                if planned is not None:
                    target = bridger.planned(planned, rings[slot], h_index)
                if target is None:
                    target = bridger.find_bridge(rings[slot], h_index)
        if target is None and relaxed:
            target = bridger.nearest_occurrence(int(rings[slot][h_index]))
        if target is None:
            raise TriangulationError(
                f"{ring_label(ring_numbers[slot])}: no bridge to the outer ring found "
                "(the island may lie outside the outer ring or cross it)"
            )
        bridger.splice(target[0], rings[slot], h_index)
        joined[slot] = True
        done += 1
        if alive is not None and done % _ALIVE_EVERY == 0:
            alive()
        touching.mark(slot)
        if order:
            ready.extend(order.ready(rings[slot].tolist()))
        if links:
            linked.extend(links.ready(rings[slot].tolist()))
    return bridger.seq


# bridge_islands calls ``alive`` after this many islands
_ALIVE_EVERY = 64


def _outside_vertices(x: np.ndarray, y: np.ndarray, rings: list[np.ndarray]) -> np.ndarray:
    """Per vertex id: a vertex of an island strictly outside the outer ring (exact)."""
    outside = np.zeros(len(x), dtype=bool)
    islands = np.unique(np.concatenate(rings[1:]))
    outside[islands] = strictly_outside(x, y, rings[:1], x[islands], y[islands])
    return outside


class _TouchingQueue:
    """The islands not joined yet that share a point with the sequence, by leftmost rank: they
    are joined before any other (docs/algorithm.md, section 2). ``partners``: per ring slot,
    the islands sharing a point with it (``shared_points.touching_islands``); ``joined`` is
    the caller's per-slot flags, read when islands are queued and taken."""

    def __init__(self, partners: list[list[int]], rank: dict[int, int], joined: list[bool]) -> None:
        self.partners, self.rank, self.joined = partners, rank, joined
        self._heap: list[tuple[int, int]] = []

    def mark(self, slot: int) -> None:
        """Queue the islands sharing a point with ring ``slot`` (now in the sequence)."""
        heap, rank, joined = self._heap, self.rank, self.joined
        for other in self.partners[slot]:
            if not joined[other]:
                heapq.heappush(heap, (rank[other], other))

    def pop(self) -> int | None:
        """The next queued island not joined yet, or None."""
        while self._heap:
            _, slot = heapq.heappop(self._heap)
            if not self.joined[slot]:
                return slot
        return None


# islands from which their bridges are planned all at once (bridge_plan)
_PLANNED_ISLANDS = 16


def _plannable(rings: list[np.ndarray]) -> bool:
    """Many islands, each of 3 vertices or more."""
    return len(rings) > _PLANNED_ISLANDS and min(len(r) for r in rings) >= 3


def _join_order(
    ring_count: int,
    leftmost: list[tuple[float, float, int, int]],
    partners: list[list[int]],
    rank: dict[int, int],
) -> list[tuple[int, int, bool]]:
    """(slot, bridge vertex index, not touching) of every island in the order
    :func:`bridge_islands` joins them (rule first or elevation): islands touching the
    sequence first, by leftmost rank, then the next in leftmost order. Touching joins have
    no planned target (their bridge vertex index is not used)."""
    joined = [False] * ring_count
    touching = _TouchingQueue(partners, rank, joined)
    order: list[tuple[int, int, bool]] = []
    touching.mark(0)
    pending = iter(leftmost)
    while True:
        slot = touching.pop()
        if slot is not None:
            order.append((slot, 0, False))
        else:
            item = next((i for i in pending if not joined[i[2]]), None)
            if item is None:
                break
            slot = item[2]
            order.append((slot, item[3], True))
        joined[slot] = True
        touching.mark(slot)
    return order


def _touch_index(x: np.ndarray, y: np.ndarray, ring: np.ndarray, bridger: _Bridger) -> int:
    """Index in ``ring`` of its leftmost vertex that coincides with a vertex of the sequence."""
    best = None
    in_seq = bridger.point_in_seq[bridger.point_of[ring]].tolist()
    for index, vid in enumerate(ring.tolist()):
        key = (float(x[vid]), float(y[vid]))
        if in_seq[index] and (best is None or key < best[0]):
            best = (key, index)
    return best[1] if best is not None else 0


def remove_spikes(
    x: np.ndarray, y: np.ndarray, seq: np.ndarray, kept: np.ndarray | None = None
) -> np.ndarray:
    """Cancel every edge that is immediately walked back (..., p, s, p, ...) -> (..., p, ...).

    Such zero-width spikes come from rings sharing an edge (invalid input, e.g. an island
    along the outer ring); they enclose no area. The sequence is cyclic. ``kept``: per
    vertex id, True for the tips that stay (interior points joined by a bridge).
    """
    px, py = x[seq], y[seq]
    if len(seq) >= 3 and not ((px == np.roll(px, 2)) & (py == np.roll(py, 2))).any():
        return seq  # no point (cyclically) equals the one two before it: no spike
    xs, ys = px.tolist(), py.tolist()
    tip = [False] * len(seq) if kept is None else kept[seq].tolist()
    stack: list[int] = []
    for index in range(len(seq)):
        point = (xs[index], ys[index])
        if len(stack) >= 2 and (xs[stack[-2]], ys[stack[-2]]) == point and not tip[stack[-1]]:
            stack.pop()
            continue
        stack.append(index)
    changed = True
    while changed and len(stack) >= 3:
        changed = False
        first, second = stack[0], stack[1]
        last, before_last = stack[-1], stack[-2]
        if (xs[last], ys[last]) == (xs[second], ys[second]) and not tip[first]:
            stack = stack[1:-1] if len(stack) > 3 else []  # spike at the first position
            changed = True
        elif (xs[before_last], ys[before_last]) == (xs[first], ys[first]) and not tip[last]:
            stack = stack[:-2]  # spike at the last position
            changed = True
    if len(stack) < 3:
        return seq[:0]
    if len(stack) == len(seq):
        return seq
    return seq[np.asarray(stack, dtype=np.int64)]


def _witness_bound(dx: np.ndarray, dy: np.ndarray) -> tuple[float, bool]:
    """For witnesses w at offsets (dx, dy) from h (none at h): a distance beyond which every
    point v has one of them strictly inside its diametral circle with h (inf where they leave
    an angular gap of nearly 180 degrees or more around h), and whether they leave no gap of
    90 degrees.

    w lies strictly inside the circle iff (w - h) . (v - h) > |w - h|^2: v beyond the line
    through w square to h-w. Between two witnesses next to each other around h (directions
    u_i, u_j at angle g < 180 degrees, distances d_i, d_j) the points inside neither half
    plane lie in a convex corner: its far point is where the two lines meet (if that lies
    between the directions) or on one of the two rays. Where no gap reaches 90 degrees,
    every v farther than sqrt(2) max d also lies within 45 degrees of some w, which bounds
    it too. Margins cover the float angles and distances."""
    # witnesses nearer than the normal floats' range (imprecise angles and distances) left
    # out: fewer witnesses only widen the corners
    distance = np.hypot(dx, dy)
    normal = distance >= _LEAST_OFFSET
    if len(normal) - np.count_nonzero(normal):
        dx, dy, distance = dx[normal], dy[normal], distance[normal]
        if len(dx) < 3:
            return math.inf, False
    angles = np.arctan2(dy, dx)
    order = np.argsort(angles, kind="stable")
    a = angles[order]
    d = distance[order]
    gaps = np.diff(np.append(a, a[0] + 2.0 * math.pi))
    widest = float(gaps.max())
    closed = widest < 0.5 * math.pi - _GAP_MARGIN
    scale = float(d.max())
    if widest >= math.pi - _OPEN_GAP or not 0.0 < scale < math.inf:
        return math.inf, False
    d = d / scale  # no overflow or loss to subnormals in the products below
    di, dj = d, np.roll(d, -1)
    c, half = np.cos(gaps), np.sin(0.5 * gaps)
    # the far end of each ray (the other line, where it meets the ray, may come first)
    with np.errstate(divide="ignore"):
        ti = np.where(c > 0, np.minimum(di, dj / c), di)
        tj = np.where(c > 0, np.minimum(dj, di / c), dj)
    far = np.maximum(ti, tj)
    # the lines' meeting point, where it lies between the two directions (loosely): its
    # squared distance (d_i^2 + d_j^2 - 2 d_i d_j cos g) / sin^2 g without cancellation
    loose = 1.0 - _GAP_MARGIN
    between = (di >= c * dj * loose) & (dj >= c * di * loose) & (gaps > _GAP_MARGIN)
    if between.any():
        g, p, q, h2 = gaps[between], di[between], dj[between], half[between]
        meet = np.sqrt((p - q) ** 2 + 4.0 * p * q * h2 * h2) / np.sin(g)
        far[between] = np.maximum(far[between], meet)
    bound = float(far.max())
    if closed:
        bound = min(bound, math.sqrt(2.0))
    bound *= scale * (1.0 + _GAP_MARGIN)
    if not _LEAST_OFFSET <= bound < math.inf:  # nan, or so small that rounding may spoil it
        return math.inf, closed
    return bound, closed
