"""Points that several rings share, found for all rings at once (islands touching a ring are
joined first, docs/algorithm.md section 2)."""

from __future__ import annotations

import numpy as np


def point_numbers(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per vertex, the number of its point: vertices with equal x and y (-0.0 equal to 0.0,
    as in comparisons) share one, numbered in the order of x, then y."""
    # adding 0.0 turns -0.0 into 0.0, so equal points sort together
    px, py = x + 0.0, y + 0.0
    order = np.lexsort((py, px))
    sx, sy = px[order], py[order]
    fresh = np.ones(len(order), dtype=bool)
    fresh[1:] = (sx[1:] != sx[:-1]) | (sy[1:] != sy[:-1])
    numbers = np.empty(len(order), dtype=np.int64)
    numbers[order] = np.cumsum(fresh) - 1
    return numbers


def touching_islands(numbers: np.ndarray, rings: list[np.ndarray]) -> list[list[int]]:
    """Per ring (slot in ``rings``, 0 the outer ring), the islands (slots from 1) other than
    itself that share a point with it (``numbers``: :func:`point_numbers`), in slot order."""
    partners: list[list[int]] = [[] for _ in rings]
    if len(rings) < 2:
        return partners
    lengths = np.fromiter((len(r) for r in rings), dtype=np.int64, count=len(rings))
    slot = np.repeat(np.arange(len(rings), dtype=np.int64), lengths)
    point = numbers[np.concatenate(rings)]
    # each (point, ring) pair once, grouped by point
    pairs = np.unique(point * len(rings) + slot)
    point, slot = pairs // len(rings), pairs % len(rings)
    starts = np.flatnonzero(np.r_[True, point[1:] != point[:-1]])
    sizes = np.diff(np.r_[starts, len(point)])
    shared = set()
    for start, size in zip(starts[sizes > 1].tolist(), sizes[sizes > 1].tolist()):
        group = slot[start : start + size].tolist()
        shared.update((a, b) for a in group for b in group if a != b and b > 0)
    for a, b in sorted(shared):
        partners[a].append(b)
    return partners
