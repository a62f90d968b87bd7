"""The bridges bucketed by cell answer "does one cross this segment" as testing them all does."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.geometry.bridge_cells import BridgeCells
from bsp_triangulate.geometry.predicates import orient


def crosses_any(segments: list[tuple[float, float, float, float]], u, w) -> bool:
    (ux, uy), (wx, wy) = u, w
    for ax, ay, bx, by in segments:
        if orient(ux, uy, wx, wy, ax, ay) * orient(ux, uy, wx, wy, bx, by) >= 0:
            continue
        if orient(ax, ay, bx, by, ux, uy) * orient(ax, ay, bx, by, wx, wy) < 0:
            return True
    return False


@pytest.mark.parametrize("size", [0.5, 3.0, 40.0, 0.0])
def test_crossings_match_every_segment_tested(size: float) -> None:
    rng = np.random.default_rng(11)
    cells = BridgeCells(0.0, 0.0, size, size)
    added: list[tuple[float, float, float, float]] = []
    for _ in range(300):
        # short and long segments on a coarse grid: collinear and touching cases are common
        ax, ay = rng.integers(0, 40, 2).astype(float)
        reach = 3 if rng.random() < 0.8 else 40
        bx, by = np.clip(np.array([ax, ay]) + rng.integers(-reach, reach + 1, 2), 0, 40).astype(
            float
        )
        u, w = (
            tuple(rng.integers(0, 40, 2).astype(float)),
            tuple(rng.integers(0, 40, 2).astype(float)),
        )
        assert cells.crosses(*u, *w) == crosses_any(added, u, w)
        cells.add(ax, ay, bx, by)
        added.append((ax, ay, bx, by))
