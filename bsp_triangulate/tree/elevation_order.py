"""Rule "elevation" on long sub-polygons: candidates closest in elevation first, without
sorting every sub-polygon's positions again (docs/algorithm.md, section 5).

A node on the base (V1, V2) takes, among its correct candidates, the one whose z is closest
to the mean of z1 and z2 (float value |2 z - z1 - z2|, near-ties decided exactly). Testing
candidates in order of that value and stopping once every untested one is surely farther
than a correct one found gives the rule's choice. The order comes from *windows*: the
positions of a range sorted by z once, shared by every node whose range lies inside and is
at least an eighth of it; a node walks outwards from its target value in its window, band by
band, so its cost follows the candidates it looks at, not its size. In pre-order the windows
of finished subtrees are never needed again, so they form a stack.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

# a node uses a window at most this many times its own range
_SPREAD = 8
# positions taken from each side of the target value in a node's first band (then doubling)
_FIRST_BAND = 16


class ElevationWindows:
    """Windows over the positions of one sequence with elevations ``z`` (per position)."""

    def __init__(self, z: np.ndarray) -> None:
        self.z = z
        # (lo, hi, positions lo < p < hi sorted by z (stable), 2 z of those, largest |z|,
        # distinct values)
        self._stack: list[tuple[int, int, np.ndarray, np.ndarray, float, int]] = []

    def _window(self, lo: int, hi: int) -> tuple[int, int, np.ndarray, np.ndarray, float, int]:
        stack = self._stack
        while stack and not (stack[-1][0] <= lo and hi <= stack[-1][1]):
            stack.pop()
        if stack and stack[-1][1] - stack[-1][0] <= _SPREAD * (hi - lo):
            return stack[-1]
        positions = np.arange(lo + 1, hi, dtype=np.int64)
        values = self.z[positions]
        order = np.argsort(values, kind="stable")
        doubled = 2.0 * values[order]
        distinct = 1 + int(np.count_nonzero(doubled[1:] != doubled[:-1]))
        window = (lo, hi, positions[order], doubled, float(np.abs(values).max()), distinct)
        stack.append(window)
        return window

    def bands(self, lo: int, hi: int, target: float) -> Iterator[tuple[np.ndarray, float]]:
        """Bands of the candidates lo < p < hi by closeness of 2 z to ``target`` (z1 + z2):
        per band the candidates (in no particular order) and a lower bound of
        |2 z - target| (the same float value) for every candidate of the later bands."""
        _, _, order, doubled, _, _ = self._window(lo, hi)
        right = int(np.searchsorted(doubled, target))
        left = right  # the band is [left, right) of the window's order, growing both ways
        size = _FIRST_BAND
        count = len(order)
        while left > 0 or right < count:
            new_left, new_right = max(left - size, 0), min(right + size, count)
            picked = np.concatenate([order[new_left:left], order[right:new_right]])
            left, right = new_left, new_right
            size *= 2
            floor = np.inf
            if left > 0:
                floor = abs(float(doubled[left - 1]) - target)
            if right < count:
                floor = min(floor, abs(float(doubled[right]) - target))
            inside = picked[(picked > lo) & (picked < hi)]
            yield inside, floor

    def mostly_distinct(self, lo: int, hi: int) -> bool:
        """At least half the elevations of the window serving lo .. hi differ (equal ones
        cannot be told apart by closeness: a plateau is better tested in candidate order)."""
        window = self._window(lo, hi)
        return 2 * window[5] >= len(window[2])

    def widest_z(self, lo: int, hi: int) -> float:
        """The largest |z| of the window serving the range lo .. hi."""
        return self._window(lo, hi)[4]
