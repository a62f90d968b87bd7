"""Island bridges for the batch path: ``bridges.bridge_islands`` over many polygons at once.

Only for polygons whose rings do not touch (no shared points, no vertex on an edge), where the
engine joins the islands in leftmost order, each to its nearest valid bridge vertex. Each round
tests the nearest untested occurrence of every polygon; a polygon whose nearest valid bridge
is not clear-cut in float64 (near-equal distances to different points) is not handled. Under
rule "delaunay" an island bridges from the first of its vertices (from the leftmost on, in
ring order) whose nearest valid target has an empty diametral circle; a polygon with an
island that has none is not handled.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from .predicates import strictly_between
from .predicates_batch import crossing, orient_items
from .rings_batch import FlatRings, covers_in_order, ragged_index

# relative margin within which two squared distances count as a tie (left to the engine)
_TIE = 1e-12
_MAX_TRIES = 24


def traversal_ids(flat: FlatRings) -> np.ndarray:
    """Vertex ids of every ring in traversal order (reversed islands backwards), laid out
    like the vertices themselves (ring r at ``ring_start[r]``)."""
    nv = len(flat.vx)
    ids = np.arange(nv, dtype=np.int64)
    rev = np.flatnonzero(flat.ring_reversed)
    if len(rev):
        pos = ragged_index(flat.ring_start[rev], flat.ring_len[rev])
        ring_of = np.repeat(rev, flat.ring_len[rev])
        first = flat.ring_start[ring_of]
        ids[pos] = first + flat.ring_len[ring_of] - 1 - (pos - first)
    return ids


def _segments(
    src: np.ndarray, starts: np.ndarray, lengths: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Gather of ``src`` segments (rows of ``starts``/``lengths`` concatenated per row)."""
    flat_len = lengths.reshape(-1)
    out = src[ragged_index(starts.reshape(-1), flat_len)]
    return out, lengths.sum(axis=1)


def _inside_angle(
    wx: np.ndarray,
    wy: np.ndarray,
    p: np.ndarray,
    v: np.ndarray,
    n: np.ndarray,
    tx: np.ndarray,
    ty: np.ndarray,
) -> np.ndarray:
    """``bridges._Bridger._inside_angle`` for arrays of (previous, vertex, next) occurrences."""
    px, py, vx, vy, nx, ny = wx[p], wy[p], wx[v], wy[v], wx[n], wy[n]
    turn = orient_items(px, py, vx, vy, nx, ny)
    on_next = orient_items(vx, vy, nx, ny, tx, ty)
    left_next = on_next > 0
    left_prev = orient_items(px, py, vx, vy, tx, ty) > 0
    straight = (nx - vx) * (px - vx) + (ny - vy) * (py - vy) < 0
    on_ray = (on_next == 0) & ((tx - vx) * (nx - vx) + (ty - vy) * (ny - vy) > 0)
    collinear = np.where(straight, left_next, ~on_ray)
    return np.where(
        turn > 0, left_next & left_prev, np.where(turn < 0, left_next | left_prev, collinear)
    )


class _Edges:
    """End points and bounding boxes of the edges of one bridging step."""

    def __init__(self, ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray) -> None:
        self.ax, self.ay, self.bx, self.by = ax, ay, bx, by
        self.lo_x = np.minimum(ax, bx)
        self.hi_x = np.maximum(ax, bx)

    @classmethod
    def of(cls, wx: np.ndarray, wy: np.ndarray, a: np.ndarray, b: np.ndarray) -> _Edges:
        """Edges a -> b."""
        return cls(wx[a], wy[a], wx[b], wy[b])

    @classmethod
    def of_rings(cls, flat: FlatRings, wx: np.ndarray, wy: np.ndarray) -> _Edges:
        """The edge of every vertex to the next in its ring, in vertex order."""
        start, last = flat.ring_start, flat.ring_start + flat.ring_len - 1
        ends = []
        for w in (wx, wy):
            end = np.empty_like(w)
            end[:-1] = w[1:]
            end[last] = w[start]
            ends.append(end)
        return cls(wx, wy, ends[0], ends[1])

    def __len__(self) -> int:
        return len(self.bx)


