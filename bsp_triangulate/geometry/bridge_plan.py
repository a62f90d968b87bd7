"""The bridge targets of many islands found at once (docs/algorithm.md, section 2).

Islands join in a fixed order (those touching the sequence first, then by leftmost vertex),
each to the nearest vertex of the sequence built so far from which a valid bridge leaves.
Two of the three tests do not depend on the sequence: a ring edge meeting the open segment or
a vertex on it, and the direction to the island inside the ring's interior angle at the
vertex (an earlier bridge at that vertex splits the angle in two: the direction lies in one
part, or along the bridge, where the segment holds the bridge's far end). The third, no
earlier bridge crossing the segment, is left to the caller, which joins the islands in turn.

So for every island at once, rounds of numpy tests find the nearest vertex of the outer ring
or of an island joined before it that passes the two fixed tests. A target is planned only
where it is clear-cut: the nearest candidates were found in a disk that holds the target
with a margin, no other candidate lies within the distance margin of the engine's exact
tie-break, and no touching vertex comes first (-1: the island takes the one-by-one search).
"""

from __future__ import annotations

import numpy as np

from .predicates import orient_many, strictly_between
from .spatial_index import SegmentGrid

# relative margin on squared distances within which the one-by-one search decides exactly
DISTANCE_MARGIN = 1e-9
# candidates per island tested in the first round (doubling after), and the rounds
_FIRST_BLOCK = 4
_ROUNDS = 6
# segments tested against the edges per numpy pass
_SEGMENTS_AT_ONCE = 2048
# farthest disk searched, in grid cells
_FARTHEST = 8


def segments_clear(
    x: np.ndarray,
    y: np.ndarray,
    grid: SegmentGrid,
    edge_a: np.ndarray,
    edge_b: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    wx: np.ndarray,
    wy: np.ndarray,
) -> np.ndarray:
    """Per segment u-w: no edge (``edge_a[i]``-``edge_b[i]``, in ``grid``) meets it in its
    open interior and no edge end lies in its relative interior (exact)."""
    if len(ux) > _SEGMENTS_AT_ONCE:  # bounded tables: long segments pass many edges
        return np.concatenate(
            [
                segments_clear(
                    x,
                    y,
                    grid,
                    edge_a,
                    edge_b,
                    *(v[k : k + _SEGMENTS_AT_ONCE] for v in (ux, uy, wx, wy)),
                )
                for k in range(0, len(ux), _SEGMENTS_AT_ONCE)
            ]
        )
    clear = np.ones(len(ux), dtype=bool)
    if len(ux) == 0:
        return clear
    row, found = grid.query_segments(ux, uy, wx, wy)
    clear[row[blocking_pairs(x, y, row, edge_a[found], edge_b[found], ux, uy, wx, wy)]] = False
    return clear


def blocking_pairs(
    x: np.ndarray,
    y: np.ndarray,
    row: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    wx: np.ndarray | float,
    wy: np.ndarray | float,
) -> np.ndarray:
    """Per pair (row, a, b): the edge a-b meets the segment of row ``row`` (of ``ux``..
    ``wy``; ``wx``, ``wy`` may be one point for all) in their open interiors, or the
    segment's relative interior holds a or b (exact)."""
    wx, wy = np.broadcast_to(wx, ux.shape), np.broadcast_to(wy, uy.shape)
    pax, pay, pbx, pby = x[a], y[a], x[b], y[b]
    pux, puy, pwx, pwy = ux[row], uy[row], wx[row], wy[row]
    # only edges whose bounding box meets the segment's can meet it (exact)
    near = (
        (np.maximum(pax, pbx) >= np.minimum(pux, pwx))
        & (np.minimum(pax, pbx) <= np.maximum(pux, pwx))
        & (np.maximum(pay, pby) >= np.minimum(puy, pwy))
        & (np.minimum(pay, pby) <= np.maximum(puy, pwy))
    )
    pick = np.flatnonzero(near)
    pux, puy, pwx, pwy = pux[pick], puy[pick], pwx[pick], pwy[pick]
    pax, pay, pbx, pby = pax[pick], pay[pick], pbx[pick], pby[pick]
    o1 = orient_many(pux, puy, pwx, pwy, pax, pay)
    o2 = orient_many(pux, puy, pwx, pwy, pbx, pby)
    on_a = (o1 == 0) & strictly_between(pax, pay, pux, puy, pwx, pwy)
    on_b = (o2 == 0) & strictly_between(pbx, pby, pux, puy, pwx, pwy)
    blocked = on_a | on_b
    straddle = np.flatnonzero(~blocked & ((o1.astype(np.int16) * o2) < 0))
    if len(straddle):
        qax, qay, qbx, qby = pax[straddle], pay[straddle], pbx[straddle], pby[straddle]
        o3 = orient_many(qax, qay, qbx, qby, pux[straddle], puy[straddle])
        o4 = orient_many(qax, qay, qbx, qby, pwx[straddle], pwy[straddle])
        blocked[straddle] = (o3.astype(np.int16) * o4) < 0
    mask = np.zeros(len(row), dtype=bool)
    mask[pick[blocked]] = True
    return mask


