"""Interior points: parse them, keep those strictly inside the polygon, join them as islands.

Each kept point becomes a one-point island (docs/algorithm.md, "Interior points"). Its
classification is exact: a crossing count of a horizontal ray against the ring edges whose
y-range holds the point, with the exact signs of :mod:`.predicates`.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Protocol

import numpy as np

from ..triangulation import TriangulationError
from .predicates import compare_sq_distances_many, orient_many, sq_distance_exact
from .rings_batch import ragged_index
from .spatial_index import SegmentGrid, bucket_starts, chunks

# (edge, point) pairs tested at once: bounds the memory of the vectorised tests
_PAIR_CHUNK = 1 << 18


def as_point_array(points: object) -> np.ndarray:
    """The given interior points as an (m, 3) float64 array (z = 0 where absent)."""
    if points is None:
        return np.zeros((0, 3))
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TriangulationError(f"points: not an array of numeric points ({exc})") from None
    if array.size == 0:
        return np.zeros((0, 3))
    if array.ndim != 2 or array.shape[1] not in (2, 3):
        raise TriangulationError(
            f"points: expected an (m, 2) or (m, 3) array, got shape {array.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(array).all(axis=1))
    if len(bad):
        raise TriangulationError(f"point {int(bad[0]) + 1}: coordinates are not finite")
    if array.shape[1] == 2:
        return np.column_stack([array, np.zeros(len(array))])
    return np.ascontiguousarray(array)


def first_occurrences(
    px: np.ndarray, py: np.ndarray, group: np.ndarray | None = None
) -> np.ndarray:
    """Mask of the points that do not repeat an earlier point (equal x and y; with
    ``group``, one key per point, an earlier point of the same group)."""
    keep = np.ones(len(px), dtype=bool)
    if len(px) < 2:
        return keep
    # lexsort is stable: equal points stay in the order given, the first one first
    order = np.lexsort((py, px) if group is None else (py, px, group))
    sx, sy = px[order], py[order]
    repeat = (sx[1:] == sx[:-1]) & (sy[1:] == sy[:-1])
    if group is not None:
        sorted_group = group[order]
        repeat &= sorted_group[1:] == sorted_group[:-1]
    keep[order[1:][repeat]] = False
    return keep


def strictly_inside(
    x: np.ndarray, y: np.ndarray, rings: list[np.ndarray], px: np.ndarray, py: np.ndarray
) -> np.ndarray:
    """Mask of the points (px, py) strictly inside the polygon of ``rings`` (vertex ids into
    ``x``, ``y``): an odd number of ring edges crosses the ray to their right, and none of
    the edges holds them (end points included). Exact."""
    odd, boundary = _ray_parity(x, y, rings, px, py)
    return odd & ~boundary


def strictly_outside(
    x: np.ndarray, y: np.ndarray, rings: list[np.ndarray], px: np.ndarray, py: np.ndarray
) -> np.ndarray:
    """Mask of the points (px, py) strictly outside the polygon of ``rings``: an even number
    of ring edges crosses the ray to their right, and none holds them. Exact."""
    odd, boundary = _ray_parity(x, y, rings, px, py)
    return ~odd & ~boundary


def _ray_parity(
    x: np.ndarray, y: np.ndarray, rings: list[np.ndarray], px: np.ndarray, py: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per point (px, py): an odd number of the edges of ``rings`` crosses the ray to its
    right (half-open in y), and an edge holds it (end points included). Exact."""
    count = len(px)
    if count == 0 or not rings:
        return np.zeros(count, dtype=bool), np.zeros(count, dtype=bool)
    starts = np.concatenate(rings)
    ends = np.concatenate([np.roll(r, -1) for r in rings])
    ax, ay, bx, by = x[starts], y[starts], x[ends], y[ends]
    # the points in y order: each edge meets those of a contiguous run
    order = np.argsort(py, kind="stable")
    sorted_y = py[order]
    first = np.searchsorted(sorted_y, np.minimum(ay, by), side="left")
    last = np.searchsorted(sorted_y, np.maximum(ay, by), side="right")
    spans = last - first
    crossings = np.zeros(count, dtype=np.int64)
    boundary = np.zeros(count, dtype=bool)
    for lo, hi in chunks(spans, _PAIR_CHUNK):
        part = spans[lo:hi]
        total = int(part.sum())
        if total == 0:
            continue
        edge = np.repeat(np.arange(lo, hi), part)
        offsets = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(part) - part, part)
        point = order[np.repeat(first[lo:hi], part) + offsets]
        qx, qy = px[point], py[point]
        eax, eay, ebx, eby = ax[edge], ay[edge], bx[edge], by[edge]
        # only pairs with the point left of the edge's right end can cross or touch
        near = qx <= np.maximum(eax, ebx)
        edge, point, qx, qy = edge[near], point[near], qx[near], qy[near]
        eax, eay, ebx, eby = eax[near], eay[near], ebx[near], eby[near]
        side = orient_many(eax, eay, ebx, eby, qx, qy)
        on = (side == 0) & (qx >= np.minimum(eax, ebx))
        boundary[point[on]] = True
        # half-open rule: an edge counts when exactly one end lies above the point's line
        upward = (eay <= qy) & (eby > qy)
        downward = (eby <= qy) & (eay > qy)
        crossing = (upward & (side > 0)) | (downward & (side < 0))
        crossings += np.bincount(point[crossing], minlength=count)
    return crossings % 2 == 1, boundary


