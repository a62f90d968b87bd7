"""Exact geometric sign tests on float64 coordinates.

Every test is a float64 evaluation with a static error bound (Shewchuk's ``ccwerrboundA``);
results within the bound are re-decided with exact rational arithmetic on the doubles' exact
values, so no result depends on rounding.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

_EPS = 2.0**-53
CCW_ERRBOUND = (3.0 + 16.0 * _EPS) * _EPS
# Absolute slack for products that underflow into the subnormal range.
_UNDERFLOW_SLACK = 1e-300


def orient_exact(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """Sign of the orientation determinant of (a, b, c), computed exactly."""
    fcx, fcy = Fraction(cx), Fraction(cy)
    det = (Fraction(ax) - fcx) * (Fraction(by) - fcy) - (Fraction(ay) - fcy) * (Fraction(bx) - fcx)
    return (det > 0) - (det < 0)


def orient(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """+1 if c lies left of the line a->b, -1 if right, 0 if on it (exact)."""
    detleft = (ax - cx) * (by - cy)
    detright = (ay - cy) * (bx - cx)
    det = detleft - detright
    bound = CCW_ERRBOUND * (abs(detleft) + abs(detright)) + _UNDERFLOW_SLACK
    if det > bound:
        return 1
    if -det > bound:
        return -1
    return orient_exact(ax, ay, bx, by, cx, cy)


def orient_many(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
) -> np.ndarray:
    """Vectorised :func:`orient` with numpy broadcasting; returns int8 signs."""
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        detleft = (ax - cx) * (by - cy)
        detright = (ay - cy) * (bx - cx)
        det = detleft - detright
        bound = CCW_ERRBOUND * (np.abs(detleft) + np.abs(detright)) + _UNDERFLOW_SLACK
        sure = np.abs(det) > bound
    signs = np.sign(det).astype(np.int8)
    if not sure.all():
        unsure = np.nonzero(~sure)
        arrays = np.broadcast_arrays(ax, ay, bx, by, cx, cy)
        picked = [a[unsure].tolist() for a in arrays]
        signs[unsure] = [orient_exact(*point) for point in zip(*picked)]
    return signs


def strictly_between(
    px: np.ndarray, py: np.ndarray, ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray
) -> np.ndarray:
    """For p collinear with a and b: p lies in the relative interior of segment ab (exact)."""
    inside_box = (
        (px >= np.minimum(ax, bx))
        & (px <= np.maximum(ax, bx))
        & (py >= np.minimum(ay, by))
        & (py <= np.maximum(ay, by))
    )
    at_a = (px == ax) & (py == ay)
    at_b = (px == bx) & (py == by)
    return inside_box & ~at_a & ~at_b


def exact_sq_distance(ax: float, ay: float, bx: float, by: float) -> Fraction:
    """Exact squared distance between two float points."""
    dx = Fraction(ax) - Fraction(bx)
    dy = Fraction(ay) - Fraction(by)
    return dx * dx + dy * dy


def _as_int_scaled(values: list[float]) -> tuple[list[int], int]:
    """Exact integers n_i and a shift s with values[i] == n_i * 2**-s."""
    ratios = [v.as_integer_ratio() for v in values]
    shift = max((d.bit_length() - 1 for _, d in ratios), default=0)
    return [n << (shift - (d.bit_length() - 1)) for n, d in ratios], shift


def ring_area_sign(x: np.ndarray, y: np.ndarray) -> int:
    """Exact sign of the signed (shoelace) area of the closed ring (x[i], y[i])."""
    if len(x) < 3:
        return 0
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        left = x * yn
        right = xn * y
        total = float(np.sum(left - right))
        magnitude = float(np.sum(np.abs(left) + np.abs(right)))
    bound = magnitude * (len(x) + 4) * 2.0 * _EPS + _UNDERFLOW_SLACK * len(x)
    if np.isfinite(total) and np.isfinite(bound) and abs(total) > bound:
        return 1 if total > 0 else -1
    xi, sx = _as_int_scaled(x.tolist())
    yi, sy = _as_int_scaled(y.tolist())
    del sx, sy  # a common positive scale does not change the sign
    n = len(xi)
    twice_area = sum(xi[i] * yi[(i + 1) % n] - xi[(i + 1) % n] * yi[i] for i in range(n))
    return (twice_area > 0) - (twice_area < 0)
