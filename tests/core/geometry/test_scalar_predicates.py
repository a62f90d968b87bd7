"""The engine's scalar predicates (large polygons) agree with the vectorised ones (batches).

Inputs are small integer grids, so collinear points, shared corners and touching edges are
common, plus the same points scaled by a non-representable factor so that the float filter has
to defer to exact arithmetic.
"""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate import triangulate, triangulate_many
from bsp_triangulate.geometry.predicates import (
    grid_exact,
    orient,
    orient_exact,
    orient_float,
    orient_many,
    strictly_between,
    strictly_between_one,
)
from bsp_triangulate.tree.one_by_one import facing_one, pair_fails
from bsp_triangulate.tree.one_polygon import facing_candidates, pairs_failing

SCALES = [1.0, 0.1, 1e-9 / 3, 1e15]


def _points(seed: int, count: int, scale: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.integers(-4, 5, size=(count, 2)).astype(np.float64) * scale


def _star(seed: int, count: int, scale: float) -> np.ndarray:
    """A star-shaped concave ring snapped to a coarse grid (collinear runs, repeated points)."""
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * np.pi, count))
    radii = rng.integers(2, 9, size=count)
    ring = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    return np.round(ring) * scale


@pytest.mark.parametrize("scale", SCALES)
def test_scalar_orientation_equals_vectorised_and_exact(scale: float) -> None:
    p = _points(1, 3 * 400, scale).reshape(400, 6)
    many = orient_many(*(p[:, k] for k in range(6)))
    for row, expected in zip(p.tolist(), many.tolist()):
        assert orient(*row) == expected == orient_exact(*row)
    if scale == 1.0:  # whole numbers: the float sign is exact
        assert [orient_float(*row) for row in p.tolist()] == many.tolist()


@pytest.mark.parametrize("scale", SCALES)
def test_scalar_strictly_between_equals_vectorised(scale: float) -> None:
    line = np.arange(-3, 4, dtype=np.float64) * scale
    px, ax, bx = np.meshgrid(line, line, line, indexing="ij")
    px, ax, bx = px.ravel(), ax.ravel(), bx.ravel()
    zeros = np.zeros_like(px)
    many = strictly_between(px, zeros, ax, zeros, bx, zeros)
    scalar = [strictly_between_one(p, 0.0, a, 0.0, b, 0.0) for p, a, b in zip(px, ax, bx)]
    assert scalar == many.tolist()
    assert any(scalar) and not all(scalar)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("scale", [1.0, 0.1])
def test_scalar_candidate_tests_equal_vectorised(seed: int, scale: float) -> None:
    points = _star(seed, 24, scale)
    sx = np.append(points[:, 0], points[0, 0])
    sy = np.append(points[:, 1], points[0, 1])
    xs, ys = sx.tolist(), sy.tolist()
    lo, hi = 1, len(points)  # the root: chord s_0 -> s_1, s_m repeats s_0
    candidates = np.arange(hi - 1, lo, -1)
    facing = facing_candidates(sx, sy, lo, hi, candidates)
    assert [facing_one(xs, ys, lo, hi, int(c)) for c in candidates] == facing.tolist()

    edges = np.arange(lo, hi)
    rows = np.repeat(np.arange(len(candidates)), len(edges))
    pairs = np.tile(edges, len(candidates))
    failing, _ = pairs_failing(sx, sy, lo, hi, candidates, rows, pairs)
    ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
    scalar = set()
    for index, c in enumerate(candidates.tolist()):
        if orient(ax, ay, bx, by, xs[c], ys[c]) <= 0:
            continue  # pair_fails assumes a counter-clockwise triangle
        corners = (ax, ay, bx, by, xs[c], ys[c])
        if any(pair_fails(corners, xs[e], ys[e], xs[e + 1], ys[e + 1]) for e in edges.tolist()):
            scalar.add(index)
    ccw = {i for i, c in enumerate(candidates.tolist()) if orient(ax, ay, bx, by, xs[c], ys[c]) > 0}
    assert scalar == set(failing.tolist()) & ccw
    # not vacuous: some candidates face the base, some of those fail on an edge, some pass
    assert facing.any() and scalar and len(scalar) < len(ccw)


