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
UNDERFLOW_SLACK = 1e-300


def orient_exact(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """Sign of the orientation determinant of (a, b, c), computed exactly (Python integers)."""
    ratios = [v.as_integer_ratio() for v in (ax, ay, bx, by, cx, cy)]
    shift = max(den.bit_length() for _, den in ratios)
    n = [num << (shift - den.bit_length()) for num, den in ratios]
    det = (n[0] - n[4]) * (n[3] - n[5]) - (n[1] - n[5]) * (n[2] - n[4])
    return (det > 0) - (det < 0)


_SPLITTER = 134217729.0  # 2**27 + 1


def _diff_error(a: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Rounding error of x = fl(a - b) (Knuth's two-sum)."""
    bvirt = a - x
    avirt = x + bvirt
    return (a - avirt) + (bvirt - b)


def sum_error(
    a: np.ndarray | float, b: np.ndarray | float, x: np.ndarray | float
) -> np.ndarray | float:
    """Rounding error of x = fl(a + b): a + b - x exactly (arrays or floats)."""
    return _diff_error(a, -b, x)


def _product_error(a: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Rounding error of x = fl(a * b) (Dekker's two-product)."""
    c = _SPLITTER * a
    ahi = c - (c - a)
    alo = a - ahi
    c = _SPLITTER * b
    bhi = c - (c - b)
    blo = b - bhi
    return alo * blo - (((x - ahi * bhi) - alo * bhi) - ahi * blo)


def _exactly_computed(ax, ay, bx, by, cx, cy) -> tuple[np.ndarray, np.ndarray]:
    """Float orientation determinants and a mask of those computed without any rounding."""
    d1, d2, d3, d4 = ax - cx, by - cy, ay - cy, bx - cx
    left, right = d1 * d2, d3 * d4
    det = left - right
    exact = (
        (_diff_error(ax, cx, d1) == 0)
        & (_diff_error(by, cy, d2) == 0)
        & (_diff_error(ay, cy, d3) == 0)
        & (_diff_error(bx, cx, d4) == 0)
        & (_product_error(d1, d2, left) == 0)
        & (_product_error(d3, d4, right) == 0)
        & (_diff_error(left, right, det) == 0)
        & np.isfinite(det)
        & (np.abs(left) + np.abs(right) > 1e-290)
    )
    exact |= (d1 == 0) & (d3 == 0) | (d2 == 0) & (d4 == 0)  # a == c or b == c in a coordinate
    return det, exact


def orient(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """+1 if c lies left of the line a->b, -1 if right, 0 if on it (exact)."""
    detleft = (ax - cx) * (by - cy)
    detright = (ay - cy) * (bx - cx)
    det = detleft - detright
    bound = CCW_ERRBOUND * (abs(detleft) + abs(detright)) + UNDERFLOW_SLACK
    if det > bound:
        return 1
    if -det > bound:
        return -1
    if (ax == cx or by == cy) and (ay == cy or bx == cx):
        return 0  # both products are exactly zero
    return orient_exact(ax, ay, bx, by, cx, cy)


def orient_float(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """:func:`orient` for coordinates where :func:`grid_exact` holds (the float is exact)."""
    det = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)
    return (det > 0) - (det < 0)


def orient_sure_many(
    ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray, cx: np.ndarray, cy: np.ndarray
) -> np.ndarray:
    """int8 sign of orient(a, b, c) where the float value is surely right (beyond the static
    bound of :func:`orient_many`), 0 where it is not sure (c on the line, near it, or an
    overflow); callers with huge coordinates silence numpy's warnings."""
    left = (ax - cx) * (by - cy)
    right = (ay - cy) * (bx - cx)
    det = left - right
    bound = CCW_ERRBOUND * (np.abs(left) + np.abs(right)) + UNDERFLOW_SLACK
    return (det > bound).astype(np.int8) - (-det > bound).astype(np.int8)


# grid_exact's range of quanta 2**q: products of two multiples of 2**q are multiples of
# 2**(2 q), exact down to 2**-1074; determinants of values below 2**t stay below 2**(2 t + 3).
_GRID_LEAST = -537
_GRID_MOST = 510


def grid_exact(*coordinates: np.ndarray) -> bool:
    """True if every orientation determinant of these coordinates is exact in float64.

    That holds when all values are multiples of one power of two 2**q with magnitude below
    2**(q + 25) (e.g. integers below 33 million): differences, products and their difference
    then all fit in 53 bits, and within the exponent range where 2**(2 q) does not underflow
    (q >= -537) and the determinant stays below 2**1024 (q + 25 <= 510).
    """
    values = np.concatenate([np.ravel(c) for c in coordinates])
    if not np.isfinite(values).all():
        return False
    values = values[values != 0]
    if len(values) == 0:
        return True
    mantissa, exponent = np.frexp(values)
    integers = (mantissa * 2.0**53).astype(np.int64)
    lowest_bit = integers & -integers
    quantum = int((exponent - 53 + np.log2(lowest_bit.astype(np.float64)).astype(np.int64)).min())
    if not _GRID_LEAST <= quantum <= _GRID_MOST - 25:
        return False
    return bool(np.abs(values).max() < 2.0 ** (quantum + 25))


def orient_many(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    exact_inputs: bool = False,
) -> np.ndarray:
    """Vectorised :func:`orient` with numpy broadcasting; returns int8 signs.

    ``exact_inputs=True`` asserts that :func:`grid_exact` holds for the coordinates, so the
    float result is exact. Overflow in the float filter is harmless (it sends the value to
    the exact path); callers with huge coordinates silence numpy's warnings with
    ``np.errstate``.
    """
    detleft = (ax - cx) * (by - cy)
    detright = (ay - cy) * (bx - cx)
    det = detleft - detright
    if exact_inputs:
        return np.sign(det).astype(np.int8)
    bound = CCW_ERRBOUND * (np.abs(detleft) + np.abs(detright)) + UNDERFLOW_SLACK
    sure = np.abs(det) > bound
    signs = np.sign(det).astype(np.int8)
    if not sure.all():
        # both products exactly zero (a coordinate of c equals one of a or b): det is exactly 0
        sure = sure | (((ax == cx) | (by == cy)) & ((ay == cy) | (bx == cx)))
    if not sure.all():
        unsure = np.nonzero(~sure)
        arrays = np.broadcast_arrays(ax, ay, bx, by, cx, cy)
        picked = [np.asarray(a[unsure], dtype=np.float64) for a in arrays]
        det2, exact = _exactly_computed(*picked)
        values = np.sign(det2).astype(np.int8)
        if not exact.all():
            rest = np.flatnonzero(~exact)
            values[rest] = [
                orient_exact(*point) for point in zip(*(p[rest].tolist() for p in picked))
            ]
        signs[unsure] = values
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


def strictly_between_one(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> bool:
    """Scalar :func:`strictly_between` (p collinear with a and b)."""
    return (
        min(ax, bx) <= px <= max(ax, bx)
        and min(ay, by) <= py <= max(ay, by)
        and not (px == ax and py == ay)
        and not (px == bx and py == by)
    )


def exact_sq_distance(ax: float, ay: float, bx: float, by: float) -> Fraction:
    """Exact squared distance between two float points."""
    dx = Fraction(ax) - Fraction(bx)
    dy = Fraction(ay) - Fraction(by)
    return dx * dx + dy * dy


def ring_area_sign(x: np.ndarray, y: np.ndarray) -> int:
    """Exact sign of the signed (shoelace) area of the closed ring (x[i], y[i])."""
    if len(x) < 3:
        return 0
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        # the area does not depend on a translation: taken from the first vertex, the terms
        # stay small for rings far from the origin (the differences round by at most eps
        # relative, which the bound's factor 4 covers)
        for dx, dy in ((x, y), (x - x[0], y - y[0])):
            dxn, dyn = np.roll(dx, -1), np.roll(dy, -1)
            left = dx * dyn
            right = dxn * dy
            total = float(np.sum(left - right))
            magnitude = float(np.sum(np.abs(left) + np.abs(right)))
            bound = magnitude * (len(x) + 4) * 4.0 * _EPS + UNDERFLOW_SLACK * len(x)
            if np.isfinite(total) and np.isfinite(bound) and abs(total) > bound:
                return 1 if total > 0 else -1
    # exact: integers times one common power of two, summed chunk by chunk (bounded memory)
    shift = max(_max_shift(x), _max_shift(y))
    twice_area = 0
    n = len(x)
    for start in range(0, n, _EXACT_CHUNK):
        stop = min(start + _EXACT_CHUNK, n)
        nxt = np.arange(start + 1, stop + 1) % n
        xi = _scaled_ints(x[start:stop].tolist(), shift)
        yi = _scaled_ints(y[start:stop].tolist(), shift)
        xn = _scaled_ints(x[nxt].tolist(), shift)
        yn = _scaled_ints(y[nxt].tolist(), shift)
        twice_area += sum(a * d - c * b for a, b, c, d in zip(xi, yi, xn, yn))
    return (twice_area > 0) - (twice_area < 0)


def shoelace_products(
    x: np.ndarray, y: np.ndarray, start: np.ndarray, last: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """x * y[next] and x[next] * y per point of rings laid out one after another (ring i at
    ``start[i]`` .. ``last[i]``): the next point is the following one, except at each ring's
    last point, where it is the ring's first."""
    left = np.empty_like(x)
    np.multiply(x[:-1], y[1:], out=left[:-1])
    left[last] = x[last] * y[start]
    right = np.empty_like(x)
    np.multiply(x[1:], y[:-1], out=right[:-1])
    right[last] = x[start] * y[last]
    return left, right


def ring_area_signs(
    x: np.ndarray, y: np.ndarray, starts: np.ndarray, counts: np.ndarray
) -> tuple[np.ndarray, bool]:
    """Sign of each ring's shoelace area (rings laid out one after another, ring i at
    ``starts[i]``, ``counts[i]`` points; 0 where it is zero or not surely decided in float,
    see :func:`ring_area_sign` for the exact sign), and whether every ring's sum of product
    magnitudes is finite (then so is every x and y: a product with a non-finite factor is inf
    or NaN)."""
    left, right = shoelace_products(x, y, starts, starts + counts - 1)
    total = np.add.reduceat(left - right, starts)
    np.abs(left, out=left)
    np.abs(right, out=right)
    left += right
    magnitude = np.add.reduceat(left, starts)
    bound = 2.0 * (magnitude * (counts + 4) * 2.0 * _EPS + UNDERFLOW_SLACK * counts)
    finite = np.isfinite(bound)
    sure = (np.abs(total) > bound) & np.isfinite(total) & finite
    return np.where(sure, np.sign(total), 0).astype(np.int64), bool(finite.all())


def area_surely_clear(
    net: np.ndarray | float, magnitude: np.ndarray | float, count: np.ndarray | int
) -> np.ndarray | bool:
    """The net shoelace sum ``net`` of ``count`` points is surely more than 8 eps of its
    products' magnitudes ``magnitude`` (the engine's negligible-area guard), whatever order
    it and the guard sum in: a margin for both roundings. False also where unsure."""
    margin = (8.0 + 8.0 * (count + 8)) * np.finfo(np.float64).eps * magnitude
    return np.isfinite(net) & np.isfinite(magnitude) & (np.abs(net) > margin)


# values per chunk of the exact area sum
_EXACT_CHUNK = 1 << 16


def _max_shift(values: np.ndarray) -> int:
    """The s for which every value times 2**s is an integer (the largest denominator's)."""
    shift = 0
    for start in range(0, len(values), _EXACT_CHUNK):
        part = values[start : start + _EXACT_CHUNK].tolist()
        shift = max(shift, max(v.as_integer_ratio()[1].bit_length() - 1 for v in part))
    return shift


def _scaled_ints(values: list[float], shift: int) -> list[int]:
    """values[i] * 2**shift as exact integers (every denominator divides 2**shift)."""
    out = []
    for v in values:
        num, den = v.as_integer_ratio()
        out.append(num << (shift - (den.bit_length() - 1)))
    return out


# Shewchuk's iccerrboundA: bound on the rounding of the float in-circle determinant
# (differences included).
ICC_ERRBOUND = (10.0 + 96.0 * _EPS) * _EPS


def incircle_exact(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> int:
    """Sign of the in-circle determinant of (a, b, c, d), computed exactly (Python integers)."""
    ratios = [v.as_integer_ratio() for v in (ax, ay, bx, by, cx, cy, dx, dy)]
    shift = max(den.bit_length() for _, den in ratios)
    n = [num << (shift - den.bit_length()) for num, den in ratios]
    adx, ady = n[0] - n[6], n[1] - n[7]
    bdx, bdy = n[2] - n[6], n[3] - n[7]
    cdx, cdy = n[4] - n[6], n[5] - n[7]
    det = (
        (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
        + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
        + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady)
    )
    return (det > 0) - (det < 0)


_INF = float("inf")


Coordinate = float | np.ndarray


def _incircle_float(
    ax: Coordinate,
    ay: Coordinate,
    bx: Coordinate,
    by: Coordinate,
    cx: Coordinate,
    cy: Coordinate,
    dx: Coordinate,
    dy: Coordinate,
) -> tuple[Coordinate, Coordinate]:
    """The in-circle determinant in float and Shewchuk's static bound on its rounding
    (``iccerrboundA``, differences included): Python floats or numpy arrays alike."""
    adx, ady = ax - dx, ay - dy
    bdx, bdy = bx - dx, by - dy
    cdx, cdy = cx - dx, cy - dy
    bc, cb = bdx * cdy, cdx * bdy
    ca, ac = cdx * ady, adx * cdy
    ab, ba = adx * bdy, bdx * ady
    alift = adx * adx + ady * ady
    blift = bdx * bdx + bdy * bdy
    clift = cdx * cdx + cdy * cdy
    det = alift * (bc - cb) + blift * (ca - ac) + clift * (ab - ba)
    permanent = (
        (abs(bc) + abs(cb)) * alift + (abs(ca) + abs(ac)) * blift + (abs(ab) + abs(ba)) * clift
    )
    return det, ICC_ERRBOUND * permanent + UNDERFLOW_SLACK


def incircle_many(
    ax: np.ndarray | float,
    ay: np.ndarray | float,
    bx: np.ndarray | float,
    by: np.ndarray | float,
    cx: np.ndarray | float,
    cy: np.ndarray | float,
    dx: np.ndarray | float,
    dy: np.ndarray | float,
) -> np.ndarray:
    """Exact sign of the in-circle determinant, vectorised with broadcasting (int8).

    For a, b, c counter-clockwise: +1 if d lies strictly inside their circumcircle, -1 if
    strictly outside, 0 on it (the sign flips for clockwise a, b, c). Float64 with Shewchuk's
    static bound; entries within it are re-decided exactly.
    """
    coordinates = (ax, ay, bx, by, cx, cy, dx, dy)
    flat: list[np.ndarray | float]
    if _points_around_one_circle(coordinates):
        circle = [float(v) for v in coordinates[:6]]
        if len(dx) <= _FEW_POINTS:
            # numpy's fixed cost per call outweighs a few tests on Python floats (exact too)
            points = zip(np.ravel(dx).tolist(), np.ravel(dy).tolist())
            return np.array([incircle_one(*circle, x, y) for x, y in points], dtype=np.int8)
        shape = np.shape(dx)
        flat = [*circle, np.asarray(dx, dtype=np.float64), np.asarray(dy, dtype=np.float64)]
    else:
        shape = np.broadcast_shapes(*(np.shape(c) for c in coordinates))
        flat = _flat_arrays(coordinates)
    signs, sure = _incircle_filter(*flat)
    if not sure.all():
        unsure = np.flatnonzero(~sure)
        picked = [a[unsure] if np.ndim(a) else np.full(len(unsure), a) for a in flat]
        # the corners of an axis-parallel rectangle (cell centres of a grid) lie on one
        # circle: exactly 0, without the integer arithmetic
        on_circle = _rectangle_corners(*picked)
        signs[unsure[on_circle]] = 0
        left = ~on_circle
        if left.any():
            points = zip(*(a[left].tolist() for a in picked))
            signs[unsure[left]] = [incircle_exact(*point) for point in points]
    return signs.reshape(shape) if shape else signs


# at most this many points against one circle are tested on Python floats
_FEW_POINTS = 24


def _points_around_one_circle(coordinates: tuple[np.ndarray | float, ...]) -> bool:
    """The circle's corners are scalars and the points two 1-D arrays of one length."""
    dx, dy = coordinates[6], coordinates[7]
    return (
        np.ndim(dx) == 1
        and np.shape(dx) == np.shape(dy)
        and all(np.ndim(c) == 0 for c in coordinates[:6])
    )


# entries per pass of :func:`_incircle_filter`: its temporaries stay in the cache
_FILTER_CHUNK = 4096


def _incircle_filter(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_incircle_float` on 1-D arrays of one length (a, b and c may be floats), in
    place and by chunks: the signs of the float determinant (int8) and where they are sure
    (beyond the bound)."""
    count = len(dx)
    signs = np.empty(count, dtype=np.int8)
    sure = np.empty(count, dtype=bool)
    corners = (ax, ay, bx, by, cx, cy)
    arrays = [np.ndim(v) > 0 for v in corners]
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        for first in range(0, count, _FILTER_CHUNK):
            part = slice(first, first + _FILTER_CHUNK)
            px, py = dx[part], dy[part]
            pax, pay, pbx, pby, pcx, pcy = (
                v[part] if is_array else v for v, is_array in zip(corners, arrays)
            )
            adx, ady = pax - px, pay - py
            bdx, bdy = pbx - px, pby - py
            cdx, cdy = pcx - px, pcy - py
            bc, cb = bdx * cdy, cdx * bdy
            ca, ac = cdx * ady, adx * cdy
            ab, ba = adx * bdy, bdx * ady
            # the lifts, in the differences' place: the same operations in the same order
            # as _incircle_float, so the same values
            adx *= adx
            ady *= ady
            adx += ady
            bdx *= bdx
            bdy *= bdy
            bdx += bdy
            cdx *= cdx
            cdy *= cdy
            cdx += cdy
            det = bc - cb
            det *= adx
            np.subtract(ca, ac, out=ady)
            ady *= bdx
            det += ady
            np.subtract(ab, ba, out=ady)
            ady *= cdx
            det += ady
            permanent = np.abs(bc, out=bc)
            permanent += np.abs(cb, out=cb)
            permanent *= adx
            np.abs(ca, out=ca)
            ca += np.abs(ac, out=ac)
            ca *= bdx
            permanent += ca
            np.abs(ab, out=ab)
            ab += np.abs(ba, out=ba)
            ab *= cdx
            permanent += ab
            permanent *= ICC_ERRBOUND
            permanent += UNDERFLOW_SLACK
            # a nan or infinite value is never sure (nor is anything under an infinite bound)
            np.greater(np.abs(det, out=cb), permanent, out=sure[part])
            sure[part] &= np.isfinite(det)
            np.greater(det, 0.0, out=signs[part].view(bool))
            signs[part] -= det < 0.0
    return signs, sure


def _flat_arrays(coordinates: tuple[np.ndarray | float, ...]) -> list[np.ndarray]:
    """The coordinates broadcast together, as flat float64 arrays (views where they can be:
    a scalar spread along 1-D arrays is not copied)."""
    return [
        np.asarray(a, dtype=np.float64).reshape(-1)
        for a in np.broadcast_arrays(*(np.atleast_1d(c) for c in coordinates))
    ]


def _rectangle_corners(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
) -> np.ndarray:
    """Where the four points are four distinct corners of one axis-parallel rectangle (two
    x values, two y values, each taken twice, all finite): they lie on one circle (exact
    comparisons)."""
    xs = np.sort(np.column_stack([ax, bx, cx, dx]), axis=1)
    ys = np.sort(np.column_stack([ay, by, cy, dy]), axis=1)
    two = np.isfinite(xs).all(axis=1) & np.isfinite(ys).all(axis=1)
    two &= (xs[:, 0] == xs[:, 1]) & (xs[:, 2] == xs[:, 3]) & (xs[:, 1] < xs[:, 2])
    two &= (ys[:, 0] == ys[:, 1]) & (ys[:, 2] == ys[:, 3]) & (ys[:, 1] < ys[:, 2])
    points = ((ax, ay), (bx, by), (cx, cy), (dx, dy))
    for i in range(4):
        for j in range(i + 1, 4):
            two &= (points[i][0] != points[j][0]) | (points[i][1] != points[j][1])
    return two


def incircle(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> int:
    """Scalar :func:`incircle_many`: +1 if d is strictly inside the circle through the
    counter-clockwise a, b, c, -1 if strictly outside, 0 if on it (exact)."""
    return int(incircle_many(ax, ay, bx, by, cx, cy, dx, dy)[0])


def incircle_one(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> int:
    """:func:`incircle` on Python floats without numpy (a float filter, exact where unsure)."""
    det, bound = _incircle_float(ax, ay, bx, by, cx, cy, dx, dy)
    if det > bound and bound < _INF:
        return 1
    if -det > bound and bound < _INF:
        return -1
    return incircle_exact(ax, ay, bx, by, cx, cy, dx, dy)


def cocircular_sign(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> int:
    """The tie rule of rule "delaunay" for d exactly on the circle through the
    counter-clockwise a, b, c: +1 if d counts as inside, -1 as outside, 0 if d is one of them.

    A symbolic perturbation: every point's lift (x^2 + y^2) is lowered by eps^r, r its rank
    in (x, y) order of the coordinates given (the working plane's), so the lexicographically
    smallest of the four points dominates. If that
    is d, d is inside; if it is a corner m, d is inside when it lies beyond the side opposite
    m (its barycentric weight for m is negative). The perturbed points are in general
    position, so the constrained Delaunay triangulation is unique, whichever way it is built.
    """
    d = (dx, dy)
    a, b, c = (ax, ay), (bx, by), (cx, cy)
    if d in (a, b, c):
        return 0
    low = min(a, b, c, d)
    if low == d:
        return 1
    if low == a:
        side = orient(bx, by, cx, cy, dx, dy)
    elif low == b:
        side = orient(cx, cy, ax, ay, dx, dy)
    else:
        side = orient(ax, ay, bx, by, dx, dy)
    return 1 if side < 0 else -1


def incircle_sos(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> int:
    """:func:`incircle_one` with exact ties decided by :func:`cocircular_sign`: 0 only
    when d is a corner's point."""
    sign = incircle_one(ax, ay, bx, by, cx, cy, dx, dy)
    return sign if sign else cocircular_sign(ax, ay, bx, by, cx, cy, dx, dy)


def incircle_sos_many(
    ax: np.ndarray | float,
    ay: np.ndarray | float,
    bx: np.ndarray | float,
    by: np.ndarray | float,
    cx: np.ndarray | float,
    cy: np.ndarray | float,
    dx: np.ndarray | float,
    dy: np.ndarray | float,
) -> np.ndarray:
    """Vectorised :func:`incircle_sos` (int8, broadcasting)."""
    signs = incircle_many(ax, ay, bx, by, cx, cy, dx, dy)
    ties = np.flatnonzero(signs.ravel() == 0)
    if len(ties):
        arrays = _flat_arrays((ax, ay, bx, by, cx, cy, dx, dy))
        flat = signs.ravel()  # a copy where signs is not contiguous
        flat[ties] = cocircular_signs(*(a[ties] for a in arrays))
        signs = flat.reshape(signs.shape)
    return signs


def cocircular_signs(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
) -> np.ndarray:
    """Vectorised :func:`cocircular_sign` (int8, one per row of the broadcast inputs)."""
    ax, ay, bx, by, cx, cy, dx, dy = _flat_arrays((ax, ay, bx, by, cx, cy, dx, dy))

    def before(px: np.ndarray, py: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        return (px < qx) | ((px == qx) & (py < qy))

    # the lowest of the four points in (x, y) order: 0 a, 1 b, 2 c, 3 d
    lx, ly = ax.copy(), ay.copy()
    low = np.zeros(len(ax), dtype=np.int8)
    for number, (px, py) in enumerate(((bx, by), (cx, cy), (dx, dy)), start=1):
        lower = before(px, py, lx, ly)
        lx, ly = np.where(lower, px, lx), np.where(lower, py, ly)
        low[lower] = number
    # d beyond the side opposite the lowest corner: inside
    side = np.where(
        low == 0,
        orient_many(bx, by, cx, cy, dx, dy),
        np.where(
            low == 1, orient_many(cx, cy, ax, ay, dx, dy), orient_many(ax, ay, bx, by, dx, dy)
        ),
    )
    signs = np.where(side < 0, 1, -1).astype(np.int8)
    signs[low == 3] = 1
    corner = ((dx == ax) & (dy == ay)) | ((dx == bx) & (dy == by)) | ((dx == cx) & (dy == cy))
    signs[corner] = 0
    return signs


def _two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """fl(a + b) and its rounding error (Knuth's two-sum): a + b == x + y exactly."""
    x = a + b
    return x, _diff_error(a, -b, x)


def _expansion_sign(terms: list[np.ndarray]) -> np.ndarray:
    """Exact sign of the sum of the float arrays ``terms`` (int8), by Shewchuk's
    grow-expansion: the components come out non-overlapping in increasing magnitude (zeros
    anywhere), so the last non-zero one has the sum's sign. Overflow-free inputs only."""
    expansion: list[np.ndarray] = []
    for term in terms:
        q = term
        for i, component in enumerate(expansion):
            q, expansion[i] = _two_sum(q, component)
        expansion.append(q)
    sign = np.zeros(len(terms[0]), dtype=np.int8)
    for component in expansion:
        sign = np.where(component != 0, np.sign(component).astype(np.int8), sign)
    return sign


def sq_distance_exact(ax: float, ay: float, bx: float, by: float) -> int:
    """The exact squared distance between two float points times 2**2148 (an integer: every
    finite double is a multiple of 2**-1074), ordered as the exact distances are."""
    dx = _times_2_1074(ax) - _times_2_1074(bx)
    dy = _times_2_1074(ay) - _times_2_1074(by)
    return dx * dx + dy * dy


def _times_2_1074(value: float) -> int:
    """``value`` times 2**1074, exactly (an integer)."""
    numerator, denominator = value.as_integer_ratio()  # the denominator a power of two
    return numerator << (1075 - denominator.bit_length())


# |differences| within which the two-product of their squares is exact (no underflow of the
# error term, no overflow of the square or of the split)
_SQUARE_LOW, _SQUARE_HIGH = 2.0**-450, 2.0**450


def compare_sq_distances_many(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
) -> np.ndarray:
    """Exact sign of |a - b|^2 - |c - d|^2 per entry (int8; 1-d arrays of one length).

    With u = a - b and v = c - d the value is (ux - vx)(ux + vx) + (uy - vy)(uy + vy). Where
    those six differences and sums are exact in float (two-sum) and of moderate size, the two
    products are split exactly into floats and rounding errors (two-product) and the sign of
    the four-term sum is taken exactly (:func:`_expansion_sign`); other entries take
    :func:`_compare_sq_distances_expanded`.
    """
    arrays = [np.asarray(v, dtype=np.float64) for v in (ax, ay, bx, by, cx, cy, dx, dy)]
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        ux, uy = arrays[0] - arrays[2], arrays[1] - arrays[3]
        vx, vy = arrays[4] - arrays[6], arrays[5] - arrays[7]
        usable = (
            (_diff_error(arrays[0], arrays[2], ux) == 0)
            & (_diff_error(arrays[1], arrays[3], uy) == 0)
            & (_diff_error(arrays[4], arrays[6], vx) == 0)
            & (_diff_error(arrays[5], arrays[7], vy) == 0)
        )
        terms = []
        for u, v in ((ux, vx), (uy, vy)):
            low, high = u - v, u + v
            usable &= (_diff_error(u, v, low) == 0) & (_diff_error(u, -v, high) == 0)
            for factor in (low, high):
                size = np.abs(factor)
                usable &= (factor == 0) | ((size > _SQUARE_LOW) & (size < _SQUARE_HIGH))
            product = low * high
            terms += [product, _product_error(low, high, product)]
        signs = _expansion_sign(terms)
    rest = np.flatnonzero(~usable)
    if len(rest):
        signs[rest] = _compare_sq_distances_expanded(*(a[rest] for a in arrays))
    return signs


def _compare_sq_distances_expanded(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
) -> np.ndarray:
    """:func:`compare_sq_distances_many` another way: where the four coordinate differences
    are exact in float and of moderate size, each square is split exactly into a float and
    its rounding error and the sign of the eight-term sum is taken exactly; the other entries
    are decided on Python integers (:func:`sq_distance_exact`)."""
    arrays = [ax, ay, bx, by, cx, cy, dx, dy]
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        differences = [(arrays[k] - arrays[k + 2], arrays[k], arrays[k + 2]) for k in (0, 1, 4, 5)]
        usable = np.ones(len(arrays[0]), dtype=bool)
        terms = []
        for diff, first, second in differences:
            size = np.abs(diff)
            usable &= (_diff_error(first, second, diff) == 0) & (
                (diff == 0) | ((size > _SQUARE_LOW) & (size < _SQUARE_HIGH))
            )
            square = diff * diff
            terms.append((square, _product_error(diff, diff, square)))
        (p, e), (q, f), (r, g), (s, h) = terms
        signs = _expansion_sign([p, e, q, f, -r, -g, -s, -h])
    rest = np.flatnonzero(~usable)
    if len(rest):
        picked = [a[rest].tolist() for a in arrays]
        signs[rest] = [
            (u > v) - (u < v)
            for u, v in (
                (sq_distance_exact(*point[:4]), sq_distance_exact(*point[4:]))
                for point in zip(*picked)
            )
        ]
    return signs
