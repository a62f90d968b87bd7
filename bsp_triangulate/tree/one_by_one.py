"""The correct-triangle conditions (docs/algorithm.md, section 4) for one candidate in
Python scalars, and the subtrees of small sub-polygons built with them one node at a time
(rule "first"): where only a few sub-polygons are left, a Python step per node costs less
than a round of numpy calls of the lock-step builder."""

from __future__ import annotations

from collections.abc import Callable

from ..geometry.predicates import (
    CCW_ERRBOUND,
    UNDERFLOW_SLACK,
    orient,
    orient_float,
    strictly_between_one,
)


def facing_one(xs: list[float], ys: list[float], lo: int, hi: int, c: int) -> bool:
    """Scalar :func:`facing_candidates` for the one candidate position ``c`` (Python lists)."""
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    cx, cy = xs[c], ys[c]
    if orient(ax, ay, bx, by, cx, cy) <= 0:
        return False
    px, py, nx, ny = xs[c - 1], ys[c - 1], xs[c + 1], ys[c + 1]
    turn = orient(px, py, cx, cy, nx, ny)
    spike = turn == 0 and (nx - cx) * (px - cx) + (ny - cy) * (py - cy) > 0
    for tx, ty in ((ax, ay), (bx, by)):
        after_next = orient(cx, cy, nx, ny, tx, ty) >= 0
        after_prev = orient(px, py, cx, cy, tx, ty) >= 0
        if turn > 0:
            inside = after_next and after_prev
        elif turn < 0:
            inside = after_next or after_prev
        else:
            inside = after_next or spike
        if not inside:
            return False
    return True


def pair_fails(
    corners: tuple[float, float, float, float, float, float],
    px: float,
    py: float,
    qx: float,
    qy: float,
    sign: Callable[[float, float, float, float, float, float], int] = orient,
) -> bool:
    """Scalar :func:`pairs_failing` for one triangle ``corners`` = (ax, ay, bx, by, cx, cy)
    (base a -> b, apex c, counter-clockwise) and one edge p-q: the edge breaks condition 2
    or 3. ``sign`` is :func:`orient`, or :func:`orient_float` for grid-exact coordinates."""
    ax, ay, bx, by, cx, cy = corners
    # most edges tested against a correct triangle start at one of its corners (the edges of
    # the sub-polygon next to them): decided by the other end alone where that is off the
    # corner's two sides
    if (px == ax and py == ay) or (px == bx and py == by) or (px == cx and py == cy):
        if not ((qx == ax and qy == ay) or (qx == bx and qy == by) or (qx == cx and qy == cy)):
            inside = _from_corner(corners, px, py, qx, qy, sign)
            if inside is not None:
                return inside
    elif (qx == ax and qy == ay) or (qx == bx and qy == by) or (qx == cx and qy == cy):
        inside = _from_corner(corners, qx, qy, px, py, sign)
        if inside is not None:
            return inside
    fp1, fq1 = sign(bx, by, cx, cy, px, py), sign(bx, by, cx, cy, qx, qy)
    # both ends strictly outside side b-c: neither on a new side nor inside (T is ccw)
    if fp1 < 0 and fq1 < 0:
        return False
    fp2, fq2 = sign(cx, cy, ax, ay, px, py), sign(cx, cy, ax, ay, qx, qy)
    if fp2 < 0 and fq2 < 0:
        return False
    # condition 3: a vertex in the relative interior of a new side
    for f1, f2, ux, uy in ((fp1, fp2, px, py), (fq1, fq2, qx, qy)):
        if f1 == 0 and strictly_between_one(ux, uy, bx, by, cx, cy):
            return True
        if f2 == 0 and strictly_between_one(ux, uy, ax, ay, cx, cy):
            return True
    # condition 2: separating-axis test
    if max(fp1, fq1) <= 0 or max(fp2, fq2) <= 0:
        return False
    if sign(ax, ay, bx, by, px, py) <= 0 and sign(ax, ay, bx, by, qx, qy) <= 0:
        return False
    if px == qx and py == qy:
        return True
    g = (
        sign(px, py, qx, qy, ax, ay),
        sign(px, py, qx, qy, bx, by),
        sign(px, py, qx, qy, cx, cy),
    )
    return min(g) < 0 < max(g)


