"""Exact orientation signs for the batch path, fast where the float result is clear.

A point p against the line through a and b (one line per row, many points per row) is
evaluated as Shewchuk's orient2d(b, p, a) = (bx - ax)(py - ay) - (by - ay)(px - ax), which
has the same sign as orient(a, b, p). Its rounding error is at most
``CCW_ERRBOUND * (|l| + |r|)`` (l, r the two products); this module uses a per-row bound of
that from the extent of the points, so only (nearly) collinear points are re-decided, by
``predicates.orient_many``, which is exact.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .predicates import CCW_ERRBOUND, UNDERFLOW_SLACK, orient_many

_EPS = 2.0**-53
# |fl(p - a)| <= (1 + eps) |p - a|, the extents and the bound itself are rounded: margin
_BOUND_FACTOR = CCW_ERRBOUND * (1.0 + 32.0 * _EPS)


def row_bound(ux: np.ndarray, uy: np.ndarray, width: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Error bound per row for points whose |p - a| is at most (width, height) per axis."""
    return _BOUND_FACTOR * (np.abs(ux) * height + np.abs(uy) * width) + UNDERFLOW_SLACK


def orient_rows(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
    bound: np.ndarray | None,
    known_count: int,
    known_zero: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Exact orient(a, b, p) > 0 and < 0 masks, with ``a``, ``b``, ``bound`` (one per row)
    broadcast against the 2D ``p``; and the (rows, cols) of the zero signs other than the
    known ones.

    ``dx``, ``dy`` are ``px - ax``, ``py - ay`` (shared between lines through a).
    ``bound`` None means the coordinates are grid-exact (every float result is exact).
    ``known_zero(rows, cols)`` marks the ``known_count`` entries that the caller knows to be
    exactly 0 (p is a or b itself: the float result is then exactly 0 too).
    """
    det = (bx - ax) * dy
    det -= (by - ay) * dx
    if bound is None:
        positive = det > 0
        negative = det < 0
    else:
        positive = det > bound
        negative = det < -bound
    if det.size - np.count_nonzero(positive) - np.count_nonzero(negative) == known_count:
        return positive, negative, _NONE
    where = np.nonzero(~(positive | negative))
    keep = ~known_zero(*where)
    where = (where[0][keep], where[1][keep])
    if bound is None or len(where[0]) == 0:
        return positive, negative, where
    shape = det.shape
    pxu = np.broadcast_to(px, shape)[where]
    pyu = np.broadcast_to(py, shape)[where]
    axu = np.broadcast_to(ax, shape)[where]
    ayu = np.broadcast_to(ay, shape)[where]
    bxu = np.broadcast_to(bx, shape)[where]
    byu = np.broadcast_to(by, shape)[where]
    # a point equal to a or b (another occurrence of it) lies on the line: exact zero
    at_end = ((pxu == axu) & (pyu == ayu)) | ((pxu == bxu) & (pyu == byu))
    rest = np.flatnonzero(~at_end)
    if len(rest):
        values = np.zeros(len(pxu), dtype=np.int8)
        values[rest] = orient_many(axu[rest], ayu[rest], bxu[rest], byu[rest], pxu[rest], pyu[rest])
        positive[where] = values > 0
        negative[where] = values < 0
        still = values == 0
        where = (where[0][still], where[1][still])
    return positive, negative, where


_NONE = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))


def crossing(
    o1: np.ndarray,
    o2: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
    exact: bool = False,
) -> np.ndarray:
    """Per item: the segments ab and uv cross at a point inside both, given ``o1`` and
    ``o2``, the exact signs of a and of b against the line u -> v (exact)."""
    cross = np.zeros(len(o1), dtype=bool)
    s = np.flatnonzero((o1.astype(np.int16) * o2) < 0)
    if len(s):
        o3 = orient_items(ax[s], ay[s], bx[s], by[s], ux[s], uy[s], exact)
        o4 = orient_items(ax[s], ay[s], bx[s], by[s], vx[s], vy[s], exact)
        cross[s] = (o3.astype(np.int16) * o4) < 0
    return cross


def sure_signs(
    ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray, px: np.ndarray, py: np.ndarray
) -> np.ndarray:
    """int8 signs of orient(a, b, p) for 1D arrays where the float value is beyond its error
    bound, and 0 where it is not (then the exact sign may be any)."""
    left = (bx - ax) * (py - ay)
    right = (by - ay) * (px - ax)
    det = left - right
    bound = CCW_ERRBOUND * (np.abs(left) + np.abs(right)) + UNDERFLOW_SLACK
    return (det > bound).view(np.int8) - (det < -bound).view(np.int8)


def orient_items(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    exact: bool = False,
) -> np.ndarray:
    """int8 signs of orient(a, b, p) for 1D arrays (exact; ``exact`` as in ``orient_rows``).

    Cheaper than ``predicates.orient_many`` where many points coincide with a or b.
    """
    if exact:
        return np.sign((bx - ax) * (py - ay) - (by - ay) * (px - ax)).astype(np.int8)
    signs = sure_signs(ax, ay, bx, by, px, py)
    where = np.flatnonzero(signs == 0)
    if len(where) == 0:
        return signs
    pxu, pyu, axu, ayu, bxu, byu = px[where], py[where], ax[where], ay[where], bx[where], by[where]
    at_end = ((pxu == axu) & (pyu == ayu)) | ((pxu == bxu) & (pyu == byu))
    rest = np.flatnonzero(~at_end)
    if len(rest):
        signs[where[rest]] = orient_many(
            axu[rest], ayu[rest], bxu[rest], byu[rest], pxu[rest], pyu[rest]
        )
    return signs