def inside_open_angle(
    x: np.ndarray,
    y: np.ndarray,
    p: np.ndarray,
    v: np.ndarray,
    n: np.ndarray,
    tx: np.ndarray | float,
    ty: np.ndarray | float,
) -> np.ndarray:
    """Per corner (p, v, n) of the sequence: the direction from v to (tx, ty) lies in its
    open interior angle (``bridges._Bridger._inside_angle``, vectorised)."""
    vx, vy, px, py, nx, ny = x[v], y[v], x[p], y[p], x[n], y[n]
    turn = orient_many(px, py, vx, vy, nx, ny)
    toward_next = orient_many(vx, vy, nx, ny, tx, ty)
    after_next = toward_next >= 1
    after_prev = orient_many(px, py, vx, vy, tx, ty) >= 1
    straight = (nx - vx) * (px - vx) + (ny - vy) * (py - vy) < 0
    on_ray = (toward_next == 0) & ((tx - vx) * (nx - vx) + (ty - vy) * (ny - vy) > 0)
    flat = np.where(straight, after_next, ~on_ray)
    return np.where(
        turn > 0, after_next & after_prev, np.where(turn < 0, after_next | after_prev, flat)
    )


def plan_targets(
    x: np.ndarray,
    y: np.ndarray,
    rings: list[np.ndarray],
    joins: list[tuple[int, int, bool]],
    grids: tuple[SegmentGrid, np.ndarray, SegmentGrid, np.ndarray, np.ndarray],
    point_of: np.ndarray,
) -> dict[int, int]:
    """{island slot: target vertex id} for the islands joined in the order ``joins`` (slot,
    index of its bridge vertex in its ring, planned: False for the islands joined where they
    touch the sequence), where clear-cut. Every island must have 3 vertices or more.
    ``grids``: a grid over the ring vertices ``points`` (as zero-length segments), and one
    over the ring edges from ``edge_a`` to ``edge_b``; ``point_of``: per vertex the number of
    its point (``shared_points.point_numbers``).

    A vertex that shares its point with another one or lies in two rings (touching rings)
    may occur in the sequence beside vertices of another ring: its ring angle says nothing,
    so an island whose nearest candidates reach one is left to the one-by-one search.
    """
    count = len(joins)
    if count == 0:
        return {}
    grid, points, edges, edge_a, edge_b = grids
    # per vertex: its ring's place in the join order (-1: the outer ring), and its ring
    # neighbours in traversal order
    lengths = np.array([len(r) for r in rings], dtype=np.int64)
    ids = np.concatenate(rings)
    rank = np.full(len(rings), count, dtype=np.int64)
    rank[0] = -1
    rank[[slot for slot, _, _ in joins]] = np.arange(count, dtype=np.int64)
    start = np.cumsum(lengths) - lengths
    local = np.arange(len(ids), dtype=np.int64) - np.repeat(start, lengths)
    ring_len = np.repeat(lengths, lengths)
    first = np.repeat(start, lengths)
    vertex_rank = np.full(len(x), count, dtype=np.int64)
    vertex_rank[ids] = np.repeat(rank, lengths)
    prev_of = np.full(len(x), -1, dtype=np.int64)
    next_of = np.full(len(x), -1, dtype=np.int64)
    prev_of[ids] = ids[first + (local - 1) % ring_len]
    next_of[ids] = ids[first + (local + 1) % ring_len]
    # vertices in two rings, and vertices sharing their point
    special = np.bincount(ids, minlength=len(x)) > 1
    number = point_of[points]
    special[points[np.bincount(number)[number] > 1]] = True
    shared = special[ids]
    if shared.any():
        # a touching vertex's rank is its earliest ring's: it is a candidate from then on
        np.minimum.at(vertex_rank, ids[shared], np.repeat(rank, lengths)[shared])
    planned = np.array([plan for _, _, plan in joins], dtype=bool)
    h = np.array([int(rings[slot][index]) for slot, index, _ in joins], dtype=np.int64)
    hx, hy = x[h], y[h]
    cell = max(grid.size_x, grid.size_y)
    radius = np.full(count, cell)
    # islands whose target lies farther take the one-by-one search (boxes stay small)
    reach_limit = min(_FARTHEST * cell, 2.0 * max(grid.size_x * grid.nx, grid.size_y * grid.ny))
    target = np.full(count, -1, dtype=np.int64)
    done = np.zeros(count, dtype=int)  # nearest candidates tested (all invalid) so far
    open_ = np.flatnonzero(planned)
    block = _FIRST_BLOCK
    for _ in range(_ROUNDS):
        if len(open_) == 0:
            break
        r = radius[open_]
        query, found = grid.query_boxes(hx[open_] - r, hy[open_] - r, hx[open_] + r, hy[open_] + r)
        cand = points[found]
        owner = open_[query]
        keep = vertex_rank[cand] < owner  # the outer ring and the islands joined before
        pair = np.unique(owner[keep] * len(x) + cand[keep])  # one pair per (island, vertex)
        owner, cand = pair // len(x), pair % len(x)
        d2 = (x[cand] - hx[owner]) ** 2 + (y[cand] - hy[owner]) ** 2
        order = _by_owner_then(d2, owner, count)
        owner, cand, d2 = owner[order], cand[order], d2[order]
        # per island, its candidates nearest first: place in that list, and how many lie in
        # its disk (the box query finds every vertex of the disk)
        starts = np.searchsorted(owner, open_)
        sizes = np.diff(np.append(starts, len(owner)))
        place = np.arange(len(owner), dtype=np.int64) - np.repeat(starts, sizes)
        inside = d2 <= radius[owner] ** 2
        in_disk = np.bincount(owner[inside], minlength=count)
        # the next ones to test: nearest first, not tested yet, in the disk
        t = np.flatnonzero(inside & (place >= done[owner]) & (place < done[owner] + block))
        tv, th = cand[t], h[owner[t]]
        ok = inside_open_angle(x, y, prev_of[tv], tv, next_of[tv], x[th], y[th])
        go = np.flatnonzero(ok)
        if len(go):
            gv, gh = tv[go], th[go]
            ok[go] = segments_clear(x, y, edges, edge_a, edge_b, x[gv], y[gv], x[gh], y[gh])
        # every nearer candidate was tested before and is invalid: the first valid one is the
        # nearest valid vertex; a touching vertex first: left to the one-by-one search
        ok |= special[tv]
        hit = t[ok]
        leading = np.ones(len(hit), dtype=bool)
        leading[1:] = owner[hit[1:]] != owner[hit[:-1]]
        hit = hit[leading]
        island = owner[hit]
        reach = d2[hit] * (1.0 + DISTANCE_MARGIN)
        sure = reach <= radius[island] ** 2  # else a wider disk may hold a nearer one
        following = np.minimum(hit + 1, len(owner) - 1)
        tie = (following > hit) & (owner[following] == island) & (d2[following] <= reach)
        tie |= special[cand[hit]]
        target[island[sure & ~tie]] = cand[hit[sure & ~tie]]
        decided = np.zeros(count, dtype=bool)
        decided[island[sure]] = True
        done += np.bincount(owner[t], minlength=count)
        left = open_[~decided[open_]]
        # every candidate in its disk tested and invalid, or a valid one too near the disk's
        # edge (tested again in the wider disk): a wider disk
        wider = left[done[left] >= in_disk[left]]
        unsure = hit[~sure]
        done[owner[unsure]] = place[unsure]
        wider = np.union1d(wider, owner[unsure])
        radius[wider] *= 2.0
        open_ = left[radius[left] <= reach_limit]
        block *= 2
    return {joins[i][0]: int(v) for i, v in enumerate(target.tolist()) if v >= 0}


def _by_owner_then(d2: np.ndarray, owner: np.ndarray, count: int) -> np.ndarray:
    """``np.lexsort((d2, owner))`` (owners below ``count``): two stable sorts, the second a
    radix sort where the owners fit 16 bits."""
    if count >= 2**15:
        return np.lexsort((d2, owner))
    by_d2 = np.argsort(d2, kind="stable")
    return by_d2[np.argsort(owner[by_d2].astype(np.int16), kind="stable")]