def _leftmost(
    flat: FlatRings, wx: np.ndarray, wy: np.ndarray, trav: np.ndarray, island_rings: np.ndarray
) -> np.ndarray:
    """Traversal position of each island's leftmost vertex (smallest x, then y; the first in
    traversal order)."""
    rlen = flat.ring_len[island_rings]
    pos = ragged_index(flat.ring_start[island_rings], rlen)
    first_of = np.cumsum(rlen) - rlen
    vid = trav[pos]
    vx = wx[vid]
    # the few vertices at their island's smallest x (one at least per island)
    at_left = np.flatnonzero(vx == np.repeat(np.minimum.reduceat(vx, first_of), rlen))
    owner = np.searchsorted(first_of, at_left, side="right") - 1
    runs = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    low_y = wy[vid[at_left]]
    at_low = low_y == np.repeat(np.minimum.reduceat(low_y, runs), np.diff(np.r_[runs, len(owner)]))
    at_left, owner = at_left[at_low], owner[at_low]
    return pos[at_left[np.r_[True, owner[1:] != owner[:-1]]]]


def _segment_clear(
    ux: np.ndarray,
    uy: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
    edge_start: np.ndarray,
    edge_count: np.ndarray,
    edges: _Edges,
) -> np.ndarray:
    """Per test i: no edge of its range meets the open segment u_i v_i, no vertex lies on it."""
    tests = np.arange(len(ux), dtype=np.int64)
    # the tests' ranges one after another over all edges: no gather of the edges
    whole = covers_in_order(edge_start, edge_count, len(edges))
    e = None if whole else ragged_index(edge_start, edge_count)
    # an edge that meets the closed segment meets its bounding box (exact comparisons):
    # x first, then y of the few edges left
    hi_x, lo_x = (edges.hi_x, edges.lo_x) if e is None else (edges.hi_x[e], edges.lo_x[e])
    near = np.flatnonzero(
        (hi_x >= np.repeat(np.minimum(ux, vx), edge_count))
        & (lo_x <= np.repeat(np.maximum(ux, vx), edge_count))
    )
    item = np.repeat(tests, edge_count)[near]
    if e is not None:
        near = e[near]
    ay, by = edges.ay[near], edges.by[near]
    near_y = np.flatnonzero(
        (np.maximum(ay, by) >= np.minimum(uy, vy)[item])
        & (np.minimum(ay, by) <= np.maximum(uy, vy)[item])
    )
    near, item, ay, by = near[near_y], item[near_y], ay[near_y], by[near_y]
    ux, uy, vx, vy = ux[item], uy[item], vx[item], vy[item]
    ax, bx = edges.ax[near], edges.bx[near]
    o1 = orient_items(ux, uy, vx, vy, ax, ay)
    o2 = orient_items(ux, uy, vx, vy, bx, by)
    blocked = np.zeros(len(item), dtype=bool)
    # an end point on the segment's line (mostly the segment's own ends) inside the segment
    for o, px, py in ((o1, ax, ay), (o2, bx, by)):
        z = np.flatnonzero(o == 0)
        blocked[z[strictly_between(px[z], py[z], ux[z], uy[z], vx[z], vy[z])]] = True
    blocked |= crossing(o1, o2, ax, ay, bx, by, ux, uy, vx, vy)
    return np.bincount(item[blocked], minlength=len(tests)) == 0


# nearest_valid's result for an island whose nearest valid bridge is not decided here
_UNDECIDED = -2
# island vertices tried per island for a Delaunay bridge before it is left to the engine
_DELAUNAY_ATTEMPTS = 8


