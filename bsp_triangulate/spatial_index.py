"""Uniform grid over segments: which segments may touch a given triangle or segment.

Queries are conservative (they may return extra segments, never miss one); the exact tests
are done by the caller on the returned candidates.
"""

from __future__ import annotations

import numpy as np


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
        allx = np.concatenate([ax, bx])
        ally = np.concatenate([ay, by])
        self.x0 = float(allx.min()) if count else 0.0
        self.y0 = float(ally.min()) if count else 0.0
        width = (float(allx.max()) - self.x0) if count else 1.0
        height = (float(ally.max()) - self.y0) if count else 1.0
        extent = max(width, height, 1e-300)
        width = max(width, extent * 1e-6)
        height = max(height, extent * 1e-6)
        size = float(np.sqrt(width * height / cells))
        # cells no smaller than a typical segment, so that segments span few cells
        lengths = np.maximum(np.abs(bx - ax), np.abs(by - ay))
        if count:
            size = max(size, float(np.median(lengths)))
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
        self.starts = np.searchsorted(cell[order], np.arange(self.nx * self.ny + 1))

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

    def query_box(self, xmin: float, ymin: float, xmax: float, ymax: float) -> np.ndarray:
        """Ids of segments in the cells that meet the closed box (may repeat ids)."""
        c0 = int(self._col(xmin, -self.pad))
        c1 = int(self._col(xmax, self.pad))
        r0 = int(self._row(ymin, -self.pad))
        r1 = int(self._row(ymax, self.pad))
        if r0 == r1 and c0 == c1:
            cell = r0 * self.nx + c0
            return self.items[self.starts[cell] : self.starts[cell + 1]]
        rows = np.arange(r0, r1 + 1)
        return self._gather(rows, np.full(len(rows), c0), np.full(len(rows), c1))

    def query_triangle(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Ids of segments in the cells that meet the closed triangle (or segment) with the
        corners ``(px[k], py[k])`` (may repeat ids)."""
        xmin, xmax = float(px.min()), float(px.max())
        ymin, ymax = float(py.min()), float(py.max())
        c0 = int(self._col(xmin, -self.pad))
        c1 = int(self._col(xmax, self.pad))
        r0 = int(self._row(ymin, -self.pad))
        r1 = int(self._row(ymax, self.pad))
        if (c1 - c0 + 1) * (r1 - r0 + 1) <= 9 or r0 == r1:
            return self.query_box(xmin, ymin, xmax, ymax)
        # per row of cells, the x-extent of the triangle inside that row's band
        rows = np.arange(r0, r1 + 1)
        band_lo = np.maximum(self.y0 + rows * self.size_y - self.pad, ymin)
        band_hi = np.minimum(self.y0 + (rows + 1) * self.size_y + self.pad, ymax)
        lo_x = np.full(len(rows), np.inf)
        hi_x = np.full(len(rows), -np.inf)
        for k in range(len(px)):
            k2 = (k + 1) % len(px)
            xa, ya, xb, yb = float(px[k]), float(py[k]), float(px[k2]), float(py[k2])
            ylo, yhi = min(ya, yb), max(ya, yb)
            clip_lo = np.clip(band_lo, ylo, yhi)
            clip_hi = np.clip(band_hi, ylo, yhi)
            valid = (band_hi >= ylo) & (band_lo <= yhi)
            if ya == yb:
                xs_lo = np.full(len(rows), min(xa, xb))
                xs_hi = np.full(len(rows), max(xa, xb))
            else:
                slope = (xb - xa) / (yb - ya)
                xl = xa + (clip_lo - ya) * slope
                xh = xa + (clip_hi - ya) * slope
                xs_lo = np.minimum(xl, xh)
                xs_hi = np.maximum(xl, xh)
            lo_x = np.where(valid, np.minimum(lo_x, xs_lo), lo_x)
            hi_x = np.where(valid, np.maximum(hi_x, xs_hi), hi_x)
        present = lo_x <= hi_x
        rows, lo_x, hi_x = rows[present], lo_x[present], hi_x[present]
        return self._gather(rows, self._col(lo_x, -self.pad), self._col(hi_x, self.pad))
