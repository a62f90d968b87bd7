"""Spatial indexes: which segments may touch a given triangle or segment, which points lie
near a segment.

Uniform grids over segments and points, and boxes over runs of a chain's consecutive segments
(for long, dense segments that no uniform grid separates). Queries are conservative (they may
return extra segments, never miss one); the exact tests are done by the caller.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np


def _frame(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float, float]:
    """(x0, y0, width, height, extent) of a grid over the points; width and height at least
    1e-6 of the extent, so that a flat set still gets cells of some size."""
    if len(x) == 0:
        return 0.0, 0.0, 1.0, 1.0, 1.0
    x0, y0 = float(x.min()), float(y.min())
    width, height = float(x.max()) - x0, float(y.max()) - y0
    extent = max(width, height, 1e-300)
    return x0, y0, max(width, extent * 1e-6), max(height, extent * 1e-6), extent


def bucket_starts(cell: np.ndarray, cells: int) -> np.ndarray:
    """Where each of ``cells`` buckets starts among the items sorted by ``cell`` (values in
    [0, cells)), with ``cells + 1`` entries: counts added up, no search per bucket."""
    starts = np.zeros(cells + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell, minlength=cells), out=starts[1:])
    return starts


def _cell_size(width: float, height: float, cells: float) -> float:
    """Side of a square cell so that about ``cells`` cover width x height (no underflow)."""
    return float(np.sqrt(width) * np.sqrt(height) / np.sqrt(cells))


class SegmentGrid:
    """Segments ``(ax, ay) - (bx, by)`` bucketed into a uniform grid of about ``cells`` cells."""

    def __init__(
        self,
        ax: np.ndarray,
        ay: np.ndarray,
        bx: np.ndarray,
        by: np.ndarray,
        cells: int | None = None,
    ) -> None:
        count = len(ax)
        cells = max(1, count if cells is None else cells)
        self.x0, self.y0, width, height, extent = _frame(
            np.concatenate([ax, bx]), np.concatenate([ay, by])
        )
        size = _cell_size(width, height, cells)
        # cells no smaller than a typical segment, so that segments span few cells
        lengths = np.maximum(np.abs(bx - ax), np.abs(by - ay))
        if count:
            size = max(size, float(np.median(lengths)))
        if not size > 0:
            size = extent
        self.size = size
        self.nx = int(min(max(1, np.ceil(width / size)), 4096))
        self.ny = int(min(max(1, np.ceil(height / size)), 4096))
        self.size_x = width / self.nx
        self.size_y = height / self.ny
        # slack against rounding in the cell arithmetic (coordinates may be large)
        self.pad = 1e-9 * max(abs(self.x0), abs(self.y0), extent) + 1e-300
        ix0, ix1 = self._col(np.minimum(ax, bx)), self._col(np.maximum(ax, bx))
        iy0, iy1 = self._row(np.minimum(ay, by)), self._row(np.maximum(ay, by))
        spans_x = ix1 - ix0 + 1
        spans_y = iy1 - iy0 + 1
        per_segment = spans_x * spans_y
        seg = np.repeat(np.arange(count, dtype=np.int64), per_segment)
        offset = np.arange(len(seg), dtype=np.int64) - np.repeat(
            np.cumsum(per_segment) - per_segment, per_segment
        )
        sx = np.repeat(spans_x, per_segment)
        col = np.repeat(ix0, per_segment) + offset % sx
        row = np.repeat(iy0, per_segment) + offset // sx
        cell = row * self.nx + col
        order = np.argsort(cell, kind="stable")
        self.items = seg[order]
        self.starts = bucket_starts(cell, self.nx * self.ny)

    def _col(self, x: np.ndarray | float, pad: float = 0.0) -> np.ndarray:
        return np.clip(
            np.floor((np.asarray(x) - self.x0 + pad) / self.size_x), 0, self.nx - 1
        ).astype(np.int64)

    def _row(self, y: np.ndarray | float, pad: float = 0.0) -> np.ndarray:
        return np.clip(
            np.floor((np.asarray(y) - self.y0 + pad) / self.size_y), 0, self.ny - 1
        ).astype(np.int64)

    def _gather(self, rows: np.ndarray, col0: np.ndarray, col1: np.ndarray) -> np.ndarray:
        first = self.starts[rows * self.nx + col0]
        last = self.starts[rows * self.nx + col1 + 1]
        counts = last - first
        total = int(counts.sum())
        if total == 0:
            return np.zeros(0, dtype=np.int64)
        offsets = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
        return self.items[np.repeat(first, counts) + offsets]

    def _cell_x(self, x: float) -> int:
        return min(max(math.floor((x - self.x0) / self.size_x), 0), self.nx - 1)

    def _cell_y(self, y: float) -> int:
        return min(max(math.floor((y - self.y0) / self.size_y), 0), self.ny - 1)

    def query_box(self, xmin: float, ymin: float, xmax: float, ymax: float) -> np.ndarray:
        """Ids of segments in the cells that meet the closed box (may repeat ids)."""
        c0, c1 = self._cell_x(xmin - self.pad), self._cell_x(xmax + self.pad)
        r0, r1 = self._cell_y(ymin - self.pad), self._cell_y(ymax + self.pad)
        starts = self.starts
        if r0 == r1 and c0 == c1:
            cell = r0 * self.nx + c0
            return self.items[starts[cell] : starts[cell + 1]]
        if c1 - c0 < self.nx // 2 or r1 - r0 < 2:
            pieces = [
                self.items[starts[r * self.nx + c0] : starts[r * self.nx + c1 + 1]]
                for r in range(r0, r1 + 1)
            ]
            return np.concatenate(pieces)
        rows = np.arange(r0, r1 + 1)
        return self._gather(rows, np.full(len(rows), c0), np.full(len(rows), c1))

    def query_boxes(
        self, xmin: np.ndarray, ymin: np.ndarray, xmax: np.ndarray, ymax: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(query, item) pairs: the segments in the cells that meet each closed box k
        (:meth:`query_box` for many boxes at once; may repeat pairs)."""
        pad = self.pad
        c0, c1 = self._col(xmin, -pad), self._col(xmax, pad)
        r0, r1 = self._row(ymin, -pad), self._row(ymax, pad)
        spans = r1 - r0 + 1
        query = np.repeat(np.arange(len(xmin), dtype=np.int64), spans)
        row = np.repeat(r0, spans) + (
            np.arange(len(query), dtype=np.int64) - np.repeat(np.cumsum(spans) - spans, spans)
        )
        first = self.starts[row * self.nx + c0[query]]
        last = self.starts[row * self.nx + c1[query] + 1]
        counts = last - first
        total = int(counts.sum())
        offsets = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
        return np.repeat(query, counts), self.items[np.repeat(first, counts) + offsets]

    def query_segments(
        self, ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(query, item) pairs: the segments in the cells that each query segment
        ``(ax[k], ay[k]) - (bx[k], by[k])`` passes through (may repeat pairs), for many
        query segments at once."""
        pad = self.pad
        xmin, xmax = np.minimum(ax, bx), np.maximum(ax, bx)
        ymin, ymax = np.minimum(ay, by), np.maximum(ay, by)
        r0, r1 = self._row(ymin, -pad), self._row(ymax, pad)
        spans = r1 - r0 + 1
        query = np.repeat(np.arange(len(ax), dtype=np.int64), spans)
        row = np.repeat(r0, spans) + (
            np.arange(len(query), dtype=np.int64) - np.repeat(np.cumsum(spans) - spans, spans)
        )
        # the query's x-range within each row's band (its whole x-range within one row)
        band_lo = np.maximum(self.y0 + row * self.size_y - pad, ymin[query])
        band_hi = np.minimum(self.y0 + (row + 1) * self.size_y + pad, ymax[query])
        qax, qay, qbx, qby = ax[query], ay[query], bx[query], by[query]
        dy = qby - qay
        whole = (spans[query] == 1) | (dy == 0)
        with np.errstate(over="ignore", invalid="ignore"):
            slope = (qbx - qax) / np.where(whole, 1.0, dy)
            xl = qax + (band_lo - qay) * slope
            xh = qax + (band_hi - qay) * slope
        whole |= ~(np.isfinite(xl) & np.isfinite(xh))
        lo_x = np.where(whole, xmin[query], np.maximum(np.minimum(xl, xh), xmin[query]))
        hi_x = np.where(whole, xmax[query], np.minimum(np.maximum(xl, xh), xmax[query]))
        base = row * self.nx
        first = self.starts[base + self._col(lo_x, -pad)]
        last = self.starts[base + self._col(hi_x, pad) + 1]
        counts = last - first
        total = int(counts.sum())
        offsets = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
        return np.repeat(query, counts), self.items[np.repeat(first, counts) + offsets]

    def query_triangle(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Ids of segments in the cells that meet the closed triangle (or segment) with the
        corners ``(px[k], py[k])`` (may repeat ids)."""
        xs, ys = px.tolist(), py.tolist()
        xmin, xmax, ymin, ymax = min(xs), max(xs), min(ys), max(ys)
        c0, c1 = self._cell_x(xmin - self.pad), self._cell_x(xmax + self.pad)
        r0, r1 = self._cell_y(ymin - self.pad), self._cell_y(ymax + self.pad)
        if (c1 - c0 + 1) * (r1 - r0 + 1) <= 12 or r0 == r1 or c0 == c1:
            return self.query_box(xmin, ymin, xmax, ymax)
        # per row of cells, the x-extent of the triangle inside that row's band
        rows = np.arange(r0, r1 + 1)
        band_lo = np.maximum(self.y0 + rows * self.size_y - self.pad, ymin)
        band_hi = np.minimum(self.y0 + (rows + 1) * self.size_y + self.pad, ymax)
        ax = np.array(xs)[:, None]
        ay = np.array(ys)[:, None]
        bx = np.roll(ax, -1, axis=0)
        by = np.roll(ay, -1, axis=0)
        ylo, yhi = np.minimum(ay, by), np.maximum(ay, by)
        clip_lo = np.clip(band_lo, ylo, yhi)
        clip_hi = np.clip(band_hi, ylo, yhi)
        valid = (band_hi >= ylo) & (band_lo <= yhi)
        dy = by - ay
        flat = dy == 0
        slope = np.where(flat, 0.0, (bx - ax) / np.where(flat, 1.0, dy))
        xl = np.where(flat, np.minimum(ax, bx), ax + (clip_lo - ay) * slope)
        xh = np.where(flat, np.maximum(ax, bx), ax + (clip_hi - ay) * slope)
        lo_x = np.where(valid, np.minimum(xl, xh), np.inf).min(axis=0)
        hi_x = np.where(valid, np.maximum(xl, xh), -np.inf).max(axis=0)
        present = lo_x <= hi_x
        rows, lo_x, hi_x = rows[present], lo_x[present], hi_x[present]
        return self._gather(rows, self._col(lo_x, -self.pad), self._col(hi_x, self.pad))


class PointColumns:
    """Points bucketed into a uniform grid stored column by column, so that the points of one
    column within a range of rows are contiguous: finds the points near segments quickly even
    where long segments pass many dense clusters of points."""

    def __init__(self, px: np.ndarray, py: np.ndarray, per_point: float = 8.0) -> None:
        count = len(px)
        self.x0, self.y0, width, height, extent = _frame(px, py)
        size = _cell_size(width, height, max(1.0, count * per_point))
        if not size > 0:
            size = extent
        self.nx = int(min(max(1, np.ceil(width / size)), 8192))
        self.ny = int(min(max(1, np.ceil(height / size)), 8192))
        self.size_x = width / self.nx
        self.size_y = height / self.ny
        # slack against rounding in the cell arithmetic (coordinates may be large)
        self.pad = 1e-9 * max(abs(self.x0), abs(self.y0), extent) + 1e-300
        cell = self._col(px) * self.ny + self._row(py)
        self.order = np.argsort(cell, kind="stable")
        self.starts = bucket_starts(cell, self.nx * self.ny)

    def _col(self, x: np.ndarray) -> np.ndarray:
        return np.clip(np.floor((x - self.x0) / self.size_x), 0, self.nx - 1).astype(np.int64)

    def _row(self, y: np.ndarray) -> np.ndarray:
        return np.clip(np.floor((y - self.y0) / self.size_y), 0, self.ny - 1).astype(np.int64)

    def column_spans(self, ax: np.ndarray, bx: np.ndarray) -> np.ndarray:
        """How many columns each segment crosses (the entries of :meth:`segment_columns`)."""
        xmin, xmax = np.minimum(ax, bx), np.maximum(ax, bx)
        return self._col(xmax + self.pad) - self._col(xmin - self.pad) + 1

    def segment_columns(
        self, ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For every column a segment crosses: (segment, first, last) where points
        ``order[first:last]`` are those of that column in the rows the segment meets there
        (conservative: a point on the closed segment is never left out)."""
        pad = self.pad
        xmin, xmax = np.minimum(ax, bx), np.maximum(ax, bx)
        ymin, ymax = np.minimum(ay, by), np.maximum(ay, by)
        c0 = self._col(xmin - pad)
        spans = self.column_spans(ax, bx)
        segment = np.repeat(np.arange(len(ax), dtype=np.int64), spans)
        col = np.arange(len(segment), dtype=np.int64) - np.repeat(np.cumsum(spans) - spans, spans)
        col += c0[segment]
        # the segment's x-range within the column's band, and its y-range over that
        lo = np.maximum(self.x0 + col * self.size_x - pad, xmin[segment])
        hi = np.minimum(self.x0 + (col + 1) * self.size_x + pad, xmax[segment])
        sax, say, sbx, sby = ax[segment], ay[segment], bx[segment], by[segment]
        # segments narrower than a column use their whole y-range (no steep or infinite slope)
        upright = np.abs(sbx - sax) < self.size_x
        slope = (sby - say) / np.where(upright, 1.0, sbx - sax)
        y_lo = np.where(upright, ymin[segment], say + (lo - sax) * slope)
        y_hi = np.where(upright, ymax[segment], say + (hi - sax) * slope)
        bottom = np.maximum(np.minimum(y_lo, y_hi) - pad, ymin[segment] - pad)
        top = np.minimum(np.maximum(y_lo, y_hi) + pad, ymax[segment] + pad)
        base = col * self.ny
        first = self.starts[base + self._row(bottom)]
        last = self.starts[base + self._row(top) + 1]
        return segment, first, last


def box_distance2(box: tuple[float, ...], x: float, y: float) -> float:
    """Squared distance from (x, y) to a :class:`ChainBoxes` box's rectangle (at most the
    distance to any point in it)."""
    ox, oy, ux, uy, hu, hv = box[4:]
    dx, dy = x - ox, y - oy
    du = max(abs(ux * dx + uy * dy) - hu, 0.0)
    dv = max(abs(uy * dx - ux * dy) - hv, 0.0)
    return du * du + dv * dv


def _beyond(box: tuple[float, ...], ox: float, oy: float, limit: float) -> bool:
    """A :class:`ChainBoxes` box lies surely beyond the squared distance ``limit`` from
    (ox, oy): its axis-aligned box, then its rectangle."""
    x0, x1, y0, y1 = box[:4]
    dx, dy = max(x0 - ox, ox - x1, 0.0), max(y0 - oy, oy - y1, 0.0)
    return dx * dx + dy * dy > limit or box_distance2(box, ox, oy) > limit


# ChainBoxes.leaves_near: discs of a radius of at most this many grid cells use the grid
_GRID_DISC = 4.0


class ChainBoxes:
    """Bounding boxes over runs of consecutive segments of a chain of points.

    Segment i joins points i and i + 1 (0 <= i < m, for m + 1 points). Level 0 boxes cover
    ``leaf`` consecutive segments each, every higher level twice as many, up to one box over
    the whole chain. Each box is a rectangle aligned with the chord of its run (first to last
    point) plus its axis-aligned box: a run of long, nearly parallel segments (a comb of
    spikes) fits a thin rectangle, where an axis-aligned box would cover its neighbours too.
    Boxes are padded against rounding, so a test that finds a box apart from a shape is
    conservative.

    ``levels[l][k]`` is the box of segments ``[k * leaf * 2**l, (k + 1) * leaf * 2**l)`` (the
    last one shorter): ``(xmin, xmax, ymin, ymax, cx, cy, ux, uy, hu, hv)`` with centre
    (cx, cy), unit axis (ux, uy) along the chord, and half-widths hu along it and hv across.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, leaf: int = 8) -> None:
        m = len(x) - 1
        self.m = m
        self.leaf = leaf
        scale = float(max(np.abs(x).max(), np.abs(y).max())) if len(x) else 0.0
        # slack against rounding in the projections (coordinates may be large)
        self.pad = 1e-9 * scale + 1e-300
        self.levels: list[list[tuple[float, ...]]] = []
        self.sizes: list[int] = []
        self._leaf_grid: SegmentGrid | None = None  # see leaves_near
        self._leaf_cells: tuple[list[int], list[int]] = ([], [])
        size = leaf
        px, py = x[:m], y[:m]
        while m > 0:
            starts = np.arange(0, m, size)
            ends = np.minimum(starts + size, m)
            self.levels.append(self._boxes(x, y, px, py, starts, ends))
            self.sizes.append(size)
            if len(starts) == 1:
                break
            size *= 2

    def leaves_meeting(
        self, lo: int, hi: int, c: int, corners: tuple[float, float, float, float, float, float]
    ) -> Iterator[tuple[int, int]]:
        """The runs [start, end) of segment positions in [lo, hi) of the leaf boxes that may
        meet the closed counter-clockwise triangle ``corners``, which holds the points at the
        positions ``lo``, ``hi`` and ``c`` (as corners or inside: a box holding one meets it
        and is entered untested); the others by separating-axis tests on each box's
        rectangle (its two axes and the triangle's three side normals)."""
        return self._leaves(lo, hi, c, corners, None)

    def leaves_near(
        self, lo: int, hi: int, disc: tuple[float, float, float]
    ) -> Iterator[tuple[int, int]]:
        """The runs [start, end) of segment positions in [lo, hi) of the leaf boxes within
        the ``disc`` (centre x, centre y, squared radius). Every point of the chain in the
        disc then starts a segment of these runs or ends the last one before ``hi``.

        A small disc takes the leaves from a grid over their boxes (the cells its square
        meets) instead of a descent from the top: each leaf is tested as the descent tests it
        at its own level, in order, so the runs hold every leaf the descent yields (and
        perhaps one whose larger box it ruled out: the runs are conservative either way)."""
        ox, oy, limit = disc
        small = 0.0 <= limit <= _GRID_DISC * _GRID_DISC * self._grid_cell2()
        if not (small and math.isfinite(ox) and math.isfinite(oy)):
            return self._leaves(lo, hi, -1, None, disc)
        return self._leaves_in_grid(lo, hi, disc)

    def _grid_cell2(self) -> float:
        """The squared cell side of the grid over the leaf boxes, built on first use (with
        its buckets as Python lists: a query reads a few cells)."""
        if self._leaf_grid is None:
            x0, x1, y0, y1 = (np.array([box[i] for box in self.levels[0]]) for i in range(4))
            self._leaf_grid = SegmentGrid(x0, y0, x1, y1)
            self._leaf_cells = (self._leaf_grid.starts.tolist(), self._leaf_grid.items.tolist())
        grid = self._leaf_grid
        return min(grid.size_x, grid.size_y) ** 2

    def _leaves_in_grid(
        self, lo: int, hi: int, disc: tuple[float, float, float]
    ) -> Iterator[tuple[int, int]]:
        """:meth:`leaves_near` of a disc a few grid cells across."""
        ox, oy, limit = disc
        reach = math.sqrt(limit) * (1.0 + 1e-9) + self.pad
        grid = self._leaf_grid
        starts, items = self._leaf_cells
        pad = grid.pad
        c0, c1 = grid._cell_x(ox - reach - pad), grid._cell_x(ox + reach + pad)
        r0, r1 = grid._cell_y(oy - reach - pad), grid._cell_y(oy + reach + pad)
        found: set[int] = set()
        nx = grid.nx
        for row in range(r0, r1 + 1):
            base = row * nx
            found.update(items[starts[base + c0] : starts[base + c1 + 1]])
        leaf, boxes = self.leaf, self.levels[0]
        first, last = lo // leaf, (hi - 1) // leaf
        for k in sorted(found):
            if k < first or k > last:
                continue
            if _beyond(boxes[k], ox, oy, limit):
                continue
            start = k * leaf
            yield max(start, lo), min(start + leaf, hi)

    def _leaves(
        self,
        lo: int,
        hi: int,
        c: int,
        corners: tuple[float, float, float, float, float, float] | None,
        disc: tuple[float, float, float] | None,
    ) -> Iterator[tuple[int, int]]:
        """:meth:`leaves_meeting` (``corners``) or :meth:`leaves_near` (``disc``), found by
        descending the boxes."""
        levels, sizes, pad = self.levels, self.sizes, self.pad
        if disc is not None:
            ox, oy, limit = disc
        else:
            ax, ay, bx, by, cx, cy = corners
            xmin, xmax = min(ax, bx, cx), max(ax, bx, cx)
            ymin, ymax = min(ay, by, cy), max(ay, by, cy)
            # outward unit normals and offsets of the triangle's sides
            sides = []
            for px, py, qx, qy in ((ax, ay, bx, by), (bx, by, cx, cy), (cx, cy, ax, ay)):
                nx, ny = qy - py, px - qx
                norm = math.hypot(nx, ny)
                if norm > 0 and norm < math.inf:
                    nx, ny = nx / norm, ny / norm
                    sides.append((nx, ny, nx * px + ny * py + pad))
        if disc is not None:
            top = len(levels) - 1
            stack = [(top, k) for k in range(len(levels[top]) - 1, -1, -1)]
        else:
            # the boxes above the cover of [lo, hi) hold lo or hi: entered untested
            stack = self._cover(lo, hi)
        while stack:
            level, k = stack.pop()
            size = sizes[level]
            start = k * size
            end = start + size
            if end <= lo or start >= hi:
                continue
            if disc is not None:
                if _beyond(levels[level][k], ox, oy, limit):
                    continue
            elif not (level and (start <= c <= end or start <= lo or end >= hi)):
                x0, x1, y0, y1, px, py, ux, uy, hu, hv = levels[level][k]
                if x1 < xmin or x0 > xmax or y1 < ymin or y0 > ymax:
                    continue
                apart = False
                for nx, ny, offset in sides:
                    if (
                        nx * px
                        + ny * py
                        - hu * abs(nx * ux + ny * uy)
                        - hv * abs(ny * ux - nx * uy)
                        > offset
                    ):
                        apart = True
                        break
                if apart:
                    continue
                # the triangle's corners along the box's axes, from its centre
                da, db, dc = ax - px, bx - px, cx - px
                ea, eb, ec = ay - py, by - py, cy - py
                pa, pb, pc = ux * da + uy * ea, ux * db + uy * eb, ux * dc + uy * ec
                if (pa > hu and pb > hu and pc > hu) or (pa < -hu and pb < -hu and pc < -hu):
                    continue
                pa, pb, pc = ux * ea - uy * da, ux * eb - uy * db, ux * ec - uy * dc
                if (pa > hv and pb > hv and pc > hv) or (pa < -hv and pb < -hv and pc < -hv):
                    continue
            if level:
                child = 2 * k
                if child + 1 < len(levels[level - 1]):
                    stack.append((level - 1, child + 1))
                stack.append((level - 1, child))
                continue
            yield max(start, lo), min(end, hi)

    def _cover(self, lo: int, hi: int) -> list[tuple[int, int]]:
        """The largest boxes (level, k) whose leaves lie within those of the segment
        positions [lo, hi), last first (a stack that pops them in order)."""
        left: list[tuple[int, int]] = []
        right: list[tuple[int, int]] = []
        first, last = lo // self.leaf, (hi - 1) // self.leaf
        level = 0
        while first <= last:
            if first & 1:
                left.append((level, first))
                first += 1
            if not last & 1:
                right.append((level, last))
                last -= 1
            first >>= 1
            last >>= 1
            level += 1
        left.reverse()
        return right + left

    def _boxes(
        self,
        x: np.ndarray,
        y: np.ndarray,
        px: np.ndarray,
        py: np.ndarray,
        starts: np.ndarray,
        ends: np.ndarray,
    ) -> list[tuple[float, ...]]:
        pad = self.pad
        dx, dy = x[ends] - x[starts], y[ends] - y[starts]
        length = np.hypot(dx, dy)
        flat = ~(length > 0) | ~np.isfinite(length)
        ux = np.where(flat, 1.0, dx / np.where(flat, 1.0, length))
        uy = np.where(flat, 0.0, dy / np.where(flat, 1.0, length))
        node = np.repeat(np.arange(len(starts)), ends - starts)
        boxes = []
        for values, last in (
            (px, x[ends]),
            (py, y[ends]),
            (ux[node] * px + uy[node] * py, ux * x[ends] + uy * y[ends]),
            (ux[node] * py - uy[node] * px, ux * y[ends] - uy * x[ends]),
        ):
            low = np.minimum(np.minimum.reduceat(values, starts), last)
            high = np.maximum(np.maximum.reduceat(values, starts), last)
            boxes.append((low, high))
        (xmin, xmax), (ymin, ymax), (umin, umax), (vmin, vmax) = boxes
        cu, cv = (umin + umax) / 2, (vmin + vmax) / 2
        fields = (
            xmin - pad,
            xmax + pad,
            ymin - pad,
            ymax + pad,
            cu * ux - cv * uy,
            cu * uy + cv * ux,
            ux,
            uy,
            (umax - umin) / 2 + pad,
            (vmax - vmin) / 2 + pad,
        )
        return list(zip(*(field.tolist() for field in fields)))


def chunks(counts: np.ndarray, size: int) -> list[tuple[int, int]]:
    """Consecutive index ranges [lo, hi) of ``counts`` summing to about ``size`` each."""
    if len(counts) == 0:
        return []
    cumulative = np.cumsum(counts)
    cuts = np.searchsorted(cumulative, np.arange(size, int(cumulative[-1]), size)).tolist()
    bounds = sorted({0, *cuts, len(counts)})
    return list(zip(bounds[:-1], bounds[1:]))