class _Search:
    """The nearest valid bridge targets of one bridging step: every occurrence ``c_id`` of
    the active polygons' sequences (``c_start``, ``c_len`` per polygon) and the edges that
    may block a bridge (``e_start``, ``e_count`` per polygon)."""

    def __init__(
        self,
        wx: np.ndarray,
        wy: np.ndarray,
        c_id: np.ndarray,
        c_x: np.ndarray,
        c_y: np.ndarray,
        c_start: np.ndarray,
        c_len: np.ndarray,
        e_start: np.ndarray,
        e_count: np.ndarray,
        edges: _Edges,
    ) -> None:
        self.wx, self.wy, self.c_id, self.c_x, self.c_y = wx, wy, c_id, c_x, c_y
        self.c_start, self.c_len = c_start, c_len
        self.e_start, self.e_count, self.edges = e_start, e_count, edges

    def nearest_valid(self, hx: np.ndarray, hy: np.ndarray, pending: np.ndarray) -> np.ndarray:
        """Per active polygon whose island is ``pending``, bridging from (hx, hy): the index
        in its sequence of the nearest valid occurrence, -1 where none is valid, or
        ``_UNDECIDED`` (near-equal distances to different points, a zero distance, too many
        tries); -1 for the others."""
        wx, wy, c_id, c_x, c_y = self.wx, self.wy, self.c_id, self.c_x, self.c_y
        c_start, c_len, edges = self.c_start, self.c_len, self.edges
        pending = pending.copy()
        k_of = np.full(len(c_start), -1, dtype=np.int64)
        d2 = c_x - np.repeat(hx, c_len)
        d2 *= d2
        dy = c_y - np.repeat(hy, c_len)
        dy *= dy
        d2 += dy
        remaining = np.ones(len(c_id), dtype=bool)
        for attempt in range(_MAX_TRIES):
            if not pending.any():
                break
            # the first attempt: every occurrence remains
            masked = (
                d2
                if attempt == 0 and pending.all()
                else np.where(remaining & np.repeat(pending, c_len), d2, np.inf)
            )
            low = np.minimum.reduceat(masked, c_start)
            live = np.flatnonzero(pending & np.isfinite(low) & (low > 1e-200))
            dead = pending.copy()
            dead[live] = False
            pending[dead] = False
            k_of[dead & np.isfinite(low)] = _UNDECIDED
            if len(live) == 0:
                break
            # the first occurrence at the lowest distance of each live polygon (one at least)
            target = np.full(len(c_start), np.nan)
            target[live] = low[live]
            hits = np.flatnonzero(masked == np.repeat(target, c_len))
            hit_owner = np.searchsorted(c_start, hits, side="right") - 1
            b = hits[np.r_[True, hit_owner[1:] != hit_owner[:-1]]]
            n_len = c_len[live]
            seq0 = c_start[live]
            k = b - seq0
            prev = c_id[seq0 + (k - 1) % n_len]
            nxt_occ = c_id[seq0 + (k + 1) % n_len]
            valid = _inside_angle(wx, wy, prev, c_id[b], nxt_occ, hx[live], hy[live])
            test = np.flatnonzero(valid)
            if len(test):
                u = c_id[b[test]]
                clear = _segment_clear(
                    wx[u],
                    wy[u],
                    hx[live[test]],
                    hy[live[test]],
                    self.e_start[live[test]],
                    self.e_count[live[test]],
                    edges,
                )
                valid[test[~clear]] = False
            remaining[b[~valid]] = False
            done = live[valid]
            if len(done):
                # a different point at a near-equal distance: the engine decides exactly
                bd = b[valid]
                limit = np.full(len(c_start), -np.inf)
                limit[done] = low[done] * (1 + _TIE)
                near = np.flatnonzero(d2 <= np.repeat(limit, c_len))
                near = near[remaining[near]]
                best = np.zeros(len(c_start), dtype=np.int64)
                best[done] = bd
                rep = best[np.searchsorted(c_start, near, side="right") - 1]
                other = near[(c_x[near] != c_x[rep]) | (c_y[near] != c_y[rep])]
                tie = np.zeros(len(c_start), dtype=bool)
                tie[np.searchsorted(c_start, other, side="right") - 1] = True
                k_of[done] = np.where(tie[done], _UNDECIDED, bd - c_start[done])
                pending[done] = False
        k_of[pending] = _UNDECIDED
        return k_of


