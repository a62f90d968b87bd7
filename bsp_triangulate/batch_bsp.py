"""The BSP tree of many bridged sequences in lock-step rounds (docs/algorithm.md, 3-5).

Every open node (sub-polygon) of every polygon tests candidates in the same round; the tests
are the engine's ``facing_candidates`` and ``correct_candidates`` over flat ragged arrays.
Each node knows its pre-order index when it is created (a node on the range [lo, hi] has
hi - lo - 1 triangles below and including it), so triangles are written straight into their
final slots.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .batch_predicates import orient_items, orient_rows, row_bound
from .batch_rings import ragged_index
from .predicates import grid_exact, strictly_between

# test items x sub-polygon vertices per numpy pass: tables of about 1 MB stay in the cache
_CHUNK_ELEMENTS = 1 << 17


@dataclass
class Trees:
    """BSP results of many sequences: triangle rows of sequence i at ``start[i]``."""

    triangles: np.ndarray  # (T, 3) local vertex indices
    parent: np.ndarray
    depth: np.ndarray
    side: np.ndarray
    start: np.ndarray
    count: np.ndarray
    ok: np.ndarray


@dataclass
class Turns:
    """Per sequence position j: the sign of the turn s_{j-1} s_j s_{j+1} and whether it is a
    spike (a collinear turn back), at index j - 1; and ``twin[j]``, the other position of the
    same vertex (bridge ends) or -1."""

    turn: np.ndarray
    spike: np.ndarray
    twin: np.ndarray

    @classmethod
    def of(cls, sx: np.ndarray, sy: np.ndarray, twin: np.ndarray, exact: bool) -> Turns:
        px, py, vx, vy, nx, ny = sx[:-2], sy[:-2], sx[1:-1], sy[1:-1], sx[2:], sy[2:]
        turn = orient_items(px, py, vx, vy, nx, ny, exact)
        spike = (turn == 0) & ((nx - vx) * (px - vx) + (ny - vy) * (py - vy) > 0)
        return cls(turn, spike, twin)


def _apex_angle(
    sx: np.ndarray,
    sy: np.ndarray,
    turns: Turns,
    c: np.ndarray,
    tx: np.ndarray,
    ty: np.ndarray,
    exact: bool,
) -> np.ndarray:
    """``engine`` condition 4 for candidate positions ``c`` towards (tx, ty)."""
    px, py = sx[c - 1], sy[c - 1]
    vx, vy = sx[c], sy[c]
    nx, ny = sx[c + 1], sy[c + 1]
    turn = turns.turn[c - 1]
    after_next = orient_items(vx, vy, nx, ny, tx, ty, exact) >= 0
    after_prev = orient_items(px, py, vx, vy, tx, ty, exact) >= 0
    return np.where(
        turn > 0,
        after_next & after_prev,
        np.where(turn < 0, after_next | after_prev, after_next | turns.spike[c - 1]),
    )


# below this many table entries a round uses one table for all items
_ONE_TABLE = 1 << 16
# padded row widths of the sub-polygon vertex tables (rows pad with the position hi)
_WIDTHS = np.array([4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024])


def correct_mask(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    extent_x: np.ndarray,
    extent_y: np.ndarray,
    turns: Turns,
    exact: bool,
) -> np.ndarray:
    """Per test item: candidate position ``c`` forms a correct triangle on the base of the
    sub-polygon [lo, hi] (the engine's facing and correct-candidate conditions).

    ``extent_x``, ``extent_y``: per item, the extent of its polygon (bounds |p - q|).
    """
    ax, ay, bx, by = sx[hi], sy[hi], sx[lo], sy[lo]
    cx, cy = sx[c], sy[c]
    ok = orient_items(ax, ay, bx, by, cx, cy, exact) > 0
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return ok
    ok[idx] = _apex_angle(sx, sy, turns, c[idx], ax[idx], ay[idx], exact) & _apex_angle(
        sx, sy, turns, c[idx], bx[idx], by[idx], exact
    )
    idx = idx[ok[idx]]
    if len(idx) == 0:
        return ok
    # a 3-vertex sub-polygon has only its corners and its own sides: conditions 2 and 3 hold
    idx = idx[hi[idx] - lo[idx] > 2]
    size = hi[idx] - lo[idx] + 1
    widths = np.minimum(np.searchsorted(_WIDTHS, size), len(_WIDTHS) - 1)
    if 0 < len(idx) * int(size.max(initial=0)) <= _ONE_TABLE:
        widths[:] = widths.max()  # few items: one table, fewer numpy calls
    for k in np.unique(widths).tolist():
        rows = idx[widths == k]
        width = max(int(_WIDTHS[k]), int(size[widths == k].max()))
        bad = _bad_rows(
            sx, sy, lo[rows], hi[rows], c[rows], extent_x[rows], extent_y[rows], turns.twin,
            width, exact,
        )  # fmt: skip
        ok[rows[bad]] = False
    return ok


def _bad_rows(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    extent_x: np.ndarray,
    extent_y: np.ndarray,
    twin: np.ndarray,
    width: int,
    exact: bool,
) -> np.ndarray:
    """Conditions 2 and 3 of the correct triangle for items of one padded width.

    Tables are (width, items): column i holds the positions lo_i .. hi_i, padded with hi_i,
    so that per-item values broadcast along long contiguous rows.
    """
    n = len(lo)
    pos = np.arange(width, dtype=np.int64)[:, None] + lo
    np.minimum(pos, hi, out=pos)
    px, py = sx[pos], sy[pos]
    ax, ay, bx, by, cx, cy = sx[hi], sy[hi], sx[lo], sy[lo], sx[c], sy[c]
    last = hi - lo
    ccol = c - lo

    def bound(ux: np.ndarray, uy: np.ndarray) -> np.ndarray | None:
        return None if exact else row_bound(ux, uy, extent_x, extent_y)

    # entries known to be exactly zero: p at position lo (b), hi and the padding (a), c, and
    # the other occurrence (twin) of a corner inside the range: p is then a or b itself
    pad_count = int((width - last).sum())

    def twin_col(position: np.ndarray) -> np.ndarray:
        t = twin[position]
        return np.where((t > lo) & (t < hi), t - lo, -1)

    ta, tb, tc = twin_col(hi), twin_col(lo), twin_col(c)
    n_ta, n_tb, n_tc = int((ta >= 0).sum()), int((tb >= 0).sum()), int((tc >= 0).sum())
    dxa, dya = px - ax, py - ay
    pos_ab, _, _ = orient_rows(
        ax, ay, bx, by, px, py, dxa, dya, bound(bx - ax, by - ay), n + pad_count + n_ta + n_tb,
        lambda k, r: (k == 0) | (k >= last[r]) | (k == ta[r]) | (k == tb[r]),
    )  # fmt: skip
    # orient(a, c, p) = -orient(c, a, p), sharing p - a with the line a -> b
    _, pos_ca, zero_ca = orient_rows(
        ax, ay, cx, cy, px, py, dxa, dya, bound(cx - ax, cy - ay), n + pad_count + n_ta + n_tc,
        lambda k, r: (k == ccol[r]) | (k >= last[r]) | (k == ta[r]) | (k == tc[r]),
    )  # fmt: skip
    pos_bc, _, zero_bc = orient_rows(
        bx, by, cx, cy, px, py, px - bx, py - by, bound(cx - bx, cy - by), 2 * n + n_tb + n_tc,
        lambda k, r: (k == 0) | (k == ccol[r]) | (k == tb[r]) | (k == tc[r]),
    )  # fmt: skip
    bad = np.zeros(n, dtype=bool)
    # condition 3: a vertex in the relative interior of a new side (the known zeros are the
    # corners themselves)
    for (k, r), ux, uy in ((zero_bc, bx, by), (zero_ca, ax, ay)):
        if len(r):
            inside = strictly_between(px[k, r], py[k, r], ux[r], uy[r], cx[r], cy[r])
            bad[r[inside]] = True
    # condition 2: an edge meets the open triangle (the padding adds only point edges at a,
    # where f_ab is 0 at both ends: never inward)
    inward = pos_ab[:-1] | pos_ab[1:]
    inward &= pos_bc[:-1] | pos_bc[1:]
    inward &= pos_ca[:-1] | pos_ca[1:]
    flat = np.flatnonzero(inward)
    if len(flat):
        k, r = np.divmod(flat, n)
        ex0, ey0, ex1, ey1 = px[k, r], py[k, r], px[k + 1, r], py[k + 1, r]
        m = len(r)
        g = orient_items(
            np.tile(ex0, 3), np.tile(ey0, 3), np.tile(ex1, 3), np.tile(ey1, 3),
            np.concatenate([ax[r], bx[r], cx[r]]), np.concatenate([ay[r], by[r], cy[r]]),
            exact,
        ).reshape(3, m)  # fmt: skip
        lowest, highest = g.min(axis=0), g.max(axis=0)
        degenerate = (ex0 == ex1) & (ey0 == ey1)
        bad[r[((lowest < 0) & (highest > 0)) | degenerate]] = True
    return bad


def _chunked_correct(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    ext_x: np.ndarray,
    ext_y: np.ndarray,
    turns: Turns,
    exact: bool,
) -> np.ndarray:
    """:func:`correct_mask` in passes of bounded size."""
    n = len(c)
    if n == 0:
        return np.zeros(0, dtype=bool)
    work = np.cumsum(hi - lo + 1)
    if work[-1] <= _CHUNK_ELEMENTS:
        return correct_mask(sx, sy, lo, hi, c, ext_x, ext_y, turns, exact)
    out = np.empty(n, dtype=bool)
    cuts = np.searchsorted(work, np.arange(_CHUNK_ELEMENTS, work[-1], _CHUNK_ELEMENTS))
    bounds = np.unique(np.concatenate([[0], cuts, [n]]))
    for s, t in zip(bounds[:-1], bounds[1:]):
        out[s:t] = correct_mask(
            sx, sy, lo[s:t], hi[s:t], c[s:t], ext_x[s:t], ext_y[s:t], turns, exact
        )
    return out


def _choose_elevation(
    sz: np.ndarray, owner: np.ndarray, cand: np.ndarray, v1: np.ndarray, v2: np.ndarray
) -> np.ndarray:
    """``rules.ElevationRule.choose`` per owner: ``cand`` grouped by owner in candidate order;
    ``v1``, ``v2`` per owner. Returns the chosen position per owner."""
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    z1, z2 = sz[v1][owner[starts]], sz[v2][owner[starts]]
    group = np.cumsum(np.r_[False, owner[1:] != owner[:-1]])
    zc = sz[cand]
    approx = np.abs(2.0 * zc - z1[group] - z2[group])
    error = 8.0 * 2.0**-53 * (2.0 * np.abs(zc) + np.abs(z1[group]) + np.abs(z2[group])) + 1e-300
    top = np.minimum.reduceat(approx + error, starts)
    close = approx - error <= top[group]
    n = len(cand)
    first_close = np.minimum.reduceat(np.where(close, np.arange(n), n), starts)
    zmin = np.minimum.reduceat(np.where(close, zc, np.inf), starts)
    zmax = np.maximum.reduceat(np.where(close, zc, -np.inf), starts)
    chosen = cand[first_close]
    # near-ties between different z values: decided exactly as the rule does
    for g in np.flatnonzero(zmin != zmax).tolist():
        members = np.flatnonzero(close & (group == g))
        target = Fraction(float(z1[g])) + Fraction(float(z2[g]))
        exact = [abs(2 * Fraction(float(zc[i])) - target) for i in members]
        chosen[g] = cand[members[exact.index(min(exact))]]
    return chosen


def _extents(sx: np.ndarray, sy: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sequence: max - min of x and of y (bounds every coordinate difference in it)."""
    extent_x = np.maximum.reduceat(sx, starts) - np.minimum.reduceat(sx, starts)
    extent_y = np.maximum.reduceat(sy, starts) - np.minimum.reduceat(sy, starts)
    return extent_x, extent_y


def build_trees(
    ids: np.ndarray,
    twin: np.ndarray,
    sx: np.ndarray,
    sy: np.ndarray,
    sz: np.ndarray,
    seq_start: np.ndarray,
    seq_len: np.ndarray,
    mirrored: np.ndarray,
    exhaustive: bool,
) -> Trees:
    """BSP trees of sequences laid out with their closing repeat (length ``seq_len + 1``) at
    ``seq_start``; ``ids`` are the output vertex indices of every position, ``twin`` the other
    position of the same vertex or -1."""
    count = len(seq_start)
    # a sample that is not grid-exact rules out the whole (cheap for float data)
    exact = grid_exact(sx[:1024], sy[:1024]) and grid_exact(sx, sy)
    extent_x, extent_y = _extents(sx, sy, seq_start)
    turns = Turns.of(sx, sy, twin, exact)
    m = seq_len
    tri_count = np.maximum(m - 2, 0)
    tri_start = np.cumsum(tri_count) - tri_count
    total = int(tri_count.sum())
    triangles = np.zeros((total, 3), dtype=np.int64)
    parent = np.zeros(total, dtype=np.int64)
    depth = np.zeros(total, dtype=np.int64)
    side = np.zeros(total, dtype=np.int8)
    ok = np.ones(count, dtype=bool)
    # open nodes
    poly = np.flatnonzero(m >= 3)
    lo = seq_start[poly] + 1
    hi = seq_start[poly] + m[poly]
    at_hi = np.ones(len(poly), dtype=bool)
    pre = np.zeros(len(poly), dtype=np.int64)
    par = np.full(len(poly), -1, dtype=np.int64)
    dep = np.zeros(len(poly), dtype=np.int64)
    sd = np.zeros(len(poly), dtype=np.int8)
    cand = hi - 1
    while len(poly):
        if exhaustive:
            span = hi - lo - 1
            owner = np.repeat(np.arange(len(poly), dtype=np.int64), span)
            c = np.repeat(hi - 1, span) - ragged_index(np.zeros(len(poly), np.int64), span)
            po = poly[owner]
            good = _chunked_correct(
                sx, sy, lo[owner], hi[owner], c, extent_x[po], extent_y[po], turns, exact
            )
            found = np.bincount(owner[good], minlength=len(poly)) > 0
            apex = np.full(len(poly), -1, dtype=np.int64)
            if found.any():
                v1 = np.where(at_hi, hi, lo)
                v2 = np.where(at_hi, lo, hi)
                apex[found] = _choose_elevation(sz, owner[good], c[good], v1, v2)
            failed = ~found
        else:
            good = _chunked_correct(
                sx, sy, lo, hi, cand, extent_x[poly], extent_y[poly], turns, exact
            )
            found = good
            apex = cand
            failed = ~good & (cand - 1 <= lo)
        if failed.any():
            ok[poly[failed]] = False
        # emit triangles
        emit = np.flatnonzero(found & ok[poly])
        p, l_, h, a = poly[emit], lo[emit], hi[emit], apex[emit]
        row = tri_start[p] + pre[emit]
        mir = mirrored[p]
        triangles[row, 0] = np.where(mir, ids[l_], ids[h])
        triangles[row, 1] = np.where(mir, ids[h], ids[l_])
        triangles[row, 2] = ids[a]
        parent[row] = par[emit]
        depth[row] = dep[emit]
        side[row] = sd[emit]
        # children: upper (apex, hi, V1 at hi) and lower (lo, apex, V1 at lo)
        ah = at_hi[emit]
        left_lo = np.where(ah, a, l_)
        left_hi = np.where(ah, h, a)
        right_lo = np.where(ah, l_, a)
        right_hi = np.where(ah, a, h)
        left_size = left_hi - left_lo - 1
        has_left = left_size > 0
        has_right = right_hi - right_lo - 1 > 0
        node_pre = pre[emit]
        retry = np.flatnonzero(~found & ~failed & ok[poly]) if not exhaustive else np.zeros(0, int)
        parts = [
            (
                p[has_left],
                left_lo[has_left],
                left_hi[has_left],
                ah[has_left],
                node_pre[has_left] + 1,
                node_pre[has_left],
                dep[emit][has_left] + 1,
                1,
            ),
            (
                p[has_right],
                right_lo[has_right],
                right_hi[has_right],
                ~ah[has_right],
                node_pre[has_right] + 1 + left_size[has_right],
                node_pre[has_right],
                dep[emit][has_right] + 1,
                2,
            ),
        ]
        new_poly = [poly[retry]] + [q[0] for q in parts]
        new_lo = [lo[retry]] + [q[1] for q in parts]
        new_hi = [hi[retry]] + [q[2] for q in parts]
        new_at = [at_hi[retry]] + [q[3] for q in parts]
        new_pre = [pre[retry]] + [q[4] for q in parts]
        new_par = [par[retry]] + [q[5] for q in parts]
        new_dep = [dep[retry]] + [q[6] for q in parts]
        new_sd = [sd[retry]] + [np.full(len(q[0]), q[7], dtype=np.int8) for q in parts]
        new_cand = [cand[retry] - 1] + [q[2] - 1 for q in parts]
        poly = np.concatenate(new_poly)
        lo = np.concatenate(new_lo)
        hi = np.concatenate(new_hi)
        at_hi = np.concatenate(new_at)
        pre = np.concatenate(new_pre)
        par = np.concatenate(new_par)
        dep = np.concatenate(new_dep)
        sd = np.concatenate(new_sd)
        cand = np.concatenate(new_cand)
        live = ok[poly]
        if not live.all():
            poly, lo, hi, at_hi = poly[live], lo[live], hi[live], at_hi[live]
            pre, par, dep, sd, cand = pre[live], par[live], dep[live], sd[live], cand[live]
    return Trees(triangles, parent, depth, side, tri_start, tri_count, ok)
