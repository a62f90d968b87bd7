"""The bridges made so far, bucketed by grid cell as they are made: which of them crosses a
new segment is asked once per island, so the answer must not cost all of them."""

from __future__ import annotations

import math

from .predicates import orient

# a bridge or segment whose bounding box spans more cells than this is not bucketed: such
# bridges are tested against every segment, such segments against every bridge
_MANY_CELLS = 16


class BridgeCells:
    """Segments (bridges) in the cells of a uniform grid (origin ``x0``, ``y0``, cell sizes
    ``size_x``, ``size_y``) that their bounding boxes meet."""

    def __init__(self, x0: float, y0: float, size_x: float, size_y: float) -> None:
        self.x0, self.y0 = x0, y0
        usable = 0 < size_x < math.inf and 0 < size_y < math.inf
        self.size_x, self.size_y = (size_x, size_y) if usable else (math.inf, math.inf)
        self.segments: list[tuple[float, float, float, float]] = []
        self.cells: dict[tuple[int, int], list[int]] = {}
        self.long: list[int] = []

    def _span(self, ax: float, ay: float, bx: float, by: float) -> tuple[int, int, int, int]:
        """Columns and rows (first, last) of the cells the box of a-b meets. Monotone in the
        coordinates, so two boxes that meet share a cell."""
        if self.size_x == math.inf:
            return 0, 0, 0, 0
        return (
            math.floor((min(ax, bx) - self.x0) / self.size_x),
            math.floor((max(ax, bx) - self.x0) / self.size_x),
            math.floor((min(ay, by) - self.y0) / self.size_y),
            math.floor((max(ay, by) - self.y0) / self.size_y),
        )

    def add(self, ax: float, ay: float, bx: float, by: float) -> None:
        number = len(self.segments)
        self.segments.append((ax, ay, bx, by))
        c0, c1, r0, r1 = self._span(ax, ay, bx, by)
        if (c1 - c0 + 1) * (r1 - r0 + 1) > _MANY_CELLS:
            self.long.append(number)
            return
        cells = self.cells
        for col in range(c0, c1 + 1):
            for row in range(r0, r1 + 1):
                cells.setdefault((col, row), []).append(number)

    def crosses(self, ux: float, uy: float, wx: float, wy: float) -> bool:
        """Some segment added crosses the segment u-w in both open interiors (exact)."""
        c0, c1, r0, r1 = self._span(ux, uy, wx, wy)
        if (c1 - c0 + 1) * (r1 - r0 + 1) > _MANY_CELLS:
            near: list[int] | set[int] = range(len(self.segments))  # type: ignore[assignment]
        else:
            near = set(self.long)
            cells = self.cells
            for col in range(c0, c1 + 1):
                for row in range(r0, r1 + 1):
                    near.update(cells.get((col, row), ()))
        xmin, xmax, ymin, ymax = min(ux, wx), max(ux, wx), min(uy, wy), max(uy, wy)
        segments = self.segments
        for number in near:
            ax, ay, bx, by = segments[number]
            if max(ax, bx) < xmin or min(ax, bx) > xmax or max(ay, by) < ymin or min(ay, by) > ymax:
                continue
            if orient(ux, uy, wx, wy, ax, ay) * orient(ux, uy, wx, wy, bx, by) >= 0:
                continue
            if orient(ax, ay, bx, by, ux, uy) * orient(ax, ay, bx, by, wx, wy) < 0:
                return True
        return False