class Bridging(Protocol):
    """What the point bridges need of ``bridges._Bridger`` (the sequence being built)."""

    x: np.ndarray
    y: np.ndarray
    points: SegmentGrid  # every vertex, as zero-length segments
    point_ids: np.ndarray
    in_seq: np.ndarray
    edges: SegmentGrid  # the ring edges
    edge_a: np.ndarray
    edge_b: np.ndarray

    def earliest(self, nodes: list[int]) -> int: ...

    def _valid_occurrences(self, vid: int, island: np.ndarray, h_index: int) -> list[int]: ...


def delaunay_point_bridge(bridger: Bridging, h: int, more: int = 8) -> tuple[int, int] | None:
    """(node, vertex id) of a bridge from the one-point island ``h`` that is a constrained
    Delaunay edge of the rings, or None (the point waits for other islands).

    The targets of section 2 are tried nearest first (float distance), up to ``more`` of
    them after the nearest valid one. Target ``v`` is taken when no vertex strictly inside
    the circle with diameter h-v is visible from ``h``: then none is visible from the
    segment's interior either (such a vertex would leave one visible from ``h`` in the same
    circle), so that circle proves h-v a constrained Delaunay edge.
    """
    x, y = bridger.x, bridger.y
    hx, hy = float(x[h]), float(y[h])
    grid = bridger.points
    radius = max(grid.size_x, grid.size_y)
    full = max(grid.size_x * grid.nx, grid.size_y * grid.ny) * 2.0 + radius
    island = np.array([h], dtype=np.int64)
    seen: set[int] = set()
    budget = None  # targets left to try once the nearest valid one has failed
    while True:
        found = bridger.point_ids[
            np.unique(grid.query_box(hx - radius, hy - radius, hx + radius, hy + radius))
        ]
        found = found[bridger.in_seq[found]]
        d2 = (x[found] - hx) ** 2 + (y[found] - hy) ** 2
        # within the box's inscribed circle the distance order is final
        inner = d2 <= radius * radius
        if radius >= full:
            inner[:] = True
        for idx in np.argsort(d2, kind="stable").tolist():
            vid = int(found[idx])
            if not inner[idx]:
                break
            if vid in seen:
                continue
            seen.add(vid)
            if budget is not None:
                budget -= 1
                if budget < 0:
                    return None
            ks = bridger._valid_occurrences(vid, island, 0)
            if not ks:
                continue
            if _disk_hidden(bridger, h, vid):
                return bridger.earliest(ks), vid
            if budget is None:
                budget = more
        if radius >= full:
            return None
        radius *= 2.0


