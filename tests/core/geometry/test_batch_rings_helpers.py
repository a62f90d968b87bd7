"""Helpers of batch_rings: joined rings, rings with z = 0, area signs and the area check
against plain references (the batch cross-checks test them through whole results)."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate.geometry.predicates import ring_area_signs
from bsp_triangulate.geometry.rings_batch import (
    _joined,
    _with_zero_z,
    clear_area,
    flatten_points,
    flatten_rings,
    ragged_index,
    stack_rings,
)

from ..random_polygons import random_polygon

MAX = 10_000


def test_ragged_index_equals_concatenated_ranges() -> None:
    """Every run arange(s, s + c) in order; runs with c <= 0 give nothing; int64 always."""
    rng = np.random.default_rng(5)
    for trial in range(500):
        n = int(rng.integers(0, 20))
        starts, counts = rng.integers(-5, 100, n), rng.integers(-2, 6, n)
        if trial % 3 == 0:
            starts, counts = starts.astype(np.int32), counts.astype(np.int32)
        runs = [np.arange(s, s + c, dtype=np.int64) for s, c in zip(starts, counts)]
        got = ragged_index(starts, counts)
        assert got.dtype == np.int64
        assert np.array_equal(got, np.concatenate([np.zeros(0, np.int64), *runs]))


def test_joined_equals_concatenate_for_contiguous_and_other_layouts() -> None:
    rng = np.random.default_rng(3)
    rings = [rng.uniform(-5, 5, (n, 2)) for n in (1, 4, 9)]
    others = [rings[0], rings[1][::-1], np.asfortranarray(rings[2])]
    for arrays in (rings, others):
        joined = _joined(arrays, 2)
        assert joined.shape == (14, 2)
        assert np.array_equal(joined, np.concatenate(arrays))


@pytest.mark.parametrize("widths", [(2, 2), (3, 3), (4, 4), (2, 3, 4)])
def test_stack_rings_gives_a_writable_copy_with_zero_z_where_absent(widths) -> None:
    rng = np.random.default_rng(len(widths))
    arrays = [rng.uniform(-5, 5, (5, w)) for w in widths]
    stacked = stack_rings(arrays, np.array(widths))
    want = np.concatenate(
        [np.c_[a[:, :2], a[:, 2] if a.shape[1] > 2 else np.zeros(5)] for a in arrays]
    )
    assert stacked.flags.writeable and stacked.flags.c_contiguous
    assert np.array_equal(stacked, want)
    stacked[0, 0] = 99.0
    assert all(a[0, 0] != 99.0 for a in arrays)


def test_with_zero_z_gives_points_and_contiguous_columns() -> None:
    xy = np.arange(12.0).reshape(6, 2)
    points, x, y = _with_zero_z(xy)
    assert np.array_equal(points, np.c_[xy, np.zeros(6)])
    assert x.flags.c_contiguous and y.flags.c_contiguous
    assert np.array_equal(x, xy[:, 0]) and np.array_equal(y, xy[:, 1])


@np.errstate(over="ignore", invalid="ignore")
def test_area_signs_and_their_finiteness() -> None:
    square = np.array([0.0, 1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0, 1.0])
    x = np.r_[square[0], square[0][::-1], [0.0, 1.0, 2.0]]
    y = np.r_[square[1], square[1][::-1], [0.0, 1.0, 2.0]]
    starts, counts = np.array([0, 4, 8]), np.array([4, 4, 3])
    signs, finite = ring_area_signs(x, y, starts, counts)
    assert signs.tolist() == [1, -1, 0] and finite
    x[9] = np.inf
    signs, finite = ring_area_signs(x, y, starts, counts)
    assert signs.tolist() == [1, -1, 0] and not finite
    # finite coordinates whose products overflow are not finite sums either
    signs, finite = ring_area_signs(
        np.array([0.0, 1e300, 1e300]), np.array([0.0, 0.0, 1e300]), np.array([0]), np.array([3])
    )
    assert signs.tolist() == [0] and not finite


NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize(
    "bad",
    [
        [(0.0, 0.0), (NAN, 1.0), (1.0, 1.0)],
        [(0.0, 0.0), (INF, 0.0), (INF, 1.0)],
        [(INF, 0.0), (INF, 0.0), (INF, 1.0), (0.0, 0.0)],
        [(0.0, 0.0), (1e300, 0.0), (1e300, 1e300)],
        [(2.0, 2.0), (-INF, 3.0)],
    ],
)
def test_two_column_rings_decide_like_three_column_rings(bad: list) -> None:
    square = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
    polygons = [[np.array(bad)], [np.array(square), np.array(bad)], [np.array(square)]]
    flat = flatten_rings(polygons, MAX)
    arrays = [np.c_[np.array(r), np.zeros(len(r))] for rings in polygons for r in rings]
    lengths = np.array([len(a) for a in arrays])
    want = flatten_points(np.concatenate(arrays), lengths, np.array([1, 2, 1]), MAX)
    for name in ("handled", "empty", "mirrored", "ring_len", "ring_reversed", "vertices", "vz"):
        assert np.array_equal(getattr(flat, name), getattr(want, name), equal_nan=True), name


def reference_clear_area(flat, wx: np.ndarray) -> np.ndarray:
    """clear_area as first written: next points by index, a sign per vertex."""
    count = len(flat.handled)
    poly_of = np.repeat(flat.ring_poly, flat.ring_len)
    has = flat.poly_rings > 0
    first = flat.ring_start[flat.poly_ring0[has]]
    x0, y0 = np.zeros(count), np.zeros(count)
    x0[has], y0[has] = wx[first], flat.vy[first]
    nxt = np.arange(len(wx)) + 1
    nxt[flat.ring_start + flat.ring_len - 1] = flat.ring_start
    x, y = wx - x0[poly_of], flat.vy - y0[poly_of]
    left, right = x * y[nxt], x[nxt] * y
    flip = np.repeat(np.where(flat.ring_reversed, -1.0, 1.0), flat.ring_len)
    net = np.bincount(poly_of, weights=flip * (left - right), minlength=count)
    magnitude = np.bincount(poly_of, weights=np.abs(left) + np.abs(right), minlength=count)
    margin = (8.0 + 8.0 * (flat.poly_vcount + 8)) * np.finfo(np.float64).eps * magnitude
    return np.isfinite(net) & np.isfinite(magnitude) & (np.abs(net) > margin)


def test_clear_area_equals_the_reference_with_mirrored_and_reversed_rings() -> None:
    rnd = random.Random(17)
    polygons = [random_polygon(rnd, islands=rnd.randint(0, 3), integer=False) for _ in range(200)]
    polygons += [
        [[(0, 0), (1, 0), (1, 1e-17)]],
        [[(0, 0), (4, 0), (4, 4)], [(1, 0.5), (3, 0.5), (3, 2.5)]],
    ]
    flat = flatten_rings(polygons, MAX)
    assert flat.mirrored.any() and flat.ring_reversed.any()
    wx = np.where(np.repeat(flat.mirrored[flat.ring_poly], flat.ring_len), -flat.vx, flat.vx)
    assert np.array_equal(clear_area(flat, wx), reference_clear_area(flat, wx))
