"""Rule "elevation" on long sub-polygons: candidates closest in elevation first, without
sorting every sub-polygon's positions again (docs/algorithm.md, section 5).

A node on the base (V1, V2) takes, among its correct candidates, the one whose z is closest
to the mean of z1 and z2 (float value |2 z - z1 - z2|, near-ties decided exactly). Testing
candidates in order of that value and stopping once every untested one is surely farther
than a correct one found gives the rule's choice. The order comes from *windows*: the
positions of a range sorted by z once, shared by every node whose range lies inside and is
at least an eighth of it; a node walks outwards from its target value in its window, band by
band, so its cost follows the candidates it looks at, not its size. Equal elevations keep
candidate order in a window, so that on plateaus (terraced elevations) the first correct one
of a level comes first and the rest of its level can be skipped. In pre-order the windows of
finished subtrees are never needed again, so they form a stack.
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
        # (lo, hi, positions lo < p < hi sorted by z (stable, candidate order among equal
        # ones), 2 z of those, largest |z|)
        self._stack: list[tuple[int, int, np.ndarray, np.ndarray, float]] = []

    def _window(self, lo: int, hi: int) -> tuple[int, int, np.ndarray, np.ndarray, float]:
        stack = self._stack
        while stack and not (stack[-1][0] <= lo and hi <= stack[-1][1]):
            stack.pop()
        if stack and stack[-1][1] - stack[-1][0] <= _SPREAD * (hi - lo):
            return stack[-1]
        # in candidate order (decreasing), which the stable sort keeps among equal z
        positions = np.arange(hi - 1, lo, -1, dtype=np.int64)
        values = self.z[positions]
        order = np.argsort(values, kind="stable")
        doubled = 2.0 * values[order]
        window = (lo, hi, positions[order], doubled, float(np.abs(values).max()))
        stack.append(window)
        return window

    def bands(self, lo: int, hi: int, target: float) -> Iterator[tuple[np.ndarray, float]]:
        """Bands of the candidates lo < p < hi by closeness of 2 z to ``target`` (z1 + z2):
        per band the candidates (in no particular order) and a lower bound of
        |2 z - target| (the same float value) for every candidate of the later bands."""
        _, _, order, doubled, _ = self._window(lo, hi)
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

    def widest_z(self, lo: int, hi: int) -> float:
        """The largest |z| of the window serving the range lo .. hi."""
        return self._window(lo, hi)[4]
