"""Points shared by rings, found at once: the same as comparing every pair of vertices."""

from __future__ import annotations

import numpy as np

from bsp_triangulate.geometry.shared_points import point_numbers, touching_islands


def test_equal_points_share_a_number_and_signed_zeros_are_equal() -> None:
    x = np.array([0.0, -0.0, 1.0, 1.0, 0.0, 2.0])
    y = np.array([0.0, 0.0, 1.0, 1.0, -0.0, 5e-324])
    numbers = point_numbers(x, y)
    for i in range(len(x)):
        for j in range(len(x)):
            assert (numbers[i] == numbers[j]) == (x[i] == x[j] and y[i] == y[j])


def test_random_grid_points_match_pairwise_comparison() -> None:
    rng = np.random.default_rng(3)
    x = rng.integers(-3, 4, 400).astype(float)
    y = rng.integers(-3, 4, 400).astype(float)
    numbers = point_numbers(x, y)
    same = (x[:, None] == x) & (y[:, None] == y)
    assert np.array_equal(numbers[:, None] == numbers, same)


def test_touching_islands_are_those_sharing_a_point() -> None:
    rng = np.random.default_rng(5)
    x = rng.integers(0, 12, 300).astype(float)
    y = rng.integers(0, 12, 300).astype(float)
    ids = rng.permutation(300)
    rings = [ids[:40]] + [ids[k : k + 5] for k in range(40, 300, 5)] + [ids[:1]]
    partners = touching_islands(point_numbers(x, y), rings)
    points = [set(zip(x[r].tolist(), y[r].tolist())) for r in rings]
    for a in range(len(rings)):
        expected = [b for b in range(1, len(rings)) if b != a and points[a] & points[b]]
        assert partners[a] == expected