def _diametral_empty(
    wx: np.ndarray,
    wy: np.ndarray,
    h: np.ndarray,
    v: np.ndarray,
    vstart: np.ndarray,
    vcount: np.ndarray,
) -> np.ndarray:
    """Per test: no vertex of its polygon (``vcount`` vertices from ``vstart``) lies
    strictly inside the circle with diameter h-v (``bridges._Bridger.diametral_disk_empty``:
    w is inside iff (w - h) . (w - v) < 0, exact)."""
    item = np.repeat(np.arange(len(h), dtype=np.int64), vcount)
    w = ragged_index(vstart, vcount)
    px, py = wx[w], wy[w]
    hx, hy, vx, vy = wx[h][item], wy[h][item], wx[v][item], wy[v][item]
    a1, a2, b1, b2 = px - hx, px - vx, py - hy, py - vy
    dot = a1 * a2 + b1 * b2
    bound = 8.0 * 2.0**-53 * (np.abs(a1) * np.abs(a2) + np.abs(b1) * np.abs(b2)) + 1e-300
    inside = dot < -bound
    unsure = np.flatnonzero(~inside & ~(dot > bound))
    if len(unsure):
        # the ends themselves: exactly 0
        at_end = ((px[unsure] == hx[unsure]) & (py[unsure] == hy[unsure])) | (
            (px[unsure] == vx[unsure]) & (py[unsure] == vy[unsure])
        )
        for i in unsure[~at_end].tolist():
            fx, fy = Fraction(float(px[i])), Fraction(float(py[i]))
            exact = (fx - Fraction(float(hx[i]))) * (fx - Fraction(float(vx[i]))) + (
                fy - Fraction(float(hy[i]))
            ) * (fy - Fraction(float(vy[i])))
            inside[i] = exact < 0
    return np.bincount(item[inside], minlength=len(h)) == 0


