"""Islands' orientation decided for all rings at once (float where sure, exact otherwise) and
the negligible-area guard's quick decision agree with the ring-by-ring exact answers."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.geometry.predicates import ring_area_sign
from bsp_triangulate.geometry.rings import normalise_rings, prepare
from bsp_triangulate.tree import one_polygon


def islands_far_from_the_origin(seed: int) -> list[np.ndarray]:
    """A square shell at 1e7 with islands: ordinary ones, slivers of 1e-9 width, collinear
    ones (no area), tiny ones whose area float rounding cannot see, both orientations."""
    rng = np.random.default_rng(seed)
    offset = 1e7
    rings = [offset + np.array([(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)])]
    for k in range(40):
        x, y = rng.uniform(5.0, 90.0, 2) + offset
        kind = k % 4
        if kind == 0:
            ring = np.array([(x, y), (x + 2.0, y), (x + 2.0, y + 2.0), (x, y + 2.0)])
        elif kind == 1:
            ring = np.array([(x, y), (x + 3.0, y + 1e-9), (x + 3.0, y + 2e-9)])
        elif kind == 2:
            ring = np.array([(x, y), (x + 1.0, y + 1.0), (x + 2.0, y + 2.0)])
        else:
            ring = np.array([(x, y), (np.nextafter(x, np.inf), y), (x, np.nextafter(y, np.inf))])
        rings.append(ring[::-1] if rng.random() < 0.5 else ring)
    return rings


@pytest.mark.parametrize("seed", range(5))
def test_islands_far_from_the_origin_keep_their_exact_orientation(seed: int):
    rings = islands_far_from_the_origin(seed)
    clean, axes = normalise_rings(rings, "xy")
    prepared = prepare(clean, axes)
    x, y = prepared.x, prepared.y
    kept = dict(zip(prepared.ring_numbers, prepared.rings))
    for number in range(1, len(clean)):
        ids = np.arange(
            sum(len(r) for r in clean[:number]), sum(len(r) for r in clean[: number + 1])
        )
        sign = ring_area_sign(x[ids], y[ids])
        if sign == 0:
            assert number not in kept
        else:  # islands are stored clockwise (traversal order)
            assert ring_area_sign(x[kept[number]], y[kept[number]]) == -1


def test_the_quick_area_decision_only_says_clear_where_the_exact_guard_does(monkeypatch):
    for seed in range(5):
        rings = islands_far_from_the_origin(seed)
        # an island repeating the shell up to rounding: the polygon has no area
        rings.append(rings[0][::-1] + 1e-9)
        clean, axes = normalise_rings(rings, "xy")
        prepared = prepare(clean, axes)
        x0, y0 = prepared.x[prepared.rings[0][0]], prepared.y[prepared.rings[0][0]]
        quick = one_polygon._clear_area(prepared, x0, y0)
        monkeypatch.setattr(one_polygon, "_clear_area", lambda *args: False)
        slow = one_polygon.negligible_area(prepared)
        monkeypatch.undo()
        assert not (quick and slow)