def _disk_hidden(bridger: Bridging, h: int, v: int) -> bool:
    """Every vertex strictly inside the circle with diameter h-v is hidden from ``h``: some
    ring edge crosses the segment to it properly (touching does not count: conservative)."""
    x, y = bridger.x, bridger.y
    hx, hy, vx, vy = float(x[h]), float(y[h]), float(x[v]), float(y[v])
    mx, my = 0.5 * (hx + vx), 0.5 * (hy + vy)
    r = 0.5 * float(np.hypot(vx - hx, vy - hy)) * (1 + 1e-9)
    found = bridger.point_ids[np.unique(bridger.points.query_box(mx - r, my - r, mx + r, my + r))]
    wx, wy = x[found], y[found]
    dot = (wx - hx) * (wx - vx) + (wy - hy) * (wy - vy)
    scale = np.abs(wx - hx) * np.abs(wx - vx) + np.abs(wy - hy) * np.abs(wy - vy)
    # scale 0 (w is h or v, or on an axis line through one): dot is exactly 0
    unsure = (np.abs(dot) <= 8.0 * 2.0**-53 * scale + 1e-300) & (scale > 0)
    inside = found[(dot < 0) & ~unsure].tolist()
    ahx, ahy, avx, avy = Fraction(hx), Fraction(hy), Fraction(vx), Fraction(vy)
    for w in found[unsure].tolist():
        fx, fy = Fraction(float(x[w])), Fraction(float(y[w]))
        if (fx - ahx) * (fx - avx) + (fy - ahy) * (fy - avy) < 0:
            inside.append(w)
    return all(_crossed(bridger, h, w) for w in inside)


def _crossed(bridger: Bridging, u: int, w: int) -> bool:
    """Some ring edge crosses the segment u-w properly (a single point, interior to both)."""
    x, y = bridger.x, bridger.y
    ux, uy, wx, wy = x[u], y[u], x[w], y[w]
    found = bridger.edges.query_triangle(np.array([ux, wx]), np.array([uy, wy]))
    a, b = bridger.edge_a[found], bridger.edge_b[found]
    if len(a) == 0:
        return False
    o1 = orient_many(ux, uy, wx, wy, x[a], y[a])
    o2 = orient_many(ux, uy, wx, wy, x[b], y[b])
    straddle = (o1.astype(np.int16) * o2) < 0
    if not straddle.any():
        return False
    a, b = a[straddle], b[straddle]
    o3 = orient_many(x[a], y[a], x[b], y[b], ux, uy)
    o4 = orient_many(x[a], y[a], x[b], y[b], wx, wy)
    return bool(((o3.astype(np.int16) * o4) < 0).any())


# relative margin within which float squared distances are re-compared exactly (the float
# values are within a few units in the last place of the exact ones)
_TIE_MARGIN = 1e-9


# up to this many candidates, exact integer keys in Python (less set-up than numpy)
_FEW_PAIRS = 128
# all pairs of a group are compared at once while there are at most this many per candidate
_ALL_PAIRS = 16


