"""A meandering band with islands: the long thin polygons of the rule-first shortcut tests."""

from __future__ import annotations

import numpy as np


def river(
    half: int,
    islands: int,
    seed: int,
    grid: float = 0.0,
    wiggle: float = 0.05,
    spread: float = 0.6,
) -> list[np.ndarray]:
    """A meandering band (``half`` vertices per bank, each off the bank by up to ``wiggle``
    of the half width: 0.4 makes the banks saw-tooth, vertices in whose crevices see little
    but the far bank) with small star islands in it, their centres up to ``spread`` of the
    half width off the centre line; ``grid`` > 0 rounds every coordinate to that step
    (collinear and repeated positions)."""
    rng = np.random.default_rng(seed)
    length, width = 4000.0, 100.0
    t = np.linspace(0.0, 1.0, half)
    mid_x, mid_y = length * t, 0.1 * length * np.sin(2 * np.pi * 3 * t)
    dx, dy = np.gradient(mid_x), np.gradient(mid_y)
    norm = np.hypot(dx, dy)
    nx, ny = -dy / norm, dx / norm
    off = 1.0 + wiggle * rng.uniform(-1, 1, (2, half))
    left = np.column_stack([mid_x + nx * width / 2 * off[0], mid_y + ny * width / 2 * off[0]])
    right = np.column_stack([mid_x - nx * width / 2 * off[1], mid_y - ny * width / 2 * off[1]])
    rings = [np.concatenate([right, left[::-1]])]
    for at in np.linspace(0.05, 0.95, islands):
        index = int(at * (half - 1))
        offset = rng.uniform(-spread, spread) * width / 2
        cx, cy = mid_x[index] + nx[index] * offset, mid_y[index] + ny[index] * offset
        count = int(rng.integers(4, 12))
        angles = -np.linspace(0.0, 2 * np.pi, count, endpoint=False) + rng.uniform(0, 1)
        radius = width * rng.uniform(0.04, 0.12)
        rings.append(np.column_stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)]))
    if grid:
        rings = [np.round(ring / grid) * grid for ring in rings]
    return rings