def _from_corner(
    corners: tuple[float, float, float, float, float, float],
    ux: float,
    uy: float,
    vx: float,
    vy: float,
    sign: Callable[[float, float, float, float, float, float], int],
) -> bool | None:
    """:func:`pair_fails` of an edge from the corner u of the counter-clockwise triangle
    ``corners`` to a point v at no corner: it breaks condition 2 or 3 exactly when v lies
    strictly inside the corner's angle (strictly left of both sides at u: the edge then
    enters the open triangle), and neither where v lies strictly right of one of them (no
    point of the edge but u is then in the closed triangle). None where v lies on the line
    of one of those sides, or u is at two corners (a degenerate triangle)."""
    ax, ay, bx, by, cx, cy = corners
    at_a = ux == ax and uy == ay
    at_b = ux == bx and uy == by
    if at_a and not at_b:
        if ux == cx and uy == cy:
            return None
        first, second = sign(ax, ay, bx, by, vx, vy), sign(cx, cy, ax, ay, vx, vy)
    elif at_b and not at_a:
        if ux == cx and uy == cy:
            return None
        first, second = sign(ax, ay, bx, by, vx, vy), sign(bx, by, cx, cy, vx, vy)
    elif not at_a:
        first, second = sign(bx, by, cx, cy, vx, vy), sign(cx, cy, ax, ay, vx, vy)
    else:
        return None
    if first == 0 or second == 0:
        return None
    return first > 0 and second > 0


def edge_blocks(
    corners: tuple[float, float, float, float, float, float],
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
    xs: list[float],
    ys: list[float],
    e: int,
    sign: Callable[[float, float, float, float, float, float], int],
) -> bool:
    """Edge (e, e + 1) breaks condition 2 or 3 for the triangle ``corners`` (whose bounding
    box is given: an edge whose box misses it cannot touch the triangle)."""
    px, py, qx, qy = xs[e], ys[e], xs[e + 1], ys[e + 1]
    if (px < xmin and qx < xmin) or (px > xmax and qx > xmax):
        return False
    if (py < ymin and qy < ymin) or (py > ymax and qy > ymax):
        return False
    # both ends surely strictly right of the side b -> c (float orientations beyond
    # orient's static bound, the exact sign): pair_fails' first test, without its calls
    _, _, bx, by, cx, cy = corners
    left, right = (bx - px) * (cy - py), (by - py) * (cx - px)
    if left - right < -(CCW_ERRBOUND * (abs(left) + abs(right)) + UNDERFLOW_SLACK):
        left, right = (bx - qx) * (cy - qy), (by - qy) * (cx - qx)
        if left - right < -(CCW_ERRBOUND * (abs(left) + abs(right)) + UNDERFLOW_SLACK):
            return False
    return pair_fails(corners, px, py, qx, qy, sign)


def first_correct(
    xs: list[float],
    ys: list[float],
    lo: int,
    hi: int,
    top: int,
    sign: Callable[[float, float, float, float, float, float], int],
    blockers: list[int],
    budget: list[int],
    runs: tuple[list[int], list[int]] | None = None,
) -> int:
    """The first of the candidates ``top``, ``top`` - 1, ... of sub-polygon [lo, hi] that
    forms a correct triangle on the base (hi, lo), or -1; each tested against every edge of
    the sub-polygon, the ``blockers`` (edges that blocked earlier candidates, the most recent
    first) before the others. Each candidate tested against every edge takes hi - lo from
    ``budget[0]``; -2 once it is spent. ``runs``: per position, the first position at or
    after it and the last at or before it where the sequence bends (``lockstep``'s
    ``straight_runs``): candidates in a straight run on from either corner of the base fail
    condition 3 (the corner's neighbour lies on their side) and are skipped."""
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    low, first = (lo + 1, hi - 1) if runs is None else run_bounds(runs, lo, hi)
    for c in range(top, lo, -1):
        if first <= c < hi - 1 or lo + 1 < c <= low:
            continue
        if not facing_one(xs, ys, lo, hi, c):
            continue
        cx, cy = xs[c], ys[c]
        corners = (ax, ay, bx, by, cx, cy)
        xmin, xmax = min(ax, bx, cx), max(ax, bx, cx)
        ymin, ymax = min(ay, by, cy), max(ay, by, cy)
        blocked = False
        for e in blockers:
            if lo <= e < hi and edge_blocks(corners, xmin, ymin, xmax, ymax, xs, ys, e, sign):
                blocked = True
                break
        if blocked:
            continue
        budget[0] -= hi - lo
        if budget[0] < 0:
            return -2
        for e in range(lo, hi):
            if edge_blocks(corners, xmin, ymin, xmax, ymax, xs, ys, e, sign):
                blockers.insert(0, e)
                del blockers[_BLOCKERS:]
                break
        else:
            return c
    return -1


