"""The touching search (a vertex in the relative interior of an edge) misses no pair.

It looks only at vertices near each edge's path through a grid; an all-pairs exact search on
inputs full of collinear lattice points (where every miss would show) is the reference.
"""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.geometry.bridges import _touching_pairs, ring_edges
from bsp_triangulate.geometry.predicates import orient_exact, strictly_between_one


def _all_pairs(x: np.ndarray, y: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> set:
    found = set()
    for edge, (a, b) in enumerate(zip(starts.tolist(), ends.tolist())):
        for v in np.unique(starts).tolist():
            if orient_exact(x[a], y[a], x[b], y[b], x[v], y[v]) == 0 and strictly_between_one(
                x[v], y[v], x[a], y[a], x[b], y[b]
            ):
                found.add((edge, v))
    return found


def _lattice_rings(seed: int, transform: str) -> tuple[np.ndarray, np.ndarray, list]:
    """Random rings whose vertices sit on a small lattice, mapped exactly in one of a few ways."""
    rng = np.random.default_rng(seed)
    rings, points = [], []
    for _ in range(rng.integers(1, 4)):
        size = int(rng.integers(3, 12))
        ids = np.arange(len(points), len(points) + size)
        points.extend(rng.integers(0, 7, size=(size, 2)).tolist())
        rings.append(ids)
    p = np.array(points, dtype=np.float64)
    if transform == "affine":  # collinear runs along a skewed lattice
        p = p @ np.array([[3.0, 1.0], [1.0, 2.0]])
    elif transform == "offset":
        p = p * 0.5 + 1e6
    elif transform == "steep":  # nearly vertical edges
        p[:, 0] *= 1 / 1024
    return p[:, 0].copy(), p[:, 1].copy(), rings


@pytest.mark.parametrize("transform", ["plain", "affine", "offset", "steep"])
def test_touching_pairs_equal_an_all_pairs_exact_search(transform: str) -> None:
    total = 0
    for seed in range(60):
        x, y, rings = _lattice_rings(seed, transform)
        starts, ends = ring_edges(rings)
        edge, vertex = _touching_pairs(x, y, starts, ends)
        found = set(zip(edge.tolist(), vertex.tolist()))
        assert found == _all_pairs(x, y, starts, ends), f"seed {seed}"
        total += len(found)
    assert total > 50  # the lattice makes many vertices lie on edges: the test is not vacuous
