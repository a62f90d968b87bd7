"""Interior points from a DEM, added greedily until a mesh follows the DEM within a tolerance.

The DEM's cell centres strictly inside a polygon are both the candidate points and the places
where the error is measured: the surface (barycentric in the containing triangle) against the
cell's value. Each round, every triangle whose worst cell is off by more than the tolerance
gets that cell as a new vertex; the polygon is triangulated again with all its points, until
every cell is within the tolerance or the polygon's group reaches its cap of points.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry.delaunay_batch import MeshSet, grown
from ..geometry.delaunay_mesh import delaunay_faults
from ..geometry.rings import xy_mirror
from ..geometry.rings_batch import ragged_index
from .raster_sampling import PreparedGrid

# (triangle, cell) pairs examined per numpy step of the point location
LOCATE_CHUNK = 2_000_000
# a cell centre this close to a ring edge (in cell widths) counts as on the boundary
BOUNDARY_SHARE = 1e-9
# barycentric weights down to this count as inside (shared edges belong to both triangles)
INSIDE_WEIGHT = -1e-9
# a cell counts as within the tolerance only this share below it: another evaluation of the
# same surface (other corner order, other arithmetic) may differ in the last digits
TOLERANCE_MARGIN = 1e-6


@dataclass(frozen=True)
class CellGrid:
    """North-up raster cells: ``x0``, ``y0`` the outer top-left corner, ``dx``, ``dy`` the
    (positive) cell width and height, ``values`` (rows, cols) float64, NaN for no value."""

    x0: float
    y0: float
    dx: float
    dy: float
    values: np.ndarray

    @classmethod
    def from_prepared(cls, grid: PreparedGrid) -> CellGrid:
        """The cells of a ``PreparedGrid`` (north-up geotransforms only)."""
        gt = [float(v) for v in grid.geotransform]
        if gt[2] != 0 or gt[4] != 0 or gt[1] <= 0 or gt[5] >= 0:
            raise ValueError("only north-up grids with positive cell sizes are supported")
        padded = grid.values.reshape(grid.rows + 2, grid.width)
        return cls(gt[0], gt[3], gt[1], -gt[5], padded[1:-1, 1:-1])

    @classmethod
    def from_array(
        cls, array: np.ndarray, geotransform: Sequence[float], nodata: float | None = None
    ) -> CellGrid:
        """Cells of a raster array and its GDAL geotransform (nodata as ``PreparedGrid``)."""
        return cls.from_prepared(PreparedGrid(array, geotransform, nodata))

    @property
    def shape(self) -> tuple[int, int]:
        return self.values.shape

    def centre_x(self, cols: np.ndarray) -> np.ndarray:
        return self.x0 + (np.asarray(cols) + 0.5) * self.dx

    def centre_y(self, rows: np.ndarray) -> np.ndarray:
        return self.y0 - (np.asarray(rows) + 0.5) * self.dy

    def column_range(self, xmin: np.ndarray, xmax: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last column whose centre lies in [xmin, xmax] (empty when first > last)."""
        first = np.ceil((np.asarray(xmin) - self.x0) / self.dx - 0.5).astype(np.int64)
        last = np.floor((np.asarray(xmax) - self.x0) / self.dx - 0.5).astype(np.int64)
        return np.maximum(first, 0), np.minimum(last, self.shape[1] - 1)

    def row_range(self, ymin: np.ndarray, ymax: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last row whose centre lies in [ymin, ymax] (rows go south)."""
        first = np.ceil((self.y0 - np.asarray(ymax)) / self.dy - 0.5).astype(np.int64)
        last = np.floor((self.y0 - np.asarray(ymin)) / self.dy - 0.5).astype(np.int64)
        return np.maximum(first, 0), np.minimum(last, self.shape[0] - 1)

    def window(self, xmin: float, ymin: float, xmax: float, ymax: float) -> CellGrid:
        """The cells whose centres lie in the box (a view; possibly empty)."""
        c0, c1 = (int(v) for v in self.column_range(xmin, xmax))
        r0, r1 = (int(v) for v in self.row_range(ymin, ymax))
        c1, r1 = max(c1, c0 - 1), max(r1, r0 - 1)
        return CellGrid(
            self.x0 + c0 * self.dx,
            self.y0 - r0 * self.dy,
            self.dx,
            self.dy,
            self.values[r0 : r1 + 1, c0 : c1 + 1],
        )


def cells_inside(rings: Sequence[np.ndarray], grid: CellGrid) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the cells whose centres lie strictly inside the polygon (even-odd rule
    over all rings; a centre on a ring edge is not inside), row by row."""
    none = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    rings = [np.asarray(ring, dtype=np.float64)[:, :2] for ring in rings if len(ring) >= 3]
    if not rings or grid.values.size == 0:
        return none
    start = np.concatenate([ring for ring in rings])
    end = np.concatenate([np.roll(ring, -1, axis=0) for ring in rings])
    r0, r1 = (int(v) for v in grid.row_range(start[:, 1].min(), start[:, 1].max()))
    c0, c1 = (int(v) for v in grid.column_range(start[:, 0].min(), start[:, 0].max()))
    if r1 < r0 or c1 < c0:
        return none
    eps = BOUNDARY_SHARE * grid.dx
    # rows crossed by each edge, half-open in y (lower end in, upper end out)
    y_low = np.minimum(start[:, 1], end[:, 1])
    y_high = np.maximum(start[:, 1], end[:, 1])
    first_row = np.maximum(grid.row_range(y_low, y_high)[0] - 1, r0)
    last_row = np.minimum(np.floor((grid.y0 - y_low) / grid.dy - 0.5).astype(np.int64) + 1, r1)
    spans = np.maximum(last_row - first_row + 1, 0)
    edge = np.repeat(np.arange(len(start)), spans)
    row = np.repeat(first_row, spans) + (
        np.arange(len(edge)) - np.repeat(np.cumsum(spans) - spans, spans)
    )
    yc = grid.centre_y(row)
    sloped = y_low[edge] != y_high[edge]
    # edges meeting the row (closed in y) tell "on the boundary"; the half-open ones count
    touches = sloped & (y_low[edge] <= yc) & (yc <= y_high[edge])
    flat = ~sloped & (np.abs(yc - y_low[edge]) <= eps)
    flat_edge, flat_row = edge[flat], row[flat]
    edge, yc, row = edge[touches], yc[touches], row[touches]
    crosses = yc < y_high[edge]
    ax, ay = start[edge, 0], start[edge, 1]
    bx, by = end[edge, 0], end[edge, 1]
    x_touch = ax + (yc - ay) * (bx - ax) / (by - ay)
    rows = np.arange(r0, r1 + 1)
    cols = np.arange(c0, c1 + 1)
    cell_row = np.repeat(rows, len(cols))
    cell_col = np.tile(cols, len(rows))
    cx = grid.centre_x(cell_col)
    # crossings left of each centre, by merging (row, x) of the touches and the centres
    key_row = np.concatenate([row, cell_row])
    key_x = np.concatenate([x_touch, cx])
    is_cell = np.concatenate([np.zeros(len(row), bool), np.ones(len(cx), bool)])
    counts = np.concatenate([crosses, np.zeros(len(cx), bool)])
    order = np.lexsort((is_cell, key_x, key_row))
    is_cell, counts = is_cell[order], counts[order]
    row_sorted, x_sorted = key_row[order], key_x[order]
    counted = np.cumsum(counts)
    row_start = np.flatnonzero(np.r_[True, row_sorted[1:] != row_sorted[:-1]])
    before = np.repeat(
        counted[row_start] - counts[row_start], np.diff(np.r_[row_start, len(order)])
    )
    inside_sorted = ((counted - before) % 2 == 1) & is_cell
    # a touch within eps of a centre puts the centre on the boundary
    positions = np.arange(len(order))
    previous = np.maximum.accumulate(np.where(is_cell, -1, positions))
    following = np.minimum.accumulate(np.where(is_cell, len(order), positions)[::-1])[::-1]
    for other in (previous, following):
        pick = np.clip(other, 0, max(len(order) - 1, 0))
        inside_sorted &= ~(
            (other >= 0)
            & (other < len(order))
            & (row_sorted[pick] == row_sorted)
            & (np.abs(x_sorted[pick] - x_sorted) <= eps)
        )
    inside = np.zeros(len(order), bool)
    inside[order] = inside_sorted
    inside = inside[len(row) :]
    if flat.any():
        on_flat = np.zeros(len(cx), bool)
        for e, r in zip(flat_edge.tolist(), flat_row.tolist()):
            lo, hi = sorted((start[e, 0], end[e, 0]))
            in_row = cell_row == r
            on_flat |= in_row & (cx >= lo - eps) & (cx <= hi + eps)
        inside &= ~on_flat
    return cell_row[inside], cell_col[inside]


def locate_cells(
    corners: np.ndarray, grids: Sequence[CellGrid], grid_of: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(triangle, row, col, z) of every cell centre inside a triangle: ``corners`` (t, 3, 3)
    x, y, z of each triangle, ``grid_of`` (t,) the index of its grid in ``grids`` (all the
    first when None), in the order triangle, row, column. Each row of a triangle's bounding
    box enumerates the centres near where its centre line crosses the triangle; barycentric
    weights decide containment (a centre on a shared edge is found in both triangles) and
    give the interpolated z."""
    corners = _sorted_corners(np.asarray(corners, dtype=np.float64))
    count = len(corners)
    grid_of = np.zeros(count, np.int64) if grid_of is None else np.asarray(grid_of, np.int64)
    empty = np.zeros(0, np.int64)
    if count == 0 or not grids:
        return empty, empty, empty, np.zeros(0)
    x0, y0, dx, dy = (
        np.array([getattr(g, name) for g in grids], dtype=np.float64)[grid_of]
        for name in ("x0", "y0", "dx", "dy")
    )
    rows_n, cols_n = (np.array([g.shape[k] for g in grids], np.int64)[grid_of] for k in (0, 1))
    xs, ys = corners[:, :, 0], corners[:, :, 1]
    # per corner columns: numpy reduces along an axis of 3 slowly
    low_x, high_x, low_y, high_y = _extremes(xs) + _extremes(ys)
    c0 = np.maximum(np.ceil((low_x - x0) / dx - 0.5), 0).astype(np.int64)
    c1 = np.minimum(np.floor((high_x - x0) / dx - 0.5), cols_n - 1).astype(np.int64)
    r0 = np.maximum(np.ceil((y0 - high_y) / dy - 0.5), 0).astype(np.int64)
    r1 = np.minimum(np.floor((y0 - low_y) / dy - 0.5), rows_n - 1).astype(np.int64)
    heights = np.maximum(r1 - r0 + 1, 0) * (c1 >= c0)
    # the weights' terms of each triangle, the same float operations as per centre before
    ax, ay, az = corners[:, 0, 0], corners[:, 0, 1], corners[:, 0, 2]
    bax, bay, bz = corners[:, 1, 0] - ax, corners[:, 1, 1] - ay, corners[:, 1, 2]
    cax, cay, cz = corners[:, 2, 0] - ax, corners[:, 2, 1] - ay, corners[:, 2, 2]
    det = bax * cay - cax * bay
    margin = _reach(xs, ys, (low_x, high_x, low_y, high_y))
    # the boxes' centres bound the pairs of a block
    starts = np.concatenate([[0], np.cumsum(heights * np.maximum(c1 - c0 + 1, 0))])
    found: list[tuple[np.ndarray, ...]] = []
    first = 0
    while first < count:
        last = int(np.searchsorted(starts, starts[first] + LOCATE_CHUNK, side="right")) - 1
        last = min(max(last, first + 1), count)
        found.append(
            _locate_rows(
                np.arange(first, last),
                (heights, r0, c0, c1),
                (xs, ys, x0, y0, dx, dy, margin),
                (ax, ay, az, bax, bay, bz, cax, cay, cz, det),
            )
        )
        first = last
    return tuple(np.concatenate(column) for column in zip(*found))  # type: ignore[return-value]


def _locate_rows(
    block: np.ndarray,
    boxes: tuple[np.ndarray, ...],
    frame: tuple[np.ndarray, ...],
    terms: tuple[np.ndarray, ...],
) -> tuple[np.ndarray, ...]:
    """:func:`locate_cells` of the triangles ``block``, row by row of their boxes:
    ``boxes`` (rows, first row, first and last column), ``frame`` the corners' x and y,
    each triangle's grid origin and cell size and :func:`_reach`, ``terms`` the weights'
    terms."""
    heights, r0, c0, c1 = boxes
    xs, ys, x0, y0, dx, dy, margin = frame
    tri = np.repeat(block, heights[block])
    row = ragged_index(r0[block], heights[block])
    yc = y0[tri] - (row + 0.5) * dy[tri]
    # the centre line's crossing with the triangle: per edge meeting it (closed in y), where
    # it crosses (clamped to the edge; an edge within 1e-6 of flat gives its whole x range)
    left = np.full(len(tri), np.inf)
    right = np.full(len(tri), -np.inf)
    corner_x = [xs[:, k][tri] for k in range(3)]
    corner_y = [ys[:, k][tri] for k in range(3)]
    for k in range(3):
        px, py = corner_x[k], corner_y[k]
        qx, qy = corner_x[(k + 1) % 3], corner_y[(k + 1) % 3]
        low_x, high_x = np.minimum(px, qx), np.maximum(px, qx)
        meets = (np.minimum(py, qy) <= yc) & (yc <= np.maximum(py, qy))
        rise = qy - py
        steep = np.abs(rise) > 1e-6 * (high_x - low_x)
        with np.errstate(invalid="ignore", divide="ignore"):
            at = np.clip(px + (yc - py) * ((qx - px) / rise), low_x, high_x)
        np.minimum(left, np.where(meets, np.where(steep, at, low_x), np.inf), out=left)
        np.maximum(right, np.where(meets, np.where(steep, at, high_x), -np.inf), out=right)
    reach = margin[tri]
    first = np.maximum(np.ceil((left - reach - x0[tri]) / dx[tri] - 0.5), c0[tri])
    last = np.minimum(np.floor((right + reach - x0[tri]) / dx[tri] - 0.5), c1[tri])
    ok = np.isfinite(first) & np.isfinite(last)
    first = np.where(ok, first, 0).astype(np.int64)
    widths = np.maximum(np.where(ok, last, -1).astype(np.int64) - first + 1, 0)
    at_row = np.repeat(np.arange(len(tri)), widths)
    tri, row = tri[at_row], row[at_row]
    col = ragged_index(first, widths)
    px = x0[tri] + (col + 0.5) * dx[tri]
    py = yc[at_row]
    ax, ay, az, bax, bay, bz, cax, cay, cz, det = (term[tri] for term in terms)
    with np.errstate(invalid="ignore", divide="ignore"):
        wb = ((px - ax) * cay - cax * (py - ay)) / det
        wc = (bax * (py - ay) - (px - ax) * bay) / det
        wa = 1.0 - wb - wc
        z = wa * az + wb * bz + wc * cz
    hit = (det != 0) & (wa >= INSIDE_WEIGHT) & (wb >= INSIDE_WEIGHT) & (wc >= INSIDE_WEIGHT)
    return tri[hit], row[hit], col[hit], z[hit]


def _extremes(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest of the three columns of ``values``."""
    a, b, c = values[:, 0], values[:, 1], values[:, 2]
    return np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)


def _reach(xs: np.ndarray, ys: np.ndarray, box: tuple[np.ndarray, ...]) -> np.ndarray:
    """Per triangle (corners ``xs``, ``ys``, extents ``box``), how far outside it (in x)
    the weights of :func:`locate_cells` may accept a centre, with room to spare: the
    weights' tolerance, their rounding (which grows as the shortest edge shrinks: inf for a
    repeated corner) and that of the crossings."""
    low_x, high_x, low_y, high_y = box
    size = np.maximum(high_x - low_x, high_y - low_y)
    scale = np.maximum(
        np.maximum(np.abs(low_x), np.abs(high_x)), np.maximum(np.abs(low_y), np.abs(high_y))
    )
    scale += size
    edges = np.minimum(
        np.minimum(
            np.hypot(xs[:, 0] - xs[:, 1], ys[:, 0] - ys[:, 1]),
            np.hypot(xs[:, 1] - xs[:, 2], ys[:, 1] - ys[:, 2]),
        ),
        np.hypot(xs[:, 2] - xs[:, 0], ys[:, 2] - ys[:, 0]),
    )
    eps = 2.0**-52
    with np.errstate(divide="ignore", invalid="ignore"):
        rounding = 64 * eps * (scale * size / edges + 1e6 * size + scale)
    reach = 8 * abs(INSIDE_WEIGHT) * size + rounding
    return np.where(np.isnan(reach), np.inf, reach)


def _sorted_corners(corners: np.ndarray) -> np.ndarray:
    """Each triangle's corners in (x, y) order: the weights and z, rounded, then depend on
    the triangle alone, not on which corner a mesh lists first or on its orientation."""
    x, y = corners[:, :, 0], corners[:, :, 1]
    # three corners: a sorting network of three compare-and-swaps
    index = np.tile(np.arange(3), (len(corners), 1))
    rows = np.arange(len(corners))
    for i, j in ((0, 1), (1, 2), (0, 1)):
        xi, yi = x[rows, index[:, i]], y[rows, index[:, i]]
        xj, yj = x[rows, index[:, j]], y[rows, index[:, j]]
        swap = (xj < xi) | ((xj == xi) & (yj < yi))
        index[swap, i], index[swap, j] = index[swap, j], index[swap, i]
    return np.take_along_axis(corners, index[:, :, None], axis=1)


@dataclass
class Refinement:
    """The outcome for one polygon.

    - ``points``: (k, 3) the interior points to triangulate with: the fixed points given,
      then the DEM cell centres added (with the cells' values as z);
    - ``added``: DEM points among them that the mesh uses;
    - ``max_error``: the largest |surface - DEM| over the cells measured (0 with none);
    - ``cells``: cells measured (centres strictly inside, with a value);
    - ``rounds``: triangulations made; ``within``: every cell within the tolerance;
    - ``capped``: the group's cap of points stopped the refinement;
    - ``error``: the engine's error that stopped it (``points`` are then the last ones that
      triangulated, or the fixed points);
    - ``mesh``: under rule delaunay, the last mesh's triangles (rows of the engine's result
      with ``points``, counter-clockwise), to hand to the engine (``mesh=``), or None.
    """

    points: np.ndarray
    added: int = 0
    max_error: float = 0.0
    cells: int = 0
    rounds: int = 0
    within: bool = True
    capped: bool = False
    error: Exception | None = None
    mesh: np.ndarray | None = None


def refine(
    rings: Sequence[np.ndarray],
    grid: CellGrid,
    tolerance: float,
    max_points: int = 10_000,
    *,
    engine: Callable[..., list],
    fixed: np.ndarray | None = None,
    share: float = 0.0,
    finish_share: float = 0.0,
    **options: object,
) -> Refinement:
    """:func:`refine_many` of one polygon."""
    return refine_many(
        [rings],
        [grid],
        tolerance,
        max_points,
        engine=engine,
        fixed=[fixed],
        share=share,
        finish_share=finish_share,
        **options,
    )[0]


def refine_many(
    polygons: Sequence[Sequence[np.ndarray]],
    grids: Sequence[CellGrid],
    tolerance: float,
    max_points: int = 10_000,
    *,
    engine: Callable[..., list],
    fixed: Sequence[np.ndarray | None] | None = None,
    groups: Sequence[int] | None = None,
    share: float = 0.0,
    finish_share: float = 0.0,
    spacing: int = 1,
    progress: Callable[[int, int], None] | None = None,
    **options: object,
) -> list[Refinement]:
    """Interior points that bring each polygon's mesh within ``tolerance`` of its grid.

    ``polygons``: rings (x, y, z) per polygon, z already from the DEM; ``grids``: the DEM
    cells of each polygon (the same grid may repeat); ``fixed``: per polygon, points (m, 3)
    always in the mesh (survey points); ``groups``: per polygon, the group whose
    ``max_points`` added points it shares (a feature's parts; each polygon its own by
    default). ``share``: a round adds only the cells off by at least this share of the
    polygon's largest error (0: every triangle's worst cell); a polygon whose cells beyond
    the tolerance are at most ``finish_share`` times the DEM points it has takes them all
    at once (fewer rounds for a few more points). ``spacing``: a round leaves out a cell
    when another of its polygon's picks, farther off, lies within this many cells in rows
    and columns (default 1; 0: none left out). ``progress(round, active)``
    is called before each round. ``engine``: ``bsp_triangulate.triangulate_many`` (passed
    in, as ``terrain`` imports nothing of the engine), called once per round over all the
    polygons still refined, with ``options`` (rule, plane...).
    """
    count = len(polygons)
    limit = tolerance * (1.0 - TOLERANCE_MARGIN)
    fixed_points = [_points(fixed[p] if fixed is not None else None) for p in range(count)]
    group = np.arange(count) if groups is None else np.asarray(groups, np.int64)
    windows, candidates = _candidates(polygons, grids)
    owner, cell_row, cell_col, value = candidates
    x0, y0, dx, dy = (
        np.array([getattr(w, name) for w in windows], np.float64)[owner]
        for name in ("x0", "y0", "dx", "dy")
    )
    # the same values as the windows' centre_x and centre_y
    cand_xyz = np.column_stack([x0 + (cell_col + 0.5) * dx, y0 - (cell_row + 0.5) * dy, value])
    lookup, base = _lookup(windows, candidates)
    meshes = _Meshes(polygons) if _by_insertion(options) else None
    outcome = [Refinement(fixed_points[p]) for p in range(count)]
    cells_of = np.bincount(owner, minlength=count)
    for p in range(count):
        outcome[p].cells = int(cells_of[p])
    added: list[np.ndarray] = [np.zeros(0, np.int64) for _ in range(count)]
    used_cells = np.zeros(count, np.int64)
    spent = np.zeros(int(group.max()) + 1 if count else 0, np.int64)
    taken = np.zeros(len(value), bool)  # given to the engine (used or not)
    active = [p for p in range(count) if cells_of[p] > 0]
    rounds = 0
    while active:
        rounds += 1
        if progress is not None:
            progress(rounds, len(active))
        given = [np.vstack([fixed_points[p], cand_xyz[added[p]]]) for p in active]
        # by insertion where a polygon has its mesh, else triangulated again
        again = [i for i, p in enumerate(active) if meshes is None or not meshes.holds(p)]
        results: list[object] = [None] * len(active)
        if meshes is not None:
            for i, p in enumerate(active):
                if meshes.holds(p):
                    results[i] = meshes.result(p)
        if again:
            fresh = engine(
                [polygons[active[i]] for i in again],
                points=[given[i] for i in again],
                on_error="return",
                **options,
            )
            for i, result in zip(again, fresh):
                results[i] = result
            if meshes is not None and rounds == 1:
                meshes.start(active, results)
        measured = []
        for p, points, result in zip(active, given, results):
            if isinstance(result, Exception) or not hasattr(result, "point_ids"):
                outcome[p].error = result if isinstance(result, Exception) else None
                continue
            if not isinstance(result, _HeldResult) and not len(result.triangles):
                continue
            ids = np.asarray(result.point_ids)[len(fixed_points[p]) :]
            used_cells[p] = int((ids >= 0).sum())
            outcome[p].points = points
            outcome[p].added = int(used_cells[p])
            outcome[p].rounds = rounds
            measured.append((p, result))
        if not measured:
            break
        # (polygon, triangle, candidate, z) of every cell centre in a triangle
        if meshes is not None:
            poly, tri, cand, z = meshes.located(measured, windows, lookup, base)
        else:
            poly, tri, cand, z = _located(measured, windows, lookup, base)
        error = np.abs(z - value[cand])
        is_measured = np.zeros(count, bool)
        is_measured[[p for p, _ in measured]] = True
        in_round = is_measured[owner]
        located = np.zeros(len(value), bool)
        located[cand] = True
        worst = np.zeros(count)
        np.maximum.at(worst, poly, error)
        # a cell on a shared edge has a z from each triangle: it counts by the larger error
        cell_error = np.zeros(len(value))
        np.maximum.at(cell_error, cand, error)
        missing = np.bincount(owner[in_round & ~located], minlength=count)
        # each triangle's worst cell beyond the tolerance, if not given already (ties: the
        # first cell)
        over = (error > limit) & ~taken[cand]
        want = over & (error >= share * worst[poly]) if share > 0 else over
        wanted_key = poly[want] * _TRIANGLE_KEY + tri[want]
        wanted_cand, wanted_error = cand[want], error[want]
        order = np.lexsort((wanted_cand, -wanted_error, wanted_key))
        sorted_key = wanted_key[order]
        first = order[np.r_[True, sorted_key[1:] != sorted_key[:-1]]] if len(order) else order
        pick = wanted_cand[first]
        # a polygon with few cells left over takes them all: its last rounds cost the most
        over_cells = np.unique(cand[over])
        over_count = np.bincount(owner[over_cells], minlength=count)
        finishing = over_count <= finish_share * np.maximum(used_cells, 1)
        pick = np.unique(np.concatenate([pick, over_cells[finishing[owner[over_cells]]]]))
        pick_error = cell_error[pick]
        # a triangle holding each cell: where the mesh inserts it from
        holder = np.zeros(len(value), np.int64)
        holder[cand] = tri
        if spacing:
            keep_pick = _local_maxima(pick, pick_error, owner, cell_row, cell_col, spacing)
            pick, pick_error = pick[keep_pick], pick_error[keep_pick]
        # the cap: each group's remaining points go to its worst cells first
        pick_group = group[owner[pick]]
        order = np.lexsort((pick, -pick_error, pick_group))
        pick, pick_group = pick[order], pick_group[order]
        group_start = np.r_[True, pick_group[1:] != pick_group[:-1]]
        starts = np.flatnonzero(group_start)
        rank = np.arange(len(pick)) - np.repeat(starts, np.diff(np.r_[starts, len(pick)]))
        allowed = rank < (max_points - spent[pick_group])
        chosen = np.sort(pick[allowed])
        np.add.at(spent, pick_group[allowed], 1)
        refused = np.bincount(owner[pick[~allowed]], minlength=count)
        chosen_of = np.bincount(owner[chosen], minlength=count)
        # candidates are grouped by polygon: each polygon's chosen ones are one slice
        chosen_start = np.cumsum(chosen_of) - chosen_of
        taken[chosen] = True
        next_active = []
        insertions = []
        for p, _ in measured:
            outcome[p].max_error = float(worst[p])
            outcome[p].within = worst[p] <= limit and missing[p] == 0
            if outcome[p].within:
                continue
            if chosen_of[p]:
                mine = chosen[chosen_start[p] : chosen_start[p] + chosen_of[p]]
                added[p] = np.concatenate([added[p], mine])
                if meshes is not None and meshes.holds(p):
                    insertions.append((p, cand_xyz[mine], holder[mine]))
                next_active.append(p)
            elif refused[p] or spent[group[p]] >= max_points:
                outcome[p].capped = True
        if insertions:
            meshes.insert(insertions)  # type: ignore[union-attr]
        active = next_active
    if meshes is not None:
        for p, triangles in meshes.triangles().items():
            if outcome[p].error is None:
                outcome[p].mesh = triangles
    return outcome


# a triangle's key in a round: polygon * _TRIANGLE_KEY + its row
_TRIANGLE_KEY = 1 << 32


def _located(
    measured: Sequence[tuple[int, object]],
    windows: Sequence[CellGrid],
    lookup: np.ndarray,
    base: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(polygon, triangle row, candidate, z) of every candidate cell centre inside a triangle
    of the measured polygons' results."""
    polys = np.array([p for p, _ in measured], np.int64)
    corners = [result.vertices[result.triangles] for _, result in measured]
    sizes = np.array([len(c) for c in corners], np.int64)
    tri_poly = np.repeat(polys, sizes)
    tri_row = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return _cells_in(tri_poly, tri_row, np.concatenate(corners), windows, lookup, base)


def _cells_in(
    tri_poly: np.ndarray,
    tri_row: np.ndarray,
    corners: np.ndarray,
    windows: Sequence[CellGrid],
    lookup: np.ndarray,
    base: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(polygon, triangle, candidate, z) of the candidate cell centres inside the triangles
    (``corners`` (t, 3, 3), each of polygon ``tri_poly`` and named ``tri_row``)."""
    tri, row, col, z = locate_cells(corners, windows, tri_poly)
    return _candidate_pairs(tri_poly[tri], tri_row[tri], row, col, z, windows, lookup, base)


def _candidate_pairs(
    poly: np.ndarray,
    tri: np.ndarray,
    row: np.ndarray,
    col: np.ndarray,
    z: np.ndarray,
    windows: Sequence[CellGrid],
    lookup: np.ndarray,
    base: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The located cells that are candidates (strictly inside, with a value)."""
    cand = lookup[base[poly] + row * _cols(windows)[poly] + col]
    keep = cand >= 0
    return poly[keep], tri[keep], cand[keep], z[keep]


def _by_insertion(options: dict) -> bool:
    """Whether the rounds insert their points into the last mesh instead of triangulating
    again: rule "delaunay" in the XY plane, where both give the same triangulation (the
    constrained Delaunay one, unique with the tie rule of ``predicates.cocircular_sign``)."""
    return (
        options.get("rule") == "delaunay"
        and options.get("plane") == "xy"
        and not options.get("planar_tolerance")
        and options.get("invalid", "fail") != "as_given"
    )


class _Meshes:
    """The meshes of the first round (the engine's, with the fixed points) of the polygons
    that keep theirs, as one :class:`MeshSet` (one region per polygon) that later rounds
    insert their points into, all polygons at once. The meshes work in the engine's working
    plane (x mirrored where the outer ring is clockwise), so that cocircular ties fall as the
    engine decides them. Vertex ids are global; each polygon's local ids (its result's rows)
    are its engine vertices, then its points in the order given, as the engine numbers them."""

    def __init__(self, polygons: Sequence[Sequence[np.ndarray]]) -> None:
        self.polygons = polygons
        self.mesh: MeshSet | None = None
        self.region_of: dict[int, int] = {}
        self.polygon_of = np.zeros(0, np.int64)
        self.mirror = np.zeros(0)
        self.z = np.zeros(0)
        self.local = np.zeros(0, np.int64)
        self.local_count: dict[int, int] = {}
        self.point_ids: dict[int, list[int]] = {}
        # polygons triangulated again each round: the triangles their cells were located
        # in (and which changed last); (polygon, triangle, candidate, z) of every located
        # cell (triangle: a row of the result, or a global mesh id)
        self.known: dict[int, np.ndarray] = {}
        self.changed: dict[int, np.ndarray] = {}
        empty = np.zeros(0, np.int64)
        self.pairs: tuple[np.ndarray, ...] = (empty, empty, empty, np.zeros(0))

    def holds(self, p: int) -> bool:
        """Polygon p has a mesh (the others are triangulated again each round)."""
        return p in self.region_of

    def start(self, active: Sequence[int], results: Sequence[object]) -> None:
        """Meshes from the engine's first results. Errors, empty results and a triangulation
        that is not locally Delaunay (an island's fallback bridge, section 5a: the engine's
        next results would not be this mesh with points inserted) get none."""
        kept = []
        for p, result in zip(active, results):
            if isinstance(result, Exception) or not len(getattr(result, "triangles", ())):
                continue
            mirror = xy_mirror(self.polygons[p])
            triangles = np.asarray(result.triangles, np.int64)
            if mirror < 0:
                triangles = triangles[:, [1, 0, 2]]
            kept.append((p, mirror, np.asarray(result.vertices, np.float64), triangles, result))
        good = _delaunay_regions([(m * v[:, 0], v[:, 1], t) for _, m, v, t, _ in kept])
        kept = [k for k, ok in zip(kept, good) if ok]
        if not kept:
            return
        sizes = np.array([len(v) for _, _, v, _, _ in kept], np.int64)
        offsets = np.cumsum(sizes) - sizes
        mirror = np.repeat([m for _, m, _, _, _ in kept], sizes)
        vertices = np.concatenate([v for _, _, v, _, _ in kept])
        triangles = np.concatenate([t + o for (_, _, _, t, _), o in zip(kept, offsets)])
        region = np.repeat(np.arange(len(kept)), [len(t) for _, _, _, t, _ in kept])
        self.mesh = MeshSet(mirror * vertices[:, 0], vertices[:, 1], triangles, region)
        self.polygon_of = np.array([p for p, _, _, _, _ in kept], np.int64)
        self.mirror = np.array([m for _, m, _, _, _ in kept])
        self.z = vertices[:, 2].copy()
        self.local = np.arange(len(vertices)) - np.repeat(offsets, sizes)
        for r, (p, _, v, _, result) in enumerate(kept):
            self.region_of[p] = r
            self.local_count[p] = len(v)
            self.point_ids[p] = np.asarray(result.point_ids, np.int64).tolist()

    def located(
        self,
        measured: Sequence[tuple[int, object]],
        windows: Sequence[CellGrid],
        lookup: np.ndarray,
        base: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:func:`_located`, locating again only the cells of the triangles that changed
        since the last round (the others keep their cells and z)."""
        fresh: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for p, result in measured:
            if self.holds(p):
                continue
            triangles = np.asarray(result.triangles)
            before = self.known.get(p)
            changed = np.ones(len(triangles), bool)
            if before is not None:
                changed[: len(before)] = (triangles[: len(before)] != before).any(axis=1)
            self.known[p] = triangles
            self.changed[p] = changed
            rows = np.flatnonzero(changed)
            fresh.append((np.full(len(rows), p), rows, result.vertices[triangles[rows]]))
        mesh_changed = np.zeros(0, bool)
        if self.mesh is not None:
            mesh = self.mesh
            mesh_changed = mesh.changed[: mesh.triangle_count].copy()
            mesh.changed[:] = False
            regions_measured = np.zeros(len(self.polygon_of), bool)
            regions_measured[[self.region_of[p] for p, _ in measured if self.holds(p)]] = True
            region_of_triangle = mesh.region[: mesh.triangle_count]
            ids = np.flatnonzero(mesh_changed & regions_measured[region_of_triangle])
            corners = mesh.vertex[(3 * ids)[:, None] + np.arange(3)]
            region = mesh.region[ids]
            xyz = np.stack(
                [self.mirror[region, None] * mesh.x[corners], mesh.y[corners], self.z[corners]],
                axis=-1,
            )
            fresh.append((self.polygon_of[region], ids, xyz))
        # the pairs of the triangles that did not change stay (polygons no longer refined
        # leave for good)
        poly, tri, cand, z = self.pairs
        if len(poly):
            count = int(poly.max()) + 1
            measuring = np.zeros(count, bool)
            held = np.zeros(count, bool)
            for p, _ in measured:
                if p < count:
                    measuring[p] = True
                    held[p] = self.holds(p)
            stays = measuring[poly]
            in_mesh = np.flatnonzero(stays & held[poly])
            stays[in_mesh] = ~mesh_changed[tri[in_mesh]]
            for p, _ in measured:
                if p < count and not held[p]:
                    at = np.flatnonzero(poly == p)
                    stays[at] = ~self.changed[p][tri[at]]
            poly, tri, cand, z = poly[stays], tri[stays], cand[stays], z[stays]
        tri_poly = np.concatenate([f[0] for f in fresh]) if fresh else np.zeros(0, np.int64)
        tri_row = np.concatenate([f[1] for f in fresh]) if fresh else np.zeros(0, np.int64)
        corners = (
            np.concatenate([f[2] for f in fresh]).reshape(-1, 3, 3)
            if fresh
            else np.zeros((0, 3, 3))
        )
        new = _cells_in(tri_poly, tri_row, corners, windows, lookup, base)
        self.pairs = tuple(np.concatenate(pair) for pair in zip((poly, tri, cand, z), new))
        return self.pairs

    def triangles(self) -> dict[int, np.ndarray]:
        """Per polygon with a mesh, its triangles in its local ids, counter-clockwise in
        the output's XY."""
        if self.mesh is None:
            return {}
        mesh = self.mesh
        region = mesh.region[: mesh.triangle_count]
        order = np.argsort(region, kind="stable")
        local = self.local[mesh.triangles()[order]]
        flip = self.mirror[region[order]] < 0
        local[flip] = local[flip][:, [1, 0, 2]]
        ends = np.searchsorted(region[order], np.arange(len(self.polygon_of) + 1))
        return {
            int(p): local[ends[r] : ends[r + 1]] for r, p in enumerate(self.polygon_of.tolist())
        }

    def result(self, p: int) -> _HeldResult:
        """The polygon's result so far: the engine's point ids, then those of the points
        inserted."""
        return _HeldResult(np.array(self.point_ids[p], np.int64))

    def insert(self, insertions: Sequence[tuple[int, np.ndarray, np.ndarray]]) -> None:
        """Insert the points (x, y, z) of each (polygon, points, near) into its mesh at once,
        each found from its triangle ``near``; a point the mesh cannot take (on a vertex) is
        recorded as not used."""
        mesh = self.mesh
        if mesh is None or not insertions:
            return
        region = np.concatenate([np.full(len(xyz), self.region_of[p]) for p, xyz, _ in insertions])
        xyz = np.concatenate([xyz for _, xyz, _ in insertions])
        near = np.concatenate([n for _, _, n in insertions])
        ids = mesh.insert(self.mirror[region] * xyz[:, 0], xyz[:, 1], near)
        total = mesh.vertex_count
        self.z = grown(self.z, total)
        self.local = grown(self.local, total)
        used = ids >= 0
        self.z[ids[used]] = xyz[used, 2]
        at = 0
        for p, points, _ in insertions:
            mine = ids[at : at + len(points)]
            at += len(points)
            taken = mine >= 0
            local = np.full(len(mine), -1, np.int64)
            local[taken] = self.local_count[p] + np.arange(int(taken.sum()))
            self.local[mine[taken]] = local[taken]
            self.local_count[p] += int(taken.sum())
            self.point_ids[p].extend(local.tolist())


@dataclass
class _HeldResult:
    point_ids: np.ndarray


def _delaunay_regions(regions: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list[bool]:
    """Per (x, y, triangles): whether the triangles are counter-clockwise, use each directed
    edge once and are locally Delaunay (the rule's tie rule) across every shared edge."""
    if not regions:
        return []
    sizes = np.array([len(x) for x, _, _ in regions], np.int64)
    offsets = np.cumsum(sizes) - sizes
    x = np.concatenate([x for x, _, _ in regions])
    y = np.concatenate([y for _, y, _ in regions])
    tri = np.concatenate([t + o for (_, _, t), o in zip(regions, offsets)])
    owner = np.repeat(np.arange(len(regions)), [len(t) for _, _, t in regions])
    bad = np.zeros(len(regions), bool)
    bad[owner[delaunay_faults(x, y, tri, ties=False)]] = True
    return (~bad).tolist()


def _points(points: np.ndarray | None) -> np.ndarray:
    """Fixed points as (m, 3) float64 (z 0 where not given)."""
    if points is None:
        return np.zeros((0, 3))
    points = np.asarray(points, dtype=np.float64).reshape(
        -1, np.shape(points)[-1] if np.ndim(points) else 3
    )
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    return points[:, :3]


def _candidates(
    polygons: Sequence[Sequence[np.ndarray]], grids: Sequence[CellGrid]
) -> tuple[list[CellGrid], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Each polygon's window of cells (over its outer ring's box) and the cells strictly
    inside with a value: (owner, row, col, value), rows and columns in the windows."""
    windows: list[CellGrid] = []
    columns: list[tuple[np.ndarray, ...]] = []
    for p, (rings, grid) in enumerate(zip(polygons, grids)):
        outer = np.asarray(rings[0], dtype=np.float64) if len(rings) else np.zeros((0, 3))
        if len(outer) < 3 or not np.isfinite(outer[:, :2]).all():
            window = grid.window(0.0, 0.0, -1.0, -1.0)
        else:
            window = grid.window(*outer[:, :2].min(0), *outer[:, :2].max(0))
        windows.append(window)
        rows, cols = (
            cells_inside(rings, window) if len(outer) >= 3 else (np.zeros(0, np.int64),) * 2
        )
        values = window.values[rows, cols]
        valid = np.isfinite(values)
        rows, cols, values = rows[valid], cols[valid], values[valid]
        columns.append((np.full(len(rows), p, np.int64), rows, cols, values))
    if not columns:
        empty = np.zeros(0, np.int64)
        return windows, (empty, empty, empty, np.zeros(0))
    owner, rows, cols, values = (np.concatenate(c) for c in zip(*columns))
    return windows, (owner, rows, cols, values)


def _cols(windows: Sequence[CellGrid]) -> np.ndarray:
    return np.array([w.shape[1] for w in windows], np.int64)


def _lookup(
    windows: Sequence[CellGrid], candidates: tuple[np.ndarray, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """A flat table over all windows' cells: the candidate index of a cell, -1 for none;
    and each window's first position in it."""
    owner, rows, cols, _values = candidates
    sizes = np.array([w.values.size for w in windows], np.int64)
    base = np.cumsum(sizes) - sizes
    table = np.full(int(sizes.sum()), -1, np.int64)
    table[base[owner] + rows * _cols(windows)[owner] + cols] = np.arange(len(owner))
    return table, base


def _local_maxima(
    pick: np.ndarray,
    error: np.ndarray,
    owner: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    spacing: int,
) -> np.ndarray:
    """Per pick: no other pick of its polygon within ``spacing`` cells (rows and columns)
    has a larger error (ties: the smaller candidate index stays)."""
    if len(pick) < 2:
        return np.ones(len(pick), bool)
    height = int(rows[pick].max()) + 2 * spacing + 1
    width = int(cols[pick].max()) + 2 * spacing + 1

    def key(row_shift: int, col_shift: int) -> np.ndarray:
        row = rows[pick] + spacing + row_shift
        col = cols[pick] + spacing + col_shift
        return (owner[pick] * height + row) * width + col

    own = key(0, 0)
    order = np.argsort(own)
    sorted_keys = own[order]
    keep = np.ones(len(pick), bool)
    for dr in range(-spacing, spacing + 1):
        for dc in range(-spacing, spacing + 1):
            if dr or dc:
                wanted = key(dr, dc)
                at = np.minimum(np.searchsorted(sorted_keys, wanted), len(pick) - 1)
                other = order[at]
                found = sorted_keys[at] == wanted
                stronger = (error[other] > error) | ((error[other] == error) & (pick[other] < pick))
                keep &= ~(found & stronger)
    return keep