def run_bounds(runs: tuple[list[int], list[int]], lo: int, hi: int) -> tuple[int, int]:
    """(low, top) for the base (hi, lo), from ``runs`` (per position, the first position at
    or after it and the last at or before it where the sequence bends): lo .. low and
    top .. hi each lie in order on one line. A candidate c with lo + 1 < c <= low has lo + 1
    in the relative interior of its side lo -> c, one with top <= c < hi - 1 has hi - 1 in
    that of its side hi -> c: both fail condition 3. (lo + 1, hi - 1) where no run is
    longer."""
    return min(runs[0][lo + 1], hi - 1), max(runs[1][hi - 1], lo + 1)


# edges remembered per subtree as likely blockers
_BLOCKERS = 8


# an open node: (lo, hi, top, at_hi, parent, depth, side)
Work = tuple[int, int, int, bool, int, int, int]


def first_nodes(
    xs: list[float],
    ys: list[float],
    lo: int,
    hi: int,
    top: int,
    at_hi: bool,
    exact: bool,
    budget: int,
    runs: tuple[list[int], list[int]] | None = None,
) -> tuple[list[tuple[int, int, int, int, int, int]], list[Work]]:
    """Rule "first": the BSP subtree of sub-polygon [lo, hi] of the sequence ``xs``, ``ys``
    (positions in Python lists; the root's candidates from ``top`` down, those above it
    rejected already; its V1 at hi where ``at_hi``), in pre-order: per node (lo, hi, apex,
    parent, depth, side), parent the index of the parent's node in the list (-1 at the
    root), depth from the root's 0, side 0 at the root, else 1 (left) or 2 (right); and the
    work left, none where the subtree is complete. Where a node finds no correct candidate,
    or after ``budget`` edge tests (a sub-polygon whose nodes reject many candidates each is
    left to the vectorised tables), the nodes found so far come with the open nodes (lo, hi,
    top, at_hi, parent, depth, side), the next one to build last: building them in that
    order continues the pre-order. ``exact``: every float orientation of the coordinates is
    exact (grid coordinates); ``runs``: see :func:`first_correct`."""
    sign = orient_float if exact else orient
    nodes: list[tuple[int, int, int, int, int, int]] = []
    blockers: list[int] = []
    remaining = [budget]
    work: list[Work] = [(lo, hi, top, at_hi, -1, 0, 0)]
    while work:
        lo, hi, top, at_hi, parent, depth, side = item = work.pop()
        apex = first_correct(xs, ys, lo, hi, top, sign, blockers, remaining, runs)
        if apex < 0:
            work.append(item)
            return nodes, work
        here = len(nodes)
        nodes.append((lo, hi, apex, parent, depth, side))
        # the left child (base V1 V3) comes first in pre-order: pushed last
        upper, lower = (apex, hi, True), (lo, apex, False)
        left, right = (upper, lower) if at_hi else (lower, upper)
        for (clo, chi, flag), child_side in ((right, 2), (left, 1)):
            if chi - clo > 1:
                work.append((clo, chi, chi - 1, flag, here, depth + 1, child_side))
    return nodes, work
