"""Rule "first" on a long sub-polygon in one or two queries of the chain boxes.

A correct triangle's sides are diagonals, so its apex is visible from s_lo; conversely the
vertex visible from s_lo nearest in angle to the base (turning from s_lo -> s_hi into the
sub-polygon) forms a correct triangle, and the vertices visible from s_lo come in the
sequence's order as that angle grows. So the first correct candidate back from hi is that
vertex (docs/algorithm.md, section 4).

It is found in a triangle with a corner at s_lo, one side along the base's line and one
along an edge e that hides every point behind it within the triangle's angle: where hi - 1
lies strictly left of the base, e is the edge (hi - 1, hi) and the triangle the ear
(s_hi, s_lo, s_{hi-1}); where not, the ray on from s_lo through s_hi first meets the edge e
beyond s_hi, and the triangle's third corner is e's end left of the base. The apex is that
corner or, where vertices lie in the triangle in front of e, the one of least angle (the
nearest along a ray). A node whose candidates walk far back (a vertex next to s_lo hiding
most of the sub-polygon) is then a query instead of a walk. The apex found is checked as
every apex is, and a node where the reasoning may not hold (a point on the base's line or on
e, crossings too close to order, an apex that fails the check) is left to the full search.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from ..geometry.predicates import CCW_ERRBOUND, UNDERFLOW_SLACK
from ..geometry.spatial_index import ChainBoxes
from .one_by_one import edge_blocks, facing_one

Sign = Callable[[float, float, float, float, float, float], int]
Runs = list[tuple[int, int]]

# positions walked back from hi for the edge that crosses the base's line beyond s_hi
# (beyond them, the ray is looked up in the chain boxes)
_CROSSING_WALK = 256
_FAR = -2
# queries made at most for the nearest edge across that line beyond s_hi
_QUERIES = 4
# positions a query may return (see _runs_within), and what visible_apex returns past them
_MOST_POINTS = 256
WIDE = -3
# relative margin between two crossings' distances along the base's line (floats)
_MARGIN = 1e-9
# a crossing of the base's line surely beyond s_hi (at 1 in units of the base), surely
# before it (the base itself or behind s_lo); between the two the float is not trusted
_AHEAD = 1.0 + 1e-6
_BEHIND = 1.0 - 1e-6
# least sine of the angle between a crossing edge and the base's line (with the 1-norms in
# _along, a factor of 2 more) for its crossing's distance to be trusted to _MARGIN
_STEEP = 1e-5


def visible_apex(
    xs: list[float], ys: list[float], sign: Sign, boxes: ChainBoxes, lo: int, hi: int
) -> int | None:
    """The first correct candidate of sub-polygon [lo, hi] (rule "first"), or None where
    this test does not decide (the full search then does), or ``WIDE`` where a query holds
    more than ``_MOST_POINTS`` positions (the caller may stop asking: see ``_runs_within``)."""
    c = hi - 1
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    if sign(ax, ay, bx, by, xs[c], ys[c]) > 0:
        corners = (ax, ay, bx, by, xs[c], ys[c])
        runs = _runs_within(boxes.leaves_meeting(lo, hi, c, corners))
        if runs is None:
            return WIDE
        return _least_angle(xs, ys, sign, runs, lo, hi, c, c)
    found = _edge_beyond(xs, ys, sign, boxes, lo, hi)
    if found is None or found == WIDE:
        return found
    runs, edge, q = found
    return _least_angle(xs, ys, sign, runs, lo, hi, q, edge)


def _runs_within(leaves: Iterator[tuple[int, int]]) -> Runs | None:
    """The runs of a chain-box query, or None once they hold more than ``_MOST_POINTS``
    positions: the Python scans here cost about a microsecond a position, and a wide
    triangle full of the chain (a star's interior, say) is left to the search with the
    shadows, which skips whole boxes and stops at the first blocking edge."""
    runs: Runs = []
    total = 0
    for start, end in leaves:
        total += end - start
        if total > _MOST_POINTS:
            return None
        runs.append((start, end))
    return runs


def _edge_beyond(
    xs: list[float], ys: list[float], sign: Sign, boxes: ChainBoxes, lo: int, hi: int
) -> tuple[Runs, int, int] | int | None:
    """Where hi - 1 does not lie left of the base's line: the runs of the leaves meeting a
    triangle that holds the one bounded by the base's line, the ray s_lo -> s_q and the edge
    (e, e + 1) that the ray from s_lo through s_hi meets first beyond s_hi, with e and its
    end q left of the line. That edge comes from the chain back from hi where it crosses
    the line within ``_CROSSING_WALK`` positions, else from the chain boxes along the ray,
    and then the nearest crossing in the triangle so bounded. None where none is found, a
    vertex lies on the line there, or two crossings are too close to order."""
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    dx, dy = ax - bx, ay - by
    length2 = dx * dx + dy * dy
    if not 0.0 < length2 < float("inf"):
        return None
    k = _crossing_back(xs, ys, sign, lo, hi)
    if k >= 0:
        along = _along(xs, ys, k, dx, dy, bx, by, length2)
        if not along > _AHEAD:
            return None  # across the base or behind s_lo, or too near s_hi to tell
        edge, q = k, k
    elif k == _FAR:
        found = _ray_crossing(xs, ys, sign, boxes, lo, hi)
        if found is None or found == WIDE:
            return found
        edge, along = found
        q = _left_end(xs, ys, sign, lo, hi, edge)
    else:
        return None
    runs: Runs = []
    for _ in range(_QUERIES):
        reach = along * (1.0 + 1e-6) + 1e-9
        corners = (bx + reach * dx, by + reach * dy, bx, by, xs[q], ys[q])
        found_runs = _runs_within(boxes.leaves_meeting(lo, hi, q, corners))
        if found_runs is None:
            return WIDE
        runs = found_runs
        found = _nearest_crossing(xs, ys, sign, runs, lo, hi, edge, along)
        if found is None:
            return None
        nearest, at = found
        if nearest == edge:
            return runs, edge, q
        # the nearer edge's end left of the line; the runs serve where it lies in the
        # triangle queried (not beyond the ray to s_q, in front of the edge before)
        near_q = _left_end(xs, ys, sign, lo, hi, nearest)
        qx, qy, nx, ny = xs[q], ys[q], xs[near_q], ys[near_q]
        front = sign(xs[edge], ys[edge], xs[edge + 1], ys[edge + 1], bx, by)
        inside = sign(bx, by, qx, qy, nx, ny) >= 0
        if inside and front * sign(xs[edge], ys[edge], xs[edge + 1], ys[edge + 1], nx, ny) > 0:
            return runs, nearest, near_q
        edge, q, along = nearest, near_q, at
    return None


def _left_end(xs: list[float], ys: list[float], sign: Sign, lo: int, hi: int, e: int) -> int:
    """The end of the edge (e, e + 1), which crosses the base's line, left of it."""
    return e if sign(xs[hi], ys[hi], xs[lo], ys[lo], xs[e], ys[e]) > 0 else e + 1


def _ray_crossing(
    xs: list[float], ys: list[float], sign: Sign, boxes: ChainBoxes, lo: int, hi: int
) -> tuple[int, float] | int | None:
    """The edge that the ray from s_lo through s_hi meets first beyond s_hi and where (as
    :func:`_nearest_crossing`), found among the chain boxes along ever longer stretches of
    the ray (4 times as long each, to the chain's extent); None if there is none or it is
    not sure."""
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    dx, dy = ax - bx, ay - by
    x0, x1, y0, y1 = boxes.levels[-1][0][:4]
    far = max(abs(x0 - bx), abs(x1 - bx)) + max(abs(y0 - by), abs(y1 - by))
    most = 2.0 * far / max(abs(dx), abs(dy))
    reach = 2.0
    while True:
        x, y = bx + reach * dx, by + reach * dy
        runs = _runs_within(boxes.leaves_meeting(lo, hi, hi, (x, y, bx, by, x, y)))
        if runs is None:
            return WIDE
        found = _nearest_crossing(xs, ys, sign, runs, lo, hi, -1, reach)
        if found is None or found[0] >= 0:
            return found
        if reach > most:
            return None
        reach *= 4.0


def _crossing_back(xs: list[float], ys: list[float], sign: Sign, lo: int, hi: int) -> int:
    """The first position k back from hi - 1 left of the base's line (the chain back from hi
    right of it up to there), within ``_CROSSING_WALK`` positions; -1 if a position on the
    line comes first, ``_FAR`` if none is within the walk."""
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    for k in range(hi - 1, max(hi - 1 - _CROSSING_WALK, lo), -1):
        px, py = xs[k], ys[k]
        left, right = (ax - px) * (by - py), (ay - py) * (bx - px)
        det = left - right
        if det < -(CCW_ERRBOUND * (abs(left) + abs(right)) + UNDERFLOW_SLACK):
            continue
        side = sign(ax, ay, bx, by, px, py)
        if side > 0:
            return k
        if side == 0:
            return -1
    return _FAR


def _nearest_crossing(
    xs: list[float],
    ys: list[float],
    sign: Sign,
    runs: Runs,
    lo: int,
    hi: int,
    edge: int,
    along: float,
) -> tuple[int, float] | None:
    """Of the edges of the ``runs`` that cross the base's line beyond s_hi, the one met
    first from s_hi (``edge`` at ``along`` to begin with; -1: none nearer than ``along``)
    and where; None if a vertex lies on the line beyond s_hi no farther, or two crossings
    are too close to order (the two copies of a bridge count once)."""
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    dx, dy = ax - bx, ay - by
    length2 = dx * dx + dy * dy
    nearest, nearest_along, close = edge, along, False
    for start, end in runs:
        for e in range(max(start, lo + 1), min(end, hi - 1)):
            px, py, qx, qy = xs[e], ys[e], xs[e + 1], ys[e + 1]
            left, right = (ax - px) * (by - py), (ay - py) * (bx - px)
            first = left - right
            if abs(first) > CCW_ERRBOUND * (abs(left) + abs(right)) + UNDERFLOW_SLACK:
                left, right = (ax - qx) * (by - qy), (ay - qy) * (bx - qx)
                second = left - right
                sure = abs(second) > CCW_ERRBOUND * (abs(left) + abs(right)) + UNDERFLOW_SLACK
                if sure and (first > 0) == (second > 0):
                    continue  # both ends surely on one side
            first, second = sign(ax, ay, bx, by, px, py), sign(ax, ay, bx, by, qx, qy)
            if first * second > 0:
                continue
            if first == 0 or second == 0:
                # a vertex on the line: beyond s_hi and no farther it is met first
                for end_x, end_y, on in ((px, py, first), (qx, qy, second)):
                    if on == 0:
                        at = (dx * (end_x - bx) + dy * (end_y - by)) / length2
                        if not at < _BEHIND and not at > nearest_along * (1.0 + 1e-6) + 1e-9:
                            return None
                continue
            if e == nearest:
                continue
            at = _along(xs, ys, e, dx, dy, bx, by, length2)
            if at < _BEHIND:
                continue
            if not at > _AHEAD:
                return None
            if abs(at - nearest_along) <= _MARGIN * nearest_along:
                n = nearest
                twin = n >= 0 and (px, py, qx, qy) == (xs[n + 1], ys[n + 1], xs[n], ys[n])
                close = close or not twin
            elif at < nearest_along:
                nearest, nearest_along, close = e, at, False
    return None if close else (nearest, nearest_along)


def _along(
    xs: list[float],
    ys: list[float],
    e: int,
    dx: float,
    dy: float,
    bx: float,
    by: float,
    length2: float,
) -> float:
    """Where the edge (e, e + 1), whose ends lie strictly on either side of the line from
    s_lo along (dx, dy), crosses it: its distance from s_lo in units of (dx, dy) (s_hi at 1;
    nan where the float intersection is not trusted)."""
    px, py, qx, qy = xs[e], ys[e], xs[e + 1], ys[e + 1]
    fp = dx * (py - by) - dy * (px - bx)
    fq = dx * (qy - by) - dy * (qx - bx)
    # an edge nearly along the line crosses it where rounding moves the point far: about
    # 4 eps / sin(angle) of the distance; kept only where that is far below _MARGIN
    span = abs(dx * (qy - py) - dy * (qx - px))
    if not span > _STEEP * (abs(dx) + abs(dy)) * (abs(qx - px) + abs(qy - py)):
        return float("nan")
    t = fp / (fp - fq)
    x, y = px + t * (qx - px), py + t * (qy - py)
    return (dx * (x - bx) + dy * (y - by)) / length2


def _least_angle(
    xs: list[float],
    ys: list[float],
    sign: Sign,
    runs: Runs,
    lo: int,
    hi: int,
    q: int,
    edge: int,
) -> int | None:
    """The apex among q and the points of the runs in the triangle bounded by the base's
    line, the ray s_lo -> s_q and the edge (edge, edge + 1) (the hiding edge, q its end left
    of the base): the one of least angle at s_lo (nearest along a ray), checked.

    Another occurrence of a corner's point (a bridge end's twin) is no apex. An edge from
    it may cross the triangle with no vertex in it (a bridge from s_hi's point over the
    ear) and hide the vertex of least angle: that vertex's triangle then fails the check
    (every edge that could break it is in the runs), and the full search decides. Where the
    vertex of least angle passes, it is visible from s_lo, and every vertex visible at a
    smaller angle would lie in the triangle too: it is the apex."""
    ax, ay, bx, by, qx, qy = xs[hi], ys[hi], xs[lo], ys[lo], xs[q], ys[q]
    ex, ey, fx, fy = xs[edge], ys[edge], xs[edge + 1], ys[edge + 1]
    # s_lo's side of the hiding edge's line (not 0: s_q lies left of the base's line)
    front = sign(ex, ey, fx, fy, bx, by)
    if front == 0:
        return None
    best: list[int] = []  # the positions at the point of least angle found so far
    at_q: list[int] = [q]
    px = py = 0.0
    for start, end in runs:
        for p in range(max(start, lo + 1), min(end, hi)):
            vx, vy = xs[p], ys[p]
            # beyond the ray s_lo -> s_q (strictly right of it): out
            left, right = (bx - vx) * (qy - vy), (by - vy) * (qx - vx)
            det = left - right
            if det < -(CCW_ERRBOUND * (abs(left) + abs(right)) + UNDERFLOW_SLACK):
                continue
            if vx == qx and vy == qy:
                if p != q:
                    at_q.append(p)
                continue
            if (vx == bx and vy == by) or (vx == ax and vy == ay):
                continue
            if sign(bx, by, qx, qy, vx, vy) < 0:
                continue
            base = sign(ax, ay, bx, by, vx, vy)
            if base < 0:
                continue
            hiding = sign(ex, ey, fx, fy, vx, vy)
            if hiding * front < 0:
                continue  # behind the hiding edge
            if base == 0 or hiding == 0:
                return None
            if not best:
                best, px, py = [p], vx, vy
                continue
            if vx == px and vy == py:
                best.append(p)
                continue
            turn = sign(bx, by, vx, vy, px, py)
            if turn < 0 or (turn == 0 and _nearer(vx, vy, px, py, bx, by)):
                best, px, py = [p], vx, vy
    if not best:
        best = at_q
    # at a bridge end's point, the position whose corner faces the base (the last first);
    # its triangle lies in the one queried, whose runs hold every edge that could break it
    for p in sorted(best, reverse=True):
        if facing_one(xs, ys, lo, hi, p):
            return p if _clear(xs, ys, sign, runs, lo, hi, p) else None
    return None


def _nearer(px: float, py: float, qx: float, qy: float, ox: float, oy: float) -> bool:
    """Of two distinct points on one ray from o, p is the nearer to o (exact comparisons)."""
    if px != qx:
        return (px < qx) == (qx > ox)
    return (py < qy) == (qy > oy)


def _clear(
    xs: list[float], ys: list[float], sign: Sign, runs: Runs, lo: int, hi: int, c: int
) -> bool:
    """No edge of the ``runs`` breaks condition 2 or 3 for the triangle (s_hi, s_lo, s_c)."""
    corners = (xs[hi], ys[hi], xs[lo], ys[lo], xs[c], ys[c])
    xmin, xmax = min(corners[0::2]), max(corners[0::2])
    ymin, ymax = min(corners[1::2]), max(corners[1::2])
    for start, end in runs:
        for e in range(start, end):
            px, qx, py, qy = xs[e], xs[e + 1], ys[e], ys[e + 1]
            if (px < xmin and qx < xmin) or (px > xmax and qx > xmax):
                continue
            if (py < ymin and qy < ymin) or (py > ymax and qy > ymax):
                continue
            if edge_blocks(corners, xmin, ymin, xmax, ymax, xs, ys, e, sign):
                return False
    return True