def _least_exact(
    group: np.ndarray, a: np.ndarray, b: np.ndarray, x: np.ndarray, y: np.ndarray
) -> np.ndarray:
    """For the pairs of vertex ids (a[i], b[i]) sorted by ``group`` (then in tie order): the
    position of each group's pair with the least exact squared distance, the first among
    equal ones; one per group, in group order."""
    count = len(group)
    starts = np.flatnonzero(np.concatenate([[True], group[1:] != group[:-1]]))
    sizes = np.diff(np.append(starts, count))
    if count <= _FEW_PAIRS:
        # few: exact integer keys in Python cost less than the vectorised test's set-up
        keys = [
            sq_distance_exact(*coordinates)
            for coordinates in zip(x[a].tolist(), y[a].tolist(), x[b].tolist(), y[b].tolist())
        ]
        ends = (starts + sizes).tolist()
        return np.array(
            [min(range(lo, hi), key=keys.__getitem__) for lo, hi in zip(starts.tolist(), ends)],
            dtype=np.int64,
        )
    owner = np.repeat(np.arange(len(starts)), sizes)
    if int((sizes * sizes).sum()) <= _ALL_PAIRS * count:
        # small groups: every pair (i, j), i before j, compared at once; the one that never
        # loses wins (a loser is farther, or as far and later)
        span = sizes[owner]
        i = np.repeat(np.arange(count), span)
        j = ragged_index(starts[owner], span)
        i, j = i[i < j], j[i < j]
        sign = compare_sq_distances_many(
            x[a[i]], y[a[i]], x[b[i]], y[b[i]], x[a[j]], y[a[j]], x[b[j]], y[b[j]]
        )
        lost = np.zeros(count, dtype=bool)
        lost[i[sign > 0]] = True
        lost[j[sign <= 0]] = True
        return np.flatnonzero(~lost)
    # large groups: a knockout, one round per rank in the groups
    best = starts.copy()
    rank = np.arange(count) - starts[owner]
    by_rank = np.argsort(rank, kind="stable")
    bounds = np.searchsorted(rank[by_rank], np.arange(int(sizes.max()) + 1))
    for k in range(1, len(bounds) - 1):
        challenger = by_rank[bounds[k] : bounds[k + 1]]
        g = owner[challenger]
        current = best[g]
        ca, cb, ba, bb = a[challenger], b[challenger], a[current], b[current]
        sign = compare_sq_distances_many(x[ca], y[ca], x[cb], y[cb], x[ba], y[ba], x[bb], y[bb])
        better = sign < 0
        best[g[better]] = challenger[better]
    return best


def nearest_vertices(
    x: np.ndarray, y: np.ndarray, ids: np.ndarray, queries: np.ndarray
) -> np.ndarray:
    """For each vertex id of ``queries``, the nearest other vertex among ``ids`` (exact
    squared distance, ties to the smallest id; -1 when there is none)."""
    return VertexGrid(x, y, ids).nearest(queries)[0]


# VertexGrid: vertices per occupied cell above which the cells are made finer, and the cells
# per vertex they may reach
_PER_CELL = 8
_CELLS_PER_VERTEX = 16
_MOST_FINER = 1 << 12