@pytest.mark.parametrize("scale", SCALES)
def test_edges_from_a_corner_equal_vectorised(scale: float) -> None:
    # most edges a correct triangle is tested against start at one of its corners; their other
    # end on every point of a small grid (on the lines of the corner's sides, on the corners,
    # beyond them) against counter-clockwise triangles of the same grid
    grid = np.arange(-3, 4, dtype=np.float64) * scale
    gx, gy = (v.ravel() for v in np.meshgrid(grid, grid))
    rng = np.random.default_rng(5)
    tested = 0
    for _ in range(40):
        a, b, c = (rng.integers(0, len(gx), 3)).tolist()
        ax, ay, bx, by, cx, cy = gx[a], gy[a], gx[b], gy[b], gx[c], gy[c]
        if orient(ax, ay, bx, by, cx, cy) <= 0:
            continue
        corners = (ax, ay, bx, by, cx, cy)
        for ux, uy in ((ax, ay), (bx, by), (cx, cy)):
            # positions b (lo), c, a (hi), then the edges (corner, v) for every grid point v
            sx = np.concatenate([[bx, cx, ax], np.column_stack([np.full_like(gx, ux), gx]).ravel()])
            sy = np.concatenate([[by, cy, ay], np.column_stack([np.full_like(gy, uy), gy]).ravel()])
            edges = 3 + 2 * np.arange(len(gx))
            rows = np.zeros(len(edges), dtype=np.int64)
            failing = set()
            for e in edges.tolist():
                if len(pairs_failing(sx, sy, 0, 2, np.array([1]), rows[:1], np.array([e]))[0]):
                    failing.add(e)
            for forward in (True, False):
                for e in edges.tolist():
                    p, q = (sx[e], sy[e]), (sx[e + 1], sy[e + 1])
                    if not forward:
                        p, q = q, p
                    assert pair_fails(corners, *p, *q) == (e in failing), (corners, p, q)
                    tested += 1
    assert tested > 3000


@pytest.mark.parametrize("exponent", [-600, -540, -538, 486, 500, 700])
def test_grid_exact_only_where_the_determinants_stay_in_range(exponent: int) -> None:
    # an integer grid scaled by 2**exponent: its determinants are multiples of
    # 2**(2 exponent), which underflow below 2**-1074, and reach 2**(2 exponent + 33), which
    # overflows past 2**1024; there the float orientation is not exact
    values = np.array([7.0, -15.0, 16.0, 1.0, 3.0, 12.0]) * 2.0**exponent
    assert not grid_exact(values)
    assert grid_exact(values * 2.0 ** (-exponent))


def test_grid_exact_keeps_its_range_ends() -> None:
    grid = np.array([1.0, 3.0, 2.0**24])
    assert grid_exact(grid * 2.0**-537)
    assert grid_exact(grid * 2.0**485)
    assert not grid_exact(grid * 2.0**486)


# polygons on an integer grid; scaled by 2**500 the products of the float orientation
# overflowed (inf - inf): the quadrilateral's triangles came out wrong with no error and the
# wide triangle found no apex; scaled by 2**-540 they underflowed and the small triangle
# found no apex
GRID_QUAD = [(3665.0, -24599.0), (8013.0, -25385.0), (5303.0, 13574.0), (496.0, 27364.0)]
GRID_TRIANGLE = [(16.0, 11.0), (16.0, 18.0), (13.0, 18.0)]
WIDE_TRIANGLE = [(-99280.0, -2015.0), (-68520.0, 9209.0), (92407.0, 11552.0)]


@pytest.mark.parametrize("exponent", [-540, 499, 500])
@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
def test_integer_grid_polygons_scaled_far_give_the_same_triangles(exponent: int, rule: str) -> None:
    scale = 2.0**exponent
    for ring in (GRID_QUAD, GRID_TRIANGLE, WIDE_TRIANGLE):
        want = triangulate([ring], rule=rule).triangles
        scaled = [[(x * scale, y * scale) for x, y in ring]]
        assert np.array_equal(triangulate(scaled, rule=rule).triangles, want)
        many = triangulate_many([scaled, scaled], rule=rule)
        assert all(np.array_equal(result.triangles, want) for result in many)