def bridge_sequences(
    flat: FlatRings, wx: np.ndarray, wy: np.ndarray, polys: np.ndarray, delaunay: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bridged vertex sequences of ``polys`` (rings must not touch); ``delaunay``: the
    bridges of rule "delaunay" (each a constrained Delaunay edge, docs/algorithm.md 5a).

    Returns the flat sequence of vertex ids, each polygon's start and length in it, and a mask
    of the polygons whose bridges were decided (the others are left to the engine).
    """
    ring0 = flat.poly_ring0[polys]
    islands = flat.poly_rings[polys] - 1
    seq_len = flat.ring_len[ring0].copy()
    # outer rings are traversed forwards: their traversal ids are their positions
    seq = ragged_index(flat.ring_start[ring0], seq_len)
    seq_start = np.cumsum(seq_len) - seq_len
    ok = np.ones(len(polys), dtype=bool)
    if not (islands > 0).any():
        return seq, seq_start, seq_len, ok
    trav = traversal_ids(flat)
    # islands of each polygon in the order of their leftmost vertex (x, then y)
    island_rings = ragged_index(ring0 + 1, islands)
    island_poly = np.repeat(np.arange(len(polys), dtype=np.int64), islands)
    h_pos = _leftmost(flat, wx, wy, trav, island_rings)
    h_index = h_pos - flat.ring_start[island_rings]
    h_id = trav[h_pos]
    if islands.max() == 1:
        step_of = np.zeros(len(island_rings), dtype=np.int64)
    else:
        rank = np.lexsort((island_rings, wy[h_id], wx[h_id], island_poly))
        island_first = np.cumsum(islands) - islands
        step_of = np.empty(len(rank), dtype=np.int64)
        step_of[rank] = np.arange(len(rank)) - np.repeat(island_first, islands)
    # ring edges of each polygon: (v, next in ring) for all its vertices
    nv = len(wx)
    nxt = None
    bridge_a: list[np.ndarray] = []
    bridge_b: list[np.ndarray] = []
    bridge_p: list[np.ndarray] = []
    for step in range(int(islands.max())):
        chosen = np.flatnonzero(step_of == step)
        chosen = chosen[ok[island_poly[chosen]]]
        if len(chosen) == 0:
            break
        active = island_poly[chosen]
        ring = island_rings[chosen]
        hid = h_id[chosen]
        hx, hy = wx[hid], wy[hid]
        # edges: ring edges plus the bridges so far, grouped per active polygon
        vstart = flat.poly_vstart[polys[active]]
        vcount = flat.poly_vcount[polys[active]]
        e_count = vcount
        if not bridge_p and covers_in_order(vstart, vcount, nv):
            edges = _Edges.of_rings(flat, wx, wy)
        else:
            if nxt is None:
                nxt = np.arange(nv, dtype=np.int64) + 1
                nxt[flat.ring_start + flat.ring_len - 1] = flat.ring_start
            ea = ragged_index(vstart, vcount)
            eb = nxt[ea]
            if bridge_p:
                e_owner = np.repeat(np.arange(len(active), dtype=np.int64), vcount)
                slot = np.full(len(polys), -1, dtype=np.int64)
                slot[active] = np.arange(len(active))
                bp = slot[np.concatenate(bridge_p)]
                keep = bp >= 0
                ea = np.concatenate([ea, np.concatenate(bridge_a)[keep]])
                eb = np.concatenate([eb, np.concatenate(bridge_b)[keep]])
                e_owner = np.concatenate([e_owner, bp[keep]])
                by_owner = np.argsort(e_owner, kind="stable")
                ea, eb, e_owner = ea[by_owner], eb[by_owner], e_owner[by_owner]
                e_count = np.bincount(e_owner, minlength=len(active))
            edges = _Edges.of(wx, wy, ea, eb)
        e_start = np.cumsum(e_count) - e_count
        # candidates: every occurrence of the current sequences
        c_len = seq_len[active]
        c_start = np.cumsum(c_len) - c_len
        if covers_in_order(seq_start[active], c_len, len(seq)):
            c_id = seq
        else:
            c_id = seq[ragged_index(seq_start[active], c_len)]
        c_x, c_y = wx[c_id], wy[c_id]
        search = _Search(wx, wy, c_id, c_x, c_y, c_start, c_len, e_start, e_count, edges)
        if not delaunay:
            k_of = search.nearest_valid(hx, hy, np.ones(len(active), dtype=bool))
            ok[active[k_of < 0]] = False
            h_used = h_index[chosen]
        else:
            # rule "delaunay": from the leftmost vertex on in ring order, the first island
            # vertex whose nearest valid target has an empty diametral circle; an island
            # that has none (it would wait for the others) is left to the engine
            il = flat.ring_len[ring]
            h_used = h_index[chosen].copy()
            k_of = np.full(len(active), -1, dtype=np.int64)
            searching = np.ones(len(active), dtype=bool)
            for attempt in range(_DELAUNAY_ATTEMPTS):
                if attempt:
                    h_used = np.where(searching, (h_index[chosen] + attempt) % il, h_used)
                    hid = trav[flat.ring_start[ring] + h_used]
                    hx, hy = wx[hid], wy[hid]
                k = search.nearest_valid(hx, hy, searching)
                undecided = searching & (k == _UNDECIDED)
                ok[active[undecided]] = False
                searching &= ~undecided
                test = np.flatnonzero(searching & (k >= 0))
                if len(test):
                    target = c_id[c_start[test] + k[test]]
                    empty = _diametral_empty(wx, wy, hid[test], target, vstart[test], vcount[test])
                    done = test[empty]
                    k_of[done] = k[done]
                    searching[done] = False
                searching &= attempt + 1 < il
                if not searching.any():
                    break
            ok[active[k_of < 0]] = False
        # splice the island into every decided sequence
        go = np.flatnonzero(ok[active] & (k_of >= 0))
        if len(go) == 0:
            continue
        gp = active[go]
        k = k_of[go]
        n_len = seq_len[gp]
        s0 = seq_start[gp]
        r = ring[go]
        i0 = flat.ring_start[r] + len(seq)
        il = flat.ring_len[r]
        hi_ = h_used[go]
        at0 = k == 0
        zero = np.zeros(len(go), dtype=np.int64)
        starts = np.column_stack([s0, s0, i0 + hi_, i0, i0 + hi_, s0 + k])
        lengths = np.column_stack(
            [
                np.where(at0, n_len, k + 1),
                at0.astype(np.int64),
                il - hi_,
                hi_,
                zero + 1,
                np.where(at0, 0, n_len - k),
            ]
        )
        new_seq, new_len = _segments(np.concatenate([seq, trav]), starts, lengths)
        bridge_a.append(seq[s0 + k])
        bridge_b.append(trav[flat.ring_start[r] + hi_])
        bridge_p.append(gp)
        # rebuild the flat sequence with the grown polygons replaced
        if len(gp) == len(polys):
            seq, seq_len = new_seq, new_len
            seq_start = np.cumsum(seq_len) - seq_len
            continue
        seq_len_new = seq_len.copy()
        seq_len_new[gp] = new_len
        src_start = seq_start.copy()
        src_start[gp] = len(seq) + np.cumsum(new_len) - new_len
        seq = _segments(np.concatenate([seq, new_seq]), src_start[:, None], seq_len_new[:, None])[0]
        seq_len = seq_len_new
        seq_start = np.cumsum(seq_len) - seq_len
    return seq, seq_start, seq_len, ok