class VertexGrid:
    """A uniform grid over the vertex ids ``ids``, built once for many nearest searches."""

    def __init__(self, x: np.ndarray, y: np.ndarray, ids: np.ndarray) -> None:
        self.x, self.y = x, y
        self.empty = True  # fewer than two vertices, or all at one place
        if len(ids) < 2:
            return
        ids = np.sort(ids)
        vx, vy = x[ids], y[ids]
        x0, y0 = float(vx.min()), float(vy.min())
        width, height = float(vx.max()) - x0, float(vy.max()) - y0
        extent = max(width, height)
        if not extent > 0:
            return
        self.empty = False
        cell = max(np.sqrt(width * height / len(ids)), extent / len(ids), extent / 4096)
        # reaches (in cells) are those of this first cell size, whatever the cells become:
        # nearest() covers the grid, or stops at its max_reach, at the same distances
        self.finer = 1
        self.cover_reach = max(int(width // cell) + 1, int(height // cell) + 1)
        while True:
            nx = int(width // cell) + 1
            ny = int(height // cell) + 1
            col = np.minimum((vx - x0) // cell, nx - 1).astype(np.int64)
            row = np.minimum((vy - y0) // cell, ny - 1).astype(np.int64)
            key = row * nx + col
            # clustered vertices (a town in a wide frame): where the occupied cells hold
            # many, cells of half the size (the searches from dense ones end sooner), within
            # a bound on the cells per vertex
            finer = 4 * nx * ny <= _CELLS_PER_VERTEX * len(ids) and cell / 2 > extent / 4096
            finer = finer and math.isfinite(cell) and self.finer < _MOST_FINER
            if not finer or len(ids) <= _PER_CELL * len(np.unique(key)):
                break
            cell /= 2
            self.finer *= 2
        self.cover_reach *= self.finer
        order = np.argsort(key, kind="stable")
        self.sorted_ids = ids[order]
        self.starts = bucket_starts(key, nx * ny)
        self.x0, self.y0, self.cell, self.nx, self.ny = x0, y0, cell, nx, ny
        # the cell arithmetic's rounding: a few units in the last place of the coordinates
        self.pad = 2.0**-48 * max(abs(x0), abs(y0), abs(x0 + width), abs(y0 + height))

    def pairs_in_boxes(
        self,
        xmin: np.ndarray,
        ymin: np.ndarray,
        xmax: np.ndarray,
        ymax: np.ndarray,
        wanted: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(box index, vertex id) of the vertices in the cells under each box whose flag in
        ``wanted`` is set (finite boxes only): a superset of those in the box, which the
        caller tests."""
        none = np.zeros(0, dtype=np.int64)
        if self.empty or not wanted.any():
            return none, none
        x0, y0, cell, nx, ny, pad = self.x0, self.y0, self.cell, self.nx, self.ny, self.pad
        index = np.flatnonzero(wanted)
        xmin, ymin, xmax, ymax = xmin[index], ymin[index], xmax[index], ymax[index]
        lo_col = np.clip((xmin - pad - x0) // cell, 0, nx - 1).astype(np.int64)
        hi_col = np.clip((xmax + pad - x0) // cell, 0, nx - 1).astype(np.int64)
        lo_row = np.clip((ymin - pad - y0) // cell, 0, ny - 1).astype(np.int64)
        rows = np.clip((ymax + pad - y0) // cell, 0, ny - 1).astype(np.int64) - lo_row + 1
        box, vertex = self._blocks(lo_col, hi_col, lo_row, rows)
        return index[box], vertex

    def _blocks(
        self, lo_col: np.ndarray, hi_col: np.ndarray, lo_row: np.ndarray, rows: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(block index, vertex id) of the vertices in each block of cells (columns lo_col to
        hi_col, ``rows`` rows from lo_row): one contiguous run of the sorted vertices per
        (block, row of cells)."""
        nx, starts = self.nx, self.starts
        block = np.repeat(np.arange(len(lo_col), dtype=np.int64), rows)
        row_of = ragged_index(lo_row, rows)
        first = starts[row_of * nx + lo_col[block]]
        spans = starts[row_of * nx + hi_col[block] + 1] - first
        return np.repeat(block, spans), self.sorted_ids[ragged_index(first, spans)]

    def nearest(
        self,
        queries: np.ndarray,
        labels: np.ndarray | None = None,
        max_reach: int | None = None,
        first_reach: int = 1,
    ) -> tuple[np.ndarray, float]:
        """:func:`nearest_vertices` among the vertices of another label than the query's (per
        vertex id; None: any other vertex), and a squared distance ``bound``: a query left at
        -1 has no such vertex nearer (float) than ``bound`` (inf: none at all).

        Each query scans the block of cells around its own, the block (``first_reach`` cells
        around) doubling until it holds the nearest vertex's circle, or reaches ``max_reach``
        cells of the grid's first cell size (see ``finer``).
        """
        result = np.full(len(queries), -1, dtype=np.int64)
        if len(queries) == 0 or self.empty:
            return result, np.inf
        x, y = self.x, self.y
        x0, y0, cell, nx, ny = self.x0, self.y0, self.cell, self.nx, self.ny
        pad = self.pad
        qx, qy = x[queries], y[queries]
        qcol = np.clip((qx - x0) // cell, 0, nx - 1).astype(np.int64)
        qrow = np.clip((qy - y0) // cell, 0, ny - 1).astype(np.int64)
        todo = np.arange(len(queries), dtype=np.int64)
        reach = first_reach
        while len(todo):
            covers = reach >= self.cover_reach
            lo_col = np.maximum(qcol[todo] - reach, 0)
            hi_col = np.minimum(qcol[todo] + reach, nx - 1)
            lo_row = np.maximum(qrow[todo] - reach, 0)
            rows = np.minimum(qrow[todo] + reach, ny - 1) - lo_row + 1
            pair_query, vertex = self._blocks(lo_col, hi_col, lo_row, rows)
            own = queries[todo][pair_query]
            keep = vertex != own if labels is None else labels[vertex] != labels[own]
            pair_query, vertex, own = pair_query[keep], vertex[keep], own[keep]
            d2 = (x[vertex] - x[own]) ** 2 + (y[vertex] - y[own]) ** 2
            best = np.full(len(todo), np.inf)
            np.minimum.at(best, pair_query, d2)
            # the block holds every vertex within reach cells of the query, less a slack for the
            # rounding of the cell arithmetic
            safe = max(reach * cell * (1 - 1e-6) - pad, 0.0)
            safe *= safe  # (** would raise OverflowError on a Python float)
            done = best * (1 + _TIE_MARGIN) <= safe if not covers else np.isfinite(best)
            near = done[pair_query] & (d2 <= best[pair_query] * (1 + _TIE_MARGIN))
            pair_query, vertex = pair_query[near], vertex[near]
            # one candidate per query unless float distances come within the margin of a tie
            ties = np.bincount(pair_query, minlength=len(todo))
            single = ties[pair_query] == 1
            result[todo[pair_query[single]]] = vertex[single]
            if not single.all():
                # exact distances, ties to the smallest vertex id
                q, v = pair_query[~single], vertex[~single]
                order = np.lexsort((v, q))
                q, v = q[order], v[order]
                win = _least_exact(q, v, queries[todo[q]], x, y)
                result[todo[q[win]]] = v[win]
            if covers:
                return result, np.inf
            todo = todo[~done]
            if max_reach is not None and reach >= max_reach * self.finer and len(todo):
                return result, safe / (1 + _TIE_MARGIN)
            reach *= 2
        return result, np.inf


# rounds linking the components of points with no ring vertex to the nearest vertex outside,
# and how far (grid cells) their members look
_LINK_ROUNDS = 8
_LINK_REACH = 8


class PointOrder:
    """The order of the one-point islands under rule delaunay: a breadth-first walk, from the
    vertices in the sequence, over links whose diametral circles hold no vertex strictly
    inside, so that either end may be joined first.

    The links: each point to its nearest vertex (:func:`nearest_vertices`), then, for a
    while, each component of linked points without a ring vertex to the nearest vertex
    outside it (a vertex strictly inside that circle would be nearer to one of the ends and
    on the other side of the component's boundary).
    """

    def __init__(
        self,
        x: np.ndarray,
        y: np.ndarray,
        vertex_ids: np.ndarray,
        slots: list[int],
        point_vids: list[int],
    ) -> None:
        self.slot_of = dict(zip(point_vids, slots))
        # vertex id -> (slot, vertex id): the linked points and where they are bridged to
        self.links: dict[int, list[tuple[int, int]]] = {}
        self.root = {vid: vid for vid in point_vids}  # union-find over the points
        self.anchored: set[int] = set()  # roots of components linked to a ring vertex
        vids = np.asarray(point_vids, dtype=np.int64)
        # one grid over every vertex for all the searches below
        grid = VertexGrid(x, y, vertex_ids)
        nearest = grid.nearest(vids)[0].tolist()
        for vid, near in zip(point_vids, nearest):
            if near >= 0:
                self._link(vid, near)
        labels = np.arange(len(x), dtype=np.int64)
        free = point_vids
        root, anchored, find = self.root, self.anchored, self._find
        for _ in range(_LINK_ROUNDS):
            # a component once anchored stays so: only the free points of the round before
            found = []
            for vid in free:
                top = root[vid]
                if root[top] != top:  # else _find would change nothing
                    top = find(vid)
                if top not in anchored:
                    found.append((vid, top))
            if not found:
                break
            free = [vid for vid, _ in found]
            members = np.asarray(free, dtype=np.int64)
            roots = np.asarray([root for _, root in found], dtype=np.int64)
            labels[members] = roots
            component, index = np.unique(roots, return_inverse=True)
            least = np.full(len(component), np.inf)
            sure = np.zeros(len(component), dtype=bool)
            near = np.full(len(members), -1, dtype=np.int64)
            d2 = np.full(len(members), np.inf)
            # growing blocks, for the members of the components not settled yet
            active, reach = np.arange(len(members)), 1
            while len(active) and reach <= _LINK_REACH:
                got, bound = grid.nearest(members[active], labels, reach, first_reach=reach)
                hit, left = active[got >= 0], active[got < 0]
                near[hit] = got[got >= 0]
                d2[hit] = (x[near[hit]] - x[members[hit]]) ** 2 + (
                    y[near[hit]] - y[members[hit]]
                ) ** 2
                np.minimum.at(least, index[hit], d2[hit])
                # settled: no member left without a result can be nearer
                open_ = np.zeros(len(component), dtype=bool)
                open_[index[left]] = True
                sure = np.isfinite(least) & (~open_ | (least * (1 + _TIE_MARGIN) < bound))
                active = left[~sure[index[left]]]
                reach *= 2
            labels[members] = members
            pick = sure[index] & (d2 <= least[index] * (1 + _TIE_MARGIN))
            picked = index[pick]
            if not len(picked):
                break
            start, end = members[pick], near[pick]
            chosen_a = np.full(len(component), -1, dtype=np.int64)
            chosen_b = np.full(len(component), -1, dtype=np.int64)
            # exact distances only where a component has more than one candidate; ties to the
            # smallest (point, vertex)
            tied = np.bincount(picked, minlength=len(component))[picked] > 1
            chosen_a[picked[~tied]] = start[~tied]
            chosen_b[picked[~tied]] = end[~tied]
            if tied.any():
                c, ta, tb = picked[tied], start[tied], end[tied]
                order = np.lexsort((tb, ta, c))
                c, ta, tb = c[order], ta[order], tb[order]
                win = _least_exact(c, ta, tb, x, y)
                chosen_a[c[win]] = ta[win]
                chosen_b[c[win]] = tb[win]
            # the components in the order of their first candidate
            unique, first = np.unique(picked, return_index=True)
            linked = unique[np.argsort(first)]
            for a, b in zip(chosen_a[linked].tolist(), chosen_b[linked].tolist()):
                self._link(a, b)

    def _find(self, vid: int) -> int:
        root = self.root
        while root[vid] != vid:
            root[vid] = root[root[vid]]
            vid = root[vid]
        return vid

    def _link(self, a: int, b: int) -> None:
        """Link point ``a`` to vertex ``b``."""
        self.links.setdefault(b, []).append((self.slot_of[a], b))
        ra = self._find(a)
        if b not in self.slot_of:
            self.anchored.add(ra)
            return
        self.links.setdefault(a, []).append((self.slot_of[b], a))
        rb = self._find(b)
        if ra != rb:
            self.root[ra] = rb
            if ra in self.anchored:
                self.anchored.add(rb)

    def ready(self, vids: list[int]) -> list[tuple[int, int]]:
        """(slot, target vertex id) of the points linked to one of ``vids`` (once each)."""
        found: list[tuple[int, int]] = []
        for vid in vids:
            found.extend(self.links.pop(vid, ()))
        return found


def point_order(
    x: np.ndarray, y: np.ndarray, rings: list[np.ndarray], vertex_ids: np.ndarray
) -> PointOrder | None:
    """The :class:`PointOrder` of the one-point islands among ``rings[1:]`` (``vertex_ids``:
    every vertex of ``rings``), None if none."""
    slots = [slot for slot in range(1, len(rings)) if len(rings[slot]) == 1]
    if not slots:
        return None
    return PointOrder(x, y, vertex_ids, slots, [int(rings[slot][0]) for slot in slots])


def nearest_point_bridge(bridger: Bridging, h: int, v: int) -> tuple[int, int] | None:
    """(node, vertex id) of the bridge from the one-point island ``h`` to its nearest vertex
    ``v``, or None (``v`` not in the sequence yet, or the bridge not valid).

    No vertex lies strictly inside the circle with diameter h-v (it would be nearer to
    ``h``), so a valid h-v is a constrained Delaunay edge without the disk test of
    :func:`delaunay_point_bridge`.
    """
    if not bridger.in_seq[v]:
        return None
    ks = bridger._valid_occurrences(v, np.array([h], dtype=np.int64), 0)
    if not ks:
        return None
    if len(ks) == 1:
        return ks[0], v
    return bridger.earliest(ks), v
