"""The BSP-tree triangulation (docs/algorithm.md, sections 3 and 4).

Pipeline per polygon: normalise the rings (``rings``), join the islands (``bridges``), then
build the BSP tree over the bridged vertex sequence with an explicit work list.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Generator, Iterable, Sequence

import numpy as np

from ..geometry.bridges import bridge_islands, remove_spikes, ring_edges, split_touching
from ..geometry.delaunay_mesh import delaunay_faults
from ..geometry.points import as_point_array, first_occurrences, strictly_inside
from ..geometry.predicates import (
    area_surely_clear,
    grid_exact,
    incircle_many,
    incircle_one,
    orient,
    orient_float,
    orient_many,
    orient_sure_many,
    ring_area_sign,
    shoelace_products,
    strictly_between,
    sum_error,
)
from ..geometry.predicates_batch import sure_signs
from ..geometry.rings import PreparedRings, normalise_rings, prepare, ring_label
from ..geometry.spatial_index import ChainBoxes, SegmentGrid
from ..rules import ApexRule, DelaunayRule, ElevationRule, FirstRule, get_rule
from ..triangulation import Triangulation, TriangulationError
from .delaunay_points import points_mesh, tree_of_cdt
from .elevation_order import ElevationWindows
from .lockstep import straight_runs
from .one_by_one import edge_blocks, facing_one, first_nodes, run_bounds
from .points_batch import InsertedMesh
from .shadows import Shadows
from .subtrees import (
    DELAUNAY_POSITIONS,
    MAX_POSITIONS,
    REFINE,
    REFINED_POSITIONS,
    Refine,
    SubtreeRequest,
    Subtrees,
    built_if_worth,
    worth_refining,
)
from .visible_apex import WIDE, visible_apex

INVALID_MODES = ("fail", "as_given")
# a tree built in steps: it yields its lock-step sub-polygons and gets their subtrees back
# (None: build them one step at a time; REFINE: split the larger ones further and ask again)
Steps = Generator[SubtreeRequest, Subtrees | Refine | None, Triangulation]
_FIRST = FirstRule()
# Sub-polygons up to this many vertices test their candidates against all their edges at once;
# larger sequences use a grid over the edges.
SMALL_SEQUENCE = 64
# Candidates tested together per step in small sub-polygons with rule "first".
_FIRST_CHUNK = 1
_MAX_CHUNK = 64
# Edges remembered per base as likely blockers of its next candidates.
_MAX_BLOCKERS = 256
_MAX_RECENT_BLOCKERS = 16
# Candidates per base tested one by one before the facing test switches to chunks.
_SCALAR_CANDIDATES = 16
# Sub-polygons longer than this take their candidates closest elevation first from shared
# sorted windows (rule "elevation"); the lock-step builder takes those under 256 positions.
_WINDOWED = 256
# Bands of at most this many candidates are tested lazily, candidate by candidate.
_LAZY_BAND = 256
# Positions next to either end of a base whose shadows rule "elevation" casts at once.
_NEAR_SHADOWS = 64
# rule "elevation": sub-polygons longer than this bound their apexes in a box first
_REGION_SPAN = 4096
# rule "elevation": bands of at most this many candidates are ordered in Python floats
_PYTHON_BAND = 64
# The rule "elevation" error bound's factor (rules.ElevationRule).
_EPS8 = 8.0 * 2.0**-53
# Largest chunk of candidates filtered at once by rule "first" on long runs.
_MAX_FIRST_CHUNK = 1024
# Candidates left after the scalar ones beyond which rule "first" skips shadowed chain boxes.
_SHADOWED = 64
# Nodes asked of visible_apex before its share of too wide queries decides (_visible_apex_pays).
_VISIBLE_TRIAL = 64
# rule first, _one_step_subtree: edge tests per position of a sub-polygon given to the scalar
# tests before _grow takes over
_FIRST_BLOCK_TESTS = 256
# Nodes of a fan (rule "first", long sub-polygons) decided in the first batch, and at most in
# one batch (the batches double in size while every node passes).
_FAN_BATCH = 16
_MAX_FAN_BATCH = 256
# The size of the triangle holding a batch, relative to its outer rays, beyond which the
# batch's nodes are left to one step at a time.
_FAN_REACH = 1e3
# Angles (radians) closer than this are not trusted to compare (fan sectors), nor the angle
# of a point within this many chain-box paddings (1e-9 of the coordinates' scale) of the fan's
# centre in either axis (its rounding moves the angle by at most about 4e-9).
_FAN_MARGIN = 1e-7
_FAN_NEAR = 64.0
# Positions a fan's node may skip back from the top of its base (a pocket: each fails
# condition 1) before its apex; a node whose apex lies further back ends the batch.
_FAN_POCKET = 16
_TWO_PI = 2.0 * math.pi
# Rule "delaunay" on long sub-polygons first tries the positions this close to either end of
# the base (most apexes lie there).
_NEAR_ENDS = 16
# Squared radii below this give no circle: the point filters square distances in the input's
# own units, which lose their precision as they near the subnormal range.
_LEAST_SQUARE = 2.0**-900


def _rows(length: int, *rows: np.ndarray | float) -> np.ndarray:
    """Stack arrays and scalars (broadcast) into a (len(rows), length) array."""
    out = np.empty((len(rows), length))
    for index, row in enumerate(rows):
        out[index] = row
    return out


def facing_candidates(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: int,
    hi: int,
    candidates: np.ndarray,
    exact_inputs: bool = False,
) -> np.ndarray:
    """Cheap necessary part of the correct-triangle test, vectorised over candidates.

    Condition 1 (strictly left of the chord) and condition 4 (the triangle lies in the
    sequence's interior angle at the apex position: this tells apart duplicate occurrences
    of one point, at bridge ends and touching rings).
    """
    count = len(candidates)
    ax, ay, bx, by = sx[hi], sy[hi], sx[lo], sy[lo]
    cx, cy = sx[candidates], sy[candidates]
    px, py = sx[candidates - 1], sy[candidates - 1]
    nx, ny = sx[candidates + 1], sy[candidates + 1]
    # rows: chord side, turn at the apex, then a and b against the apex's two edges
    signs = orient_many(
        _rows(count, ax, px, cx, px, cx, px),
        _rows(count, ay, py, cy, py, cy, py),
        _rows(count, bx, cx, nx, cx, nx, cx),
        _rows(count, by, cy, ny, cy, ny, cy),
        _rows(count, cx, nx, ax, ax, bx, bx),
        _rows(count, cy, ny, ay, ay, by, by),
        exact_inputs,
    )
    turn = signs[1]
    after_next = signs[2:6:2] >= 0
    after_prev = signs[3:6:2] >= 0
    spike = (turn == 0) & ((nx - cx) * (px - cx) + (ny - cy) * (py - cy) > 0)
    inside = np.where(
        turn > 0,
        after_next & after_prev,
        np.where(turn < 0, after_next | after_prev, after_next | spike),
    )
    return (signs[0] > 0) & inside[0] & inside[1]


def correct_candidates(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: int,
    hi: int,
    candidates: np.ndarray,
    edges: np.ndarray | None = None,
    facing: bool = False,
    exact_inputs: bool = False,
) -> np.ndarray:
    """Mask of ``candidates`` (positions) forming a correct triangle on the base (hi, lo).

    ``sx``, ``sy`` are the sequence coordinates (position m repeats position 0). ``edges`` are
    the positions i of the edges (i, i+1) to test; None means every edge of the sub-polygon.
    ``facing=True`` says the candidates already passed :func:`facing_candidates`;
    ``exact_inputs`` is :func:`predicates.grid_exact` of the coordinates.
    Implements the conditions of docs/algorithm.md section 4 exactly.
    """
    if facing:
        ok = np.ones(len(candidates), dtype=bool)
    else:
        ok = facing_candidates(sx, sy, lo, hi, candidates, exact_inputs)
    if edges is None:
        edges = np.arange(lo, hi)
    if not ok.any() or len(edges) == 0:
        return ok
    ax, ay, bx, by = sx[hi], sy[hi], sx[lo], sy[lo]
    live = np.flatnonzero(ok)
    cx, cy = sx[candidates[live]], sy[candidates[live]]
    # only edges whose bounding box meets the triangle's can matter (exact comparisons)
    ex0, ey0, ex1, ey1 = sx[edges], sy[edges], sx[edges + 1], sy[edges + 1]
    tx0 = np.minimum(np.minimum(ax, bx), cx)[:, None]
    tx1 = np.maximum(np.maximum(ax, bx), cx)[:, None]
    ty0 = np.minimum(np.minimum(ay, by), cy)[:, None]
    ty1 = np.maximum(np.maximum(ay, by), cy)[:, None]
    near = (
        (np.maximum(ex0, ex1) >= tx0)
        & (np.minimum(ex0, ex1) <= tx1)
        & (np.maximum(ey0, ey1) >= ty0)
        & (np.minimum(ey0, ey1) <= ty1)
    )
    rows, cols = np.nonzero(near)
    failing, _ = pairs_failing(sx, sy, lo, hi, candidates[live], rows, edges[cols], exact_inputs)
    ok[live[failing]] = False
    return ok


def pairs_failing(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: int,
    hi: int,
    candidates: np.ndarray,
    rows: np.ndarray,
    edges: np.ndarray,
    exact_inputs: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Indices into ``candidates`` that fail conditions 2 or 3 on one of the given pairs, and
    the edges that made them fail.

    Pair k is candidate ``candidates[rows[k]]`` with the edge (edges[k], edges[k] + 1).
    """
    if len(rows) == 0:
        return rows, rows
    ax, ay, bx, by = sx[hi], sy[hi], sx[lo], sy[lo]
    cx, cy = sx[candidates], sy[candidates]
    count = len(rows)
    ex0, ey0, ex1, ey1 = sx[edges], sy[edges], sx[edges + 1], sy[edges + 1]
    # edge end points of every (candidate, edge) pair: p's then q's
    px = np.concatenate([ex0, ex1])
    py = np.concatenate([ey0, ey1])
    pcx = np.concatenate([cx[rows], cx[rows]])
    pcy = np.concatenate([cy[rows], cy[rows]])
    # f[0]: side of line a->b, f[1]: of b->c, f[2]: of c->a
    f = orient_many(
        _rows(2 * count, ax, bx, pcx),
        _rows(2 * count, ay, by, pcy),
        _rows(2 * count, bx, pcx, ax),
        _rows(2 * count, by, pcy, ay),
        px,
        py,
        exact_inputs,
    )
    bad = np.zeros(len(candidates), dtype=bool)
    blockers = [edges[:0]]
    pair_rows = np.concatenate([rows, rows])
    pair_edges = np.concatenate([edges, edges])
    # condition 3: a vertex in the relative interior of a new side
    for side, (ux, uy) in ((1, (bx, by)), (2, (ax, ay))):
        zero = np.flatnonzero(f[side] == 0)
        if len(zero):
            inside = strictly_between(px[zero], py[zero], ux, uy, pcx[zero], pcy[zero])
            bad[pair_rows[zero[inside]]] = True
            blockers.append(pair_edges[zero[inside]])
    # condition 2: an edge meets the open triangle (separating-axis test, all exact signs)
    inward = (np.maximum(f[:, :count], f[:, count:]) > 0).all(axis=0)
    if inward.any():
        hit = np.flatnonzero(inward)
        qx0, qy0, qx1, qy1 = px[hit], py[hit], px[hit + count], py[hit + count]
        g = orient_many(
            qx0, qy0, qx1, qy1,
            _rows(len(hit), ax, bx, pcx[hit]),
            _rows(len(hit), ay, by, pcy[hit]),
            exact_inputs,
        )  # fmt: skip
        degenerate = (qx0 == qx1) & (qy0 == qy1)
        crossing = ((g.min(axis=0) < 0) & (g.max(axis=0) > 0)) | degenerate
        if crossing.any():
            bad[rows[hit[crossing]]] = True
            blockers.append(edges[hit[crossing]])
    return np.flatnonzero(bad), np.concatenate(blockers)


def _exponent(*values: float) -> int:
    """The binary exponent of the largest |value| (0 where none is finite and non-zero):
    ``math.ldexp(value, -exponent)`` brings it into [0.5, 1), exactly, so products of such
    lengths neither overflow nor underflow."""
    largest = max(map(abs, values))
    return math.frexp(largest)[1] if 0 < largest < math.inf else 0


def _circle_reach(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    """Distance from the midpoint of a-b beyond which the circle through a, b, c has no point
    on c's side of the line a-b, computed on the differences scaled by a power of two; only a
    search extent, so with a margin of 1e-6 of it and 1e-12 of the coordinates' magnitude
    (the midpoint's own rounding, which matters far from the origin)."""
    mx, my = 0.5 * (ax + bx), 0.5 * (ay + by)
    nx, ny = ay - by, bx - ax  # a normal of the base, of length 2 * half
    ux, uy = cx - mx, cy - my
    e = _exponent(nx, ny, ux, uy)
    nx, ny, ux, uy = math.ldexp(nx, -e), math.ldexp(ny, -e), math.ldexp(ux, -e), math.ldexp(uy, -e)
    half = 0.5 * math.hypot(ny, -nx)
    toward = ux * nx + uy * ny
    if toward == 0:
        return math.inf
    offset = abs((ux * ux + uy * uy - half * half) / toward)  # centre offset / |n|
    reach = half
    if ux * ux + uy * uy > half * half:  # the centre is on c's side
        centre = offset * half
        reach = centre + math.hypot(centre, half)
    magnitude = max(abs(ax), abs(ay), abs(bx), abs(by), abs(cx), abs(cy))
    return math.ldexp(reach, e) * (1.0 + 1e-6) + 1e-12 * magnitude + 1e-300


def _circle_around(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, reach: float
) -> tuple[float, float, float] | None:
    """The circle through a, b and c as (centre x, centre y, a squared radius beyond which a
    point is surely strictly outside: the float radius plus a margin of 1e-6 ``reach`` and
    1e-12 of the coordinates' magnitude, far above the rounding of a well-shaped corner's
    centre and of the points' distances to it), computed at the corner of the largest angle
    on the differences scaled by a power of two; None where that angle is within about half
    a degree of 180 (the centre not trusted), or the squared radius is not finite or below
    ``_LEAST_SQUARE``."""
    e = _exponent(bx - ax, by - ay, cx - ax, cy - ay, cx - bx, cy - by)
    best = None
    for px, py, qx, qy, rx, ry in ((ax, ay, bx, by, cx, cy), (bx, by, cx, cy, ax, ay),
                                   (cx, cy, ax, ay, bx, by)):  # fmt: skip
        ux, uy = math.ldexp(qx - px, -e), math.ldexp(qy - py, -e)
        vx, vy = math.ldexp(rx - px, -e), math.ldexp(ry - py, -e)
        uu, vv = ux * ux + uy * uy, vx * vx + vy * vy
        d = 2.0 * (ux * vy - uy * vx)
        scale = math.sqrt(uu) * math.sqrt(vv)
        if scale > 0 and (best is None or abs(d) * best[0] > best[1] * scale):
            best = (scale, abs(d), px, py, ux, uy, vx, vy, uu, vv, d)
    if best is None or not best[1] >= 2e-2 * best[0] or not reach < math.inf:
        return None
    _, _, px, py, ux, uy, vx, vy, uu, vv, d = best
    ox, oy = math.ldexp((vy * uu - uy * vv) / d, e), math.ldexp((ux * vv - vx * uu) / d, e)
    magnitude = max(abs(ax), abs(ay), abs(bx), abs(by), abs(cx), abs(cy))
    radius = math.hypot(ox, oy) + 1e-6 * reach + 1e-12 * magnitude
    ox, oy, limit = px + ox, py + oy, radius * radius
    if not (_LEAST_SQUARE < limit < math.inf and math.isfinite(ox) and math.isfinite(oy)):
        return None
    return ox, oy, limit


class _Ties:
    """Rule elevation's correct candidates found on one base (z1, z2), by the elevations
    exactly as far from the base's mean as theirs: their own z, and the one on the other
    side (z1 + z2 - z, where that and z1 + z2 are exact). A candidate at such an elevation
    and after one of them in candidate order (a smaller position) cannot be chosen: the rule
    breaks ties by candidate order. Inactive (nothing settled) for other rules."""

    def __init__(self, z1: float, z2: float, active: bool) -> None:
        self.total = z1 + z2
        self.active = active
        self.mirrors = active and sum_error(z1, z2, self.total) == 0.0
        self.after: dict[float, int] = {}  # elevation -> largest position found at it
        self.levels: list[float] = []  # the distinct z of the correct candidates found

    def settled(self, z: float, position: int) -> bool:
        """The candidate at ``position`` with elevation ``z`` cannot be chosen."""
        return position < self.after.get(z, -1)

    def add(self, z: float, position: int) -> None:
        """Record the correct candidate at ``position`` with elevation ``z``."""
        if not self.active:
            return
        if z not in self.levels:
            self.levels.append(z)
        self.after[z] = max(self.after.get(z, -1), position)
        mirror = self.total - z
        if self.mirrors and sum_error(self.total, -z, mirror) == 0.0:
            self.after[mirror] = max(self.after.get(mirror, -1), position)


def _remember(blockers: list[int], edge: int) -> None:
    """Put ``edge`` first in the short list of recent blockers."""
    if edge in blockers:
        blockers.remove(edge)
    blockers.insert(0, edge)
    del blockers[_MAX_RECENT_BLOCKERS:]


class _Rows:
    """Output rows of a tree being built: triangles, parent, depth, side; ``count`` used."""

    def __init__(self, capacity: int) -> None:
        self.triangles = np.empty((capacity, 3), dtype=np.int64)
        self.parent = np.empty(capacity, dtype=np.int64)
        self.depth = np.empty(capacity, dtype=np.int64)
        self.side = np.empty(capacity, dtype=np.int8)
        self.count = 0


class _Tree:
    """BSP construction over one bridged sequence."""

    def __init__(
        self,
        prepared: PreparedRings,
        sequence: np.ndarray,
        z: np.ndarray,
        rule: ApexRule,
        as_given: bool = False,
        tick: Callable[[float], None] | None = None,
    ) -> None:
        self.prepared = prepared
        self.tick = tick
        self.as_given = as_given
        self._prefix: np.ndarray | None = None
        self.used_fallback = False  # some base of invalid input had no correct triangle
        self.loss_watch: _LossWatch | None = None  # as given: may stop a tree losing area
        self.ids = np.concatenate([sequence, sequence[:1]])
        self.sx = prepared.x[self.ids]
        self.sy = prepared.y[self.ids]
        self.sz = z[self.ids]
        self.xs, self.ys = self.sx.tolist(), self.sy.tolist()  # for the scalar tests
        self._zs: list[float] | None = None  # see zs
        self.rule = rule
        self.m = len(sequence)
        self.exact = grid_exact(self.sx, self.sy)
        self.sign = orient_float if self.exact else orient
        self._grid: SegmentGrid | None = None
        self._windows: ElevationWindows | None = None  # rule "elevation", long sub-polygons
        self._points: SegmentGrid | None = None  # positions, for rule "delaunay"
        self.boxes = ChainBoxes(self.sx, self.sy) if self.m > SMALL_SEQUENCE else None
        # the last long base's blockers: in a chain of nodes that each cut off a few
        # vertices, the next base's far candidates are mostly blocked by the same edges
        self._recent: list[int] = []
        self._bends: tuple[list[int], list[int]] | None = None  # see _straight_runs
        self._seen = [0, 0]  # nodes asked of visible_apex, and of them found too wide
        self._z_steps: list[int] | None = None  # rule "elevation": see _level
        # called now and then in a node's long search, which tells no share (it may raise)
        self.alive: Callable[[], None] | None = None

    @property
    def zs(self) -> list[float]:
        """The elevations per position as Python floats (rule "elevation"), made once."""
        if self._zs is None:
            self._zs = self.sz.tolist()
        return self._zs

    @property
    def grid(self) -> SegmentGrid | None:
        """Grid over the sequence's edges (the exhaustive rules' candidate tests), built once
        on first use; None for small sequences."""
        if self._grid is None and self.m > SMALL_SEQUENCE:
            starts = np.arange(self.m)
            self._grid = SegmentGrid(
                self.sx[starts], self.sy[starts], self.sx[starts + 1], self.sy[starts + 1]
            )
        return self._grid

    def _apex(self, lo: int, hi: int, v1: int, v2: int) -> int:
        """Position of the apex on the base (v1, v2) of sub-polygon [lo, hi], or -1."""
        rule = self.rule
        if not rule.exhaustive:
            apex = self._first_apex(lo, hi)
            return -1 if apex < 0 else rule.choose(np.array([apex]), v1, v2, self.sz)
        if isinstance(rule, ElevationRule):
            return self._closest_apex(lo, hi, v1, v2)
        if getattr(rule, "in_plane", False):
            return self._delaunay_apex(lo, hi)
        sx, sy = self.sx, self.sy
        small = self.grid is None or hi - lo <= SMALL_SEQUENCE
        found: list[np.ndarray] = []
        blockers: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
        start = hi - 1
        size = _FIRST_CHUNK
        while start > lo:
            stop = max(start - size, lo)
            chunk = np.arange(start, stop, -1)
            start, size = stop, min(size * 2, _MAX_CHUNK)
            chunk = chunk[facing_candidates(sx, sy, lo, hi, chunk, self.exact)]
            if len(chunk) == 0:
                continue
            if small:
                mask = correct_candidates(
                    sx, sy, lo, hi, chunk, facing=True, exact_inputs=self.exact
                )
                correct = chunk[mask]
            else:
                correct = self._grid_correct(lo, hi, chunk, rule.exhaustive, blockers)
            if len(correct):
                found.append(correct)
                if not rule.exhaustive:
                    break
        if not found:
            return -1
        return rule.choose(np.concatenate(found), v1, v2, self.sz)

    def _level(self, lo: int, hi: int) -> bool:
        """The candidates of sub-polygon [lo, hi] all have the same z (exactly): rule
        "elevation" then finds them all equally close and takes the first correct one in
        candidate order, which is rule "first"'s apex."""
        if not self._ties_in_order:
            return False
        if self._z_steps is None:
            # how many positions up to p have another z than the one before
            z = self.sz
            self._z_steps = np.concatenate([[0], np.cumsum(z[1:] != z[:-1])]).tolist()
        return hi - lo < 3 or self._z_steps[hi - 1] == self._z_steps[lo + 1]

    def _closest_apex(self, lo: int, hi: int, v1: int, v2: int) -> int:
        """:meth:`_apex` under rule "elevation": the facing candidates are tested closest
        elevation first, until no untested one can be as close as the closest correct one;
        the rule then chooses among the correct ones found, as among all of them. Where all
        candidates are level, the first correct one (:meth:`_level`)."""
        if self._level(lo, hi):
            return self._first_apex(lo, hi)
        if self.boxes is not None and hi - lo > _WINDOWED:
            if self._windows is None:
                self._windows = ElevationWindows(self.sz)
            return self._closest_apex_windows(lo, hi, v1, v2)
        sx, sy, z = self.sx, self.sy, self.sz
        candidates = np.arange(hi - 1, lo, -1)
        # those surely right of the chord leave first (a float sign beyond its error bound,
        # cheaper than the exact conditions 1 and 4)
        ax, ay, bx, by = sx[hi], sy[hi], sx[lo], sy[lo]
        candidates = candidates[sure_signs(ax, ay, bx, by, sx[candidates], sy[candidates]) >= 0]
        candidates = candidates[facing_candidates(sx, sy, lo, hi, candidates, self.exact)]
        if len(candidates) == 0:
            return -1
        z1, z2 = float(z[v1]), float(z[v2])
        zc = z[candidates]
        approx = np.abs(2.0 * zc - z1 - z2)
        # the rule's own error bound: candidates within it of the best are decided exactly
        error = 8.0 * 2.0**-53 * (2.0 * np.abs(zc) + abs(z1) + abs(z2)) + 1e-300
        widest = float(error.max())
        order = np.argsort(approx, kind="stable")
        if self.boxes is not None and hi - lo > SMALL_SEQUENCE:
            return self._closest_apex_scalar(lo, hi, v1, v2, candidates, order, approx, error)
        found: list[np.ndarray] = []
        best = np.inf
        start, size = 0, _FIRST_CHUNK
        while start < len(order):
            if found and float(approx[order[start]]) - widest > best:
                break  # every untested candidate is surely farther than a correct one
            chosen = order[start : start + size]
            start, size = start + size, min(size * 2, _MAX_CHUNK)
            chunk = candidates[chosen]
            mask = correct_candidates(sx, sy, lo, hi, chunk, facing=True, exact_inputs=self.exact)
            good = chosen[mask]
            if len(good):
                found.append(good)
                best = min(best, float((approx[good] + error[good]).min()))
                order = self._without_level_of(order, start, zc, zc[good])
        if not found:
            return -1
        # in candidate order, as the rule expects
        return self.rule.choose(candidates[np.sort(np.concatenate(found))], v1, v2, z)

    @property
    def _ties_in_order(self) -> bool:
        """The rule is rule "elevation" itself, whose ties go to the first in candidate order."""
        return type(self.rule) is ElevationRule

    def _without_level_of(
        self, order: np.ndarray, start: int, zc: np.ndarray, levels: np.ndarray
    ) -> np.ndarray:
        """``order`` (indices into the candidates, by closeness, candidate order among
        equals) without its untested entries (from ``start``) whose z is one of ``levels``,
        the z of correct candidates found. Such a candidate is exactly as close as one of
        them and comes after it in candidate order (equal z, equal float value: the stable
        order keeps candidate order), so the rule cannot choose it."""
        if not self._ties_in_order or start >= len(order):
            return order
        rest = order[start:]
        keep = ~np.isin(zc[rest], levels)
        if keep.all():
            return order
        return np.concatenate([order[:start], rest[keep]])

    def _closest_apex_windows(self, lo: int, hi: int, v1: int, v2: int) -> int:
        """:meth:`_closest_apex` for long sub-polygons: the candidates come band by band,
        closest elevation first, from a window sorted once for many nodes
        (:class:`.elevation_order.ElevationWindows`), each facing one tested with the scalar
        exact test (:meth:`_blocked`), until every untested one is surely farther than a
        correct one found; the rule then chooses among the correct ones found. Bases of more
        than ``_REGION_SPAN`` positions cast the near vertices' shadows first; where these
        bound the correct apexes in a box (:meth:`.shadows.Shadows.region_box`), each band
        drops the candidates outside it before any test."""
        windows, z = self._windows, self.sz
        xs, ys = self.xs, self.ys
        z1, z2 = float(z[v1]), float(z[v2])
        # the rule's error bound for any candidate of the window
        widest = _EPS8 * (2.0 * windows.widest_z(lo, hi) + abs(z1) + abs(z2)) + 1e-300
        blockers = self._carried(lo, hi)
        shadows: Shadows | None = None
        area = None
        if hi - lo > _REGION_SPAN:
            # the near vertices' shadows often bound the correct apexes in a small box: the
            # candidates outside it leave each band first
            shadows = self._near_shadows(lo, hi, blockers)
            area = shadows.region_box()
        found: list[int] = []
        best = math.inf
        ties = _Ties(z1, z2, self._ties_in_order)
        looked = 0  # candidates given the facing test one by one
        ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
        for band, floor in windows.bands(lo, hi, z1 + z2):
            if self.alive is not None:
                self.alive()
            if area is not None:
                xmin, ymin, xmax, ymax = area
                x, y = self.sx[band], self.sy[band]
                band = band[(x >= xmin) & (x <= xmax) & (y >= ymin) & (y <= ymax)]
            lazy = len(band) <= _LAZY_BAND
            if not lazy or looked >= _SCALAR_CANDIDATES:
                # wide bands (elevations close or equal), and the later bands of a node that
                # did not find its apex among its first candidates: those surely right of the
                # chord and those in the shadows leave at once
                band = band[sure_signs(ax, ay, bx, by, self.sx[band], self.sy[band]) >= 0]
                if shadows is not None and len(band):
                    band = band[~shadows.shadowed_many(self.sx, self.sy, band)]
            if not lazy:
                # wide bands: conditions 1 and 4, then the edges that blocked earlier
                # candidates, against the whole band at once (narrow ones test each candidate
                # only when its turn comes)
                band = band[facing_candidates(self.sx, self.sy, lo, hi, band, self.exact)]
                if len(band) > _SCALAR_CANDIDATES and blockers:
                    band = self._not_blocked_by(lo, hi, band, blockers)
            if len(band) > _PYTHON_BAND:
                zc = z[band]
                approx = np.abs(2.0 * zc - z1 - z2)
                error = _EPS8 * (2.0 * np.abs(zc) + abs(z1) + abs(z2)) + 1e-300
                approx_list, error_list = approx.tolist(), error.tolist()
                band_list, z_list = band.tolist(), zc.tolist()
                order = np.argsort(approx, kind="stable").tolist()
            elif len(band):
                # the same values in Python floats (the same operations in the same order),
                # cheaper than numpy calls on a few candidates
                band_list = band.tolist()
                zs = self.zs
                z_list = [zs[p] for p in band_list]
                approx_list = [abs(2.0 * value - z1 - z2) for value in z_list]
                a1, a2 = abs(z1), abs(z2)
                error_list = [_EPS8 * (2.0 * abs(value) + a1 + a2) + 1e-300 for value in z_list]
                order = sorted(range(len(band_list)), key=approx_list.__getitem__)
            if len(band):
                for index in order:
                    if found and approx_list[index] - widest > best:
                        break  # this band's others too are surely farther than a correct one
                    c = band_list[index]
                    if ties.settled(z_list[index], c):
                        continue
                    # narrow bands: each test only when the candidate's turn comes
                    if lazy:
                        looked += 1
                        if not facing_one(xs, ys, lo, hi, c):
                            continue
                    if shadows is not None and shadows.shadowed(*shadows.angles(xs[c], ys[c])):
                        continue
                    if not self._blocked(lo, hi, c, blockers):
                        found.append(c)
                        best = min(best, approx_list[index] + error_list[index])
                        ties.add(z_list[index], c)
                    elif shadows is None:
                        # a candidate that fails usually holds a vertex next to the base:
                        # those vertices' shadows rule out the others that hold one
                        shadows = self._near_shadows(lo, hi, blockers)
                    else:
                        shadows.add_edge(blockers[0])
            if found and floor - widest > best:
                break  # every later band is surely farther than a correct one
        self._recent = blockers
        if not found:
            return -1
        # in candidate order (decreasing position), as the rule expects
        return self.rule.choose(np.sort(np.array(found, dtype=np.int64))[::-1], v1, v2, z)

    def _closest_apex_scalar(
        self,
        lo: int,
        hi: int,
        v1: int,
        v2: int,
        candidates: np.ndarray,
        order: np.ndarray,
        approx: np.ndarray,
        error: np.ndarray,
    ) -> int:
        """:meth:`_closest_apex` for long sub-polygons: the candidates tested one by one with
        the scalar exact test over the chain boxes (:meth:`_blocked`), closest elevation
        first, stopping as soon as no untested one can be as close as a correct one."""
        widest = float(error.max())
        approx_list, error_list = approx.tolist(), error.tolist()
        zc = self.sz[candidates]
        z_list, position = zc.tolist(), candidates.tolist()
        blockers = self._carried(lo, hi)
        found: list[int] = []
        ties = _Ties(float(self.sz[v1]), float(self.sz[v2]), self._ties_in_order)
        best = math.inf
        start, size = 0, 1
        while start < len(order):
            chosen = order[start : start + size]
            start, size = start + size, min(size * 2, _MAX_CHUNK)
            if found and approx_list[int(chosen[0])] - widest > best:
                break
            chunk = candidates[chosen]
            if len(chunk) > 1 and blockers:
                # the edges that blocked earlier candidates, against the whole chunk at once
                kept = self._not_blocked_by(lo, hi, chunk, blockers)
                chosen = chosen[np.isin(chunk, kept)]
            known = len(ties.levels)
            for index in chosen.tolist():
                if found and approx_list[index] - widest > best:
                    break  # every untested candidate is surely farther than a correct one
                if ties.settled(z_list[index], position[index]):
                    continue
                if not self._blocked(lo, hi, position[index], blockers):
                    found.append(index)
                    ties.add(z_list[index], position[index])
                    best = min(best, approx_list[index] + error_list[index])
            if len(ties.levels) > known:
                order = self._without_level_of(order, start, zc, np.array(ties.levels))
        self._recent = blockers
        if not found:
            return -1
        # in candidate order, as the rule expects
        return self.rule.choose(candidates[np.sort(found)], v1, v2, self.sz)

    def _delaunay_apex(self, lo: int, hi: int) -> int:
        """:meth:`_apex` under rule "delaunay" (its ``choose_in_plane``).

        Small sub-polygons test every candidate. Larger ones search outwards from the base's
        midpoint through a grid over the positions: a box that doubles until it holds the
        best correct candidate's circle on the candidates' side of the base (no candidate
        outside that circle can see the base under a larger angle, and cocircular ones lie
        on it), so the choice is the one the test of every candidate would give.
        """
        sx, sy, xs, ys, rule = self.sx, self.sy, self.xs, self.ys, self.rule
        if self.grid is None or hi - lo <= SMALL_SEQUENCE:
            return self._delaunay_small(lo, hi, np.arange(hi - 1, lo, -1))
        if self._points is None:
            px, py = sx[: self.m], sy[: self.m]
            self._points = SegmentGrid(px, py, px, py)
        points = self._points
        apex = self._delaunay_near_ends(lo, hi)
        if apex >= 0:
            return apex
        ax, ay, bx, by = float(sx[hi]), float(sy[hi]), float(sx[lo]), float(sy[lo])
        mx, my = 0.5 * (ax + bx), 0.5 * (ay + by)
        half = 0.5 * math.hypot(bx - ax, by - ay)
        # a first box of twice the base (or a grid cell) holds most bases' circles at once
        radius = 2.0 * max(half, points.size_x, points.size_y)
        full = 2.0 * max(points.size_x * points.nx, points.size_y * points.ny) + radius
        nx, ny = ay - by, bx - ax  # the base's normal towards the candidates
        half2 = half * half
        seen = np.zeros(0, dtype=np.int64)
        untested = np.zeros(0, dtype=np.int64)
        sure = np.zeros(0, dtype=bool)  # per untested position: surely left of the chord
        pool: list[np.ndarray] = []
        best = -1
        blockers: list[int] = []
        while True:
            found = np.unique(points.query_box(mx - radius, my - radius, mx + radius, my + radius))
            found = found[(found > lo) & (found < hi)]
            fresh = np.setdiff1d(found, seen, assume_unique=True)
            seen = found
            # the positions surely right of the chord leave (float signs beyond their error
            # bound; an overflow is not sure); the rest are ordered, and each is tested
            # exactly (conditions 1 and 4, then the edges) only when its turn comes
            with np.errstate(over="ignore", invalid="ignore"):
                side = orient_sure_many(ax, ay, bx, by, sx[fresh], sy[fresh])
            keep = side >= 0
            untested = np.concatenate([untested, fresh[keep]])
            sure = np.concatenate([sure, side[keep] > 0])
            size = 1
            while len(untested):
                if self.alive is not None:
                    self.alive()
                if best >= 0:
                    # strictly outside the best circle: never better (the circles' parts on
                    # this side of the base shrink as the best improves). Those beyond its
                    # reach from the midpoint or surely outside its float circle leave first,
                    # the rest take the exact test (a grid cell along a densely digitised
                    # boundary holds hundreds of positions, nearly all far outside)
                    cx, cy = float(sx[best]), float(sy[best])
                    reach = _circle_reach(ax, ay, bx, by, cx, cy)
                    px, py = sx[untested], sy[untested]
                    near = np.abs(px - mx) <= reach
                    near &= np.abs(py - my) <= reach
                    circle = _circle_around(ax, ay, bx, by, cx, cy, reach)
                    if circle is not None:
                        ox, oy, limit = circle
                        px, py = px - ox, py - oy
                        near &= px * px + py * py <= limit
                    untested, sure = untested[near], sure[near]
                    if len(untested):
                        inside = incircle_many(
                            ax, ay, bx, by, sx[best], sy[best], sx[untested], sy[untested]
                        )
                        untested, sure = untested[inside >= 0], sure[inside >= 0]
                    if len(untested) == 0:
                        break
                # most promising first: smallest centre offset (largest angle), in float;
                # those not surely left of the chord last
                ux, uy = sx[untested] - mx, sy[untested] - my
                with np.errstate(divide="ignore", invalid="ignore"):  # an order, checked after
                    key = (ux * ux + uy * uy - half2) / (ux * nx + uy * ny)
                key[~sure] = np.inf
                order = np.argsort(key, kind="stable")
                chunk = np.sort(untested[order[:size]])[::-1]  # candidate order
                untested, sure = untested[order[size:]], sure[order[size:]]
                size = min(2 * size, _MAX_CHUNK)
                # the exact tests of each (the chain boxes find the few edges near a long
                # thin triangle that a grid query would gather by the thousand)
                correct = np.array(
                    [
                        c
                        for c in chunk.tolist()
                        if facing_one(xs, ys, lo, hi, c) and not self._blocked(lo, hi, c, blockers)
                    ],
                    dtype=np.int64,
                )
                if len(correct):
                    pool.append(correct)
                    everything = np.sort(np.concatenate(pool))[::-1]
                    best = rule.choose_in_plane(everything, hi, lo, sx, sy)
            if best >= 0:
                if _circle_reach(ax, ay, bx, by, float(sx[best]), float(sy[best])) <= radius:
                    return best
                if radius >= full:
                    return best
            elif radius >= full:
                return -1
            radius *= 2.0

    def _delaunay_near_ends(self, lo: int, hi: int) -> int:
        """:meth:`_delaunay_apex` where its choice is, of the ``_NEAR_ENDS`` positions after
        s_lo and as many before s_hi, the one that sees the base under the largest angle (in
        float), and that is shown in Python scalars; else -1. It is shown where it is
        correct and every other position strictly left of the base lies strictly outside
        its circle (exact), so sees the base under a smaller angle. Only that one position
        can be shown so: the others near the ends lie in its circle (up to rounding)."""
        xs, ys, sign = self.xs, self.ys, self.sign
        ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
        mx, my = 0.5 * (ax + bx), 0.5 * (ay + by)
        half2 = 0.25 * ((bx - ax) * (bx - ax) + (by - ay) * (by - ay))
        nx, ny = ay - by, bx - ax  # the base's normal towards the candidates
        best = None
        for c in (*range(lo + 1, lo + 1 + _NEAR_ENDS), *range(hi - _NEAR_ENDS, hi)):
            ux, uy = xs[c] - mx, ys[c] - my
            toward = ux * nx + uy * ny
            if toward > 0:
                key = (ux * ux + uy * uy - half2) / toward
                if best is None or key < best[0]:
                    best = (key, c)
        if best is None or not facing_one(xs, ys, lo, hi, best[1]):
            return -1
        c = best[1]
        cx, cy = xs[c], ys[c]
        circle = _circle_around(ax, ay, bx, by, cx, cy, _circle_reach(ax, ay, bx, by, cx, cy))
        if circle is None:
            return -1
        ox, oy, limit = circle
        # the triangle lies in its circle: the leaves near the circle hold every edge that
        # may block it too
        runs = list(self.boxes.leaves_near(lo, hi, circle))
        for start, end in runs:
            for p in range(max(start, lo + 1), end):
                dx, dy = xs[p] - ox, ys[p] - oy
                if dx * dx + dy * dy > limit or p == c:
                    continue
                px, py = xs[p], ys[p]
                if (
                    sign(ax, ay, bx, by, px, py) > 0
                    and incircle_one(ax, ay, bx, by, cx, cy, px, py) >= 0
                ):
                    return -1
        return -1 if self._blocked_in(runs, (ax, ay, bx, by, cx, cy), []) else c

    def _delaunay_small(self, lo: int, hi: int, candidates: np.ndarray) -> int:
        """:meth:`_delaunay_apex` of a small sub-polygon: the candidates are tested one by
        one (the scalar exact tests) largest angle first (in float; those not clearly on the
        candidates' side last); each correct one found discards those strictly outside its
        circle (exact), so usually one or two are tested. The rule then chooses among the
        correct ones found, as among all of them."""
        sx, sy, xs, ys = self.sx, self.sy, self.xs, self.ys
        ax, ay, bx, by = float(sx[hi]), float(sy[hi]), float(sx[lo]), float(sy[lo])
        mx, my = 0.5 * (ax + bx), 0.5 * (ay + by)
        half2 = 0.25 * ((bx - ax) * (bx - ax) + (by - ay) * (by - ay))  # no OverflowError
        ux, uy = sx[candidates] - mx, sy[candidates] - my
        toward = ux * (ay - by) + uy * (bx - ax)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            key = np.where(toward > 0, (ux * ux + uy * uy - half2) / toward, np.inf)
        key[np.isnan(key)] = np.inf
        untested = candidates[np.argsort(key, kind="stable")]
        blockers: list[int] = []
        correct: list[int] = []
        best = -1
        while len(untested):
            c = int(untested[0])
            untested = untested[1:]
            if not facing_one(xs, ys, lo, hi, c) or self._blocked(lo, hi, c, blockers):
                continue
            correct.append(c)
            found = np.sort(np.array(correct, dtype=np.int64))[::-1]  # candidate order
            best = self.rule.choose_in_plane(found, hi, lo, sx, sy)
            if len(untested):
                inside = incircle_many(
                    ax, ay, bx, by, sx[best], sy[best], sx[untested], sy[untested]
                )
                untested = untested[inside >= 0]
        return best

    def _first_apex(self, lo: int, hi: int) -> int:
        """The first candidate of sub-polygon [lo, hi] forming a correct triangle, or -1.

        Candidates are tested one by one with the scalar tests; edges that blocked earlier
        candidates of this base often block the next ones too and are tried first.
        """
        xs, ys = self.xs, self.ys
        if self.boxes is not None and hi - lo > SMALL_SEQUENCE and self._visible_apex_pays():
            apex = visible_apex(xs, ys, self.sign, self.boxes, lo, hi)
            self._seen[0] += 1
            if apex == WIDE:
                self._seen[1] += 1
            elif apex is not None:
                return apex
        blockers: list[int] = []
        start = max(hi - 1 - _SCALAR_CANDIDATES, lo)
        # candidates in a straight run on from either corner of the base fail (below)
        low, top = self._straight_runs(lo, hi)
        for c in range(hi - 1, start, -1):
            if top <= c < hi - 1 or lo + 1 < c <= low:
                continue
            if facing_one(xs, ys, lo, hi, c) and not self._blocked(lo, hi, c, blockers):
                return c
        if self.boxes is not None and start - lo > _SHADOWED:
            # the candidates left but those of the runs, then lo + 1 after a run from lo
            first = min(start, top - 1)
            bottom = low + 1 if low > lo + 1 else lo + 1
            apex = -1
            if first >= bottom:
                apex = self._first_apex_shadowed(lo, hi, start, blockers, first, bottom)
            if apex >= 0 or bottom == lo + 1:
                return apex
            c = lo + 1
            if facing_one(xs, ys, lo, hi, c) and not self._blocked(lo, hi, c, blockers):
                return c
            return -1
        # long runs of candidates that do not face the base or that the same few edges block:
        # filter them in chunks
        size = _SCALAR_CANDIDATES
        while start > lo:
            stop = max(start - size, lo)
            chunk = np.arange(start, stop, -1)
            start, size = stop, min(size * 2, _MAX_FIRST_CHUNK)
            chunk = chunk[facing_candidates(self.sx, self.sy, lo, hi, chunk, self.exact)]
            if len(chunk) > 1 and blockers:
                chunk = self._not_blocked_by(lo, hi, chunk, blockers)
            for c in chunk.tolist():
                if not self._blocked(lo, hi, c, blockers):
                    return c
        return -1

    def _visible_apex_pays(self) -> bool:
        """Whether to look for the apex seen from s_lo (``visible_apex``): not once more than
        one in 8 of the 64 or more nodes asked so far found a query too wide (a polygon whose
        triangles hold much of the chain, a spiky star's, where the shadow walk costs less:
        on a star of 100,000 vertices with islands, 1.4 times the time without this)."""
        asked, wide = self._seen
        return asked < _VISIBLE_TRIAL or wide * 8 <= asked

    def _straight_runs(self, lo: int, hi: int) -> tuple[int, int]:
        """``one_by_one.run_bounds`` of the base (hi, lo): candidates in a straight run on from
        either corner fail condition 3. (lo + 1, hi - 1), no run, for short sequences."""
        if self.boxes is None:
            return lo + 1, hi - 1
        return run_bounds(self._runs(), lo, hi)

    def _runs(self) -> tuple[list[int], list[int]]:
        """Per position, the first position at or after it and the last at or before it where
        the sequence bends (``lockstep.straight_runs``), made once."""
        if self._bends is None:
            x, y, m = self.sx, self.sy, self.m
            turn = np.zeros(m + 1)
            turn[1:m] = orient_many(x[:-2], y[:-2], x[1:-1], y[1:-1], x[2:], y[2:], self.exact)
            after, before = straight_runs(x, y, turn, np.zeros(1, dtype=np.int64))
            self._bends = after.tolist(), before.tolist()
        return self._bends

    def _fan_apexes(self, lo: int, top: int, floor: int) -> list[int]:
        """The apexes of a fan at ``lo`` decided at once (rule "first"): node j has the base
        (lo, last), last = ``top`` for j = 0, else node j - 1's apex, with last > ``floor``,
        and its apex is its first candidate back from last that passes condition 1 (at most
        ``_FAN_POCKET`` before it fail it: a pocket, the node's upper child) where that
        candidate forms a correct triangle: every candidate before it fails condition 1, so
        it is the node's first correct one, and node j + 1 is its lower child.

        Checked a batch of nodes at a time. Conditions 1 and 4 per node, and the apexes must
        turn strictly clockwise around ``lo`` within a half-turn from the batch's first base:
        the triangles then lie in disjoint sectors around ``lo``, so no side of one breaks
        another. Conditions 2 and 3 are tested against the edges before that chain in the
        chain boxes that meet a triangle holding the whole batch, and against the pockets'
        edges, each edge only against the nodes whose sectors its angles (with a margin)
        overlap. The edges tested include every edge of each node's sub-polygon that could
        break its triangle (and maybe others: a batch then ends early, and the node is left
        to the full search, which decides the same).
        """
        xs, ys, sign = self.xs, self.ys, self.sign
        ox, oy = xs[lo], ys[lo]
        near = self.boxes.pad * _FAN_NEAR  # closer to lo, a point's angle is not trusted
        apexes: list[int] = []
        size = _FAN_BATCH
        high = top
        while high > floor:
            hx, hy = xs[high], ys[high]
            batch: list[int] = []
            last = high
            while len(batch) < size and last > floor:
                lx, ly = xs[last], ys[last]
                c = last - 1
                stop = max(last - 1 - _FAN_POCKET, lo)
                while c > stop and sign(lx, ly, ox, oy, xs[c], ys[c]) <= 0:
                    c -= 1
                if c <= stop:
                    break
                if sign(ox, oy, xs[c], ys[c], hx, hy) <= 0 or not facing_one(xs, ys, lo, last, c):
                    break
                batch.append(c)
                last = c
            size = min(2 * size, _MAX_FAN_BATCH)
            # the batch's first top, then each node's apex: node j's base top is positions[j]
            positions = [high, *batch]
            fan = self._fan_sectors(lo, positions, near) if batch else None
            if fan is None:
                return apexes
            hull, ray, angles = fan
            hx0, hx1 = min(hull[0::2]), max(hull[0::2])
            hy0, hy1 = min(hull[1::2]), max(hull[1::2])
            buckets: list[list[int]] = [[] for _ in batch]
            runs = list(self.boxes.leaves_meeting(lo, last, last, hull))
            # the pockets' edges (a node whose apex is its top's neighbour has none: that edge
            # is its triangle's side)
            runs += [(c, above) for above, c in zip(positions, batch) if above - c > 1]
            for begin, end in runs:
                # the angle of each edge's end (see _end_angle), kept for the next edge
                known, known_angle = -1, None
                for e in range(begin, end):
                    px, py, qx, qy = xs[e], ys[e], xs[e + 1], ys[e + 1]
                    if (px < hx0 and qx < hx0) or (px > hx1 and qx > hx1):
                        continue
                    if (py < hy0 and qy < hy0) or (py > hy1 and qy > hy1):
                        continue
                    if known != e:
                        known_angle = _end_angle(px - ox, py - oy, ray, near)
                    angle = _end_angle(qx - ox, qy - oy, ray, near)
                    first, final = _sectors_of(known_angle, angle, angles)
                    known, known_angle = e + 1, angle
                    for k in range(first, final + 1):
                        buckets[k].append(e)
            for j, edges in enumerate(buckets):
                if edges:
                    a, c = positions[j], batch[j]
                    corners = (xs[a], ys[a], ox, oy, xs[c], ys[c])
                    xmin, xmax = min(corners[0::2]), max(corners[0::2])
                    ymin, ymax = min(corners[1::2]), max(corners[1::2])
                    for e in edges:
                        if edge_blocks(corners, xmin, ymin, xmax, ymax, xs, ys, e, sign):
                            return apexes + batch[:j]
            apexes += batch
            high = last
        return apexes

    def _fan_sectors(
        self, lo: int, positions: list[int], near: float
    ) -> tuple[tuple[float, float, float, float, float, float], float, list[float]] | None:
        """For the fan at ``lo`` over ``positions`` (its first base's top, then each node's
        apex): a triangle holding it (corners counter-clockwise, at ``lo`` along the rays to
        the first and the last position, with a margin), the first ray's angle and the
        clockwise angles from it of the rays to each position (kept non-decreasing); None
        where the two outer rays are too close to parallel or to opposite for a small such
        triangle, or a position lies within ``near`` of ``lo`` in both axes (its angle not
        trusted)."""
        xs, ys = self.xs, self.ys
        ox, oy = xs[lo], ys[lo]
        ux, uy = xs[positions[0]] - ox, ys[positions[0]] - oy
        wx, wy = xs[positions[-1]] - ox, ys[positions[-1]] - oy
        det = ux * wy - uy * wx
        if not -math.inf < det < 0:
            return None  # also where the products overflow: no trusted triangle
        start = math.atan2(uy, ux)
        reach = 0.0
        angles = []
        turned = 0.0
        for p in positions:
            vx, vy = xs[p] - ox, ys[p] - oy
            angle = _end_angle(vx, vy, start, near)
            if angle is None or angle < 0:
                return None  # at the centre or within near of it: its angle is not trusted
            share = ((vx * wy - vy * wx) + (ux * vy - uy * vx)) / det
            if share != share:
                return None  # nan: an overflow (max would pass it over)
            reach = max(reach, share)
            turned = max(turned, angle)
            angles.append(turned)
        if not reach < _FAN_REACH or turned > math.pi - _FAN_MARGIN:
            return None
        angles[0] = 0.0
        reach *= 1.0 + 1e-6
        hull = (ox + reach * ux, oy + reach * uy, ox, oy, ox + reach * wx, oy + reach * wy)
        return hull, start, angles

    def _carried(self, lo: int, hi: int) -> list[int]:
        """The last long base's blockers that are edges of sub-polygon [lo, hi]: tried
        first (any blocking edge proves a candidate fails, so the choice is the same)."""
        return [e for e in self._recent if lo <= e < hi]

    def _near_shadows(self, lo: int, hi: int, blockers: list[int]) -> Shadows:
        """The shadows on the base of [lo, hi] (no rays) of the ``_NEAR_SHADOWS`` positions
        next to either end of the base and of the ends of the edges ``blockers``, cast at
        once (the points along those edges, which :meth:`Shadows.add_edge` adds too, cost
        more than the few more candidates they would rule out)."""
        shadows = Shadows(self.xs, self.ys, self.boxes, lo, hi, rays=False)
        ends = np.array(blockers, dtype=np.int64)
        first = np.arange(lo + 1, min(lo + 1 + _NEAR_SHADOWS, hi))
        last = np.arange(max(hi - _NEAR_SHADOWS, lo + 1), hi)
        shadows.add_many(self.sx, self.sy, np.concatenate([first, last, ends, ends + 1]))
        return shadows

    def _shadows(self, lo: int, hi: int, blockers: list[int]) -> Shadows:
        """The shadows on the base of [lo, hi] of the edges ``blockers`` (the caller adds
        more as it finds them), and their rays (:meth:`Shadows.candidates`)."""
        shadows = Shadows(self.xs, self.ys, self.boxes, lo, hi)
        for e in blockers:
            shadows.add_edge(e)
        return shadows

    def _first_apex_shadowed(
        self, lo: int, hi: int, start: int, blockers: list[int], first: int, last: int
    ) -> int:
        """:meth:`_first_apex` for the candidates from ``first`` back to ``last`` (at most
        ``start``, at least lo + 1) in a long sub-polygon: chain boxes right of the chord or
        in the shadow of a vertex (``Shadows``) are skipped whole; the candidates tested, as
        many positions after ``lo`` and the ends of the edges that blocked them cast the
        shadows (the vertices next to either end of the base: the shadows most failing
        candidates fall in)."""
        xs, ys = self.xs, self.ys
        shadows = self._shadows(lo, hi, blockers)
        for c in range(hi - 1, start, -1):
            shadows.add(c)
        for c in range(lo + 1, min(lo + 1 + _SCALAR_CANDIDATES, start + 1)):
            shadows.add(c)
        for c in shadows.candidates(first, last):
            if not facing_one(xs, ys, lo, hi, c):
                continue
            if not self._blocked(lo, hi, c, blockers):
                return c
            shadows.add_edge(blockers[0])
        return -1

    def _not_blocked_by(
        self, lo: int, hi: int, chunk: np.ndarray, blockers: list[int]
    ) -> np.ndarray:
        """The candidates of ``chunk`` (in order) that none of the edges ``blockers`` blocks
        (the vectorised exact test of every candidate against every listed edge)."""
        known = np.array(blockers)
        rows = np.repeat(np.arange(len(chunk)), len(known))
        failing, _ = pairs_failing(
            self.sx, self.sy, lo, hi, chunk, rows, np.tile(known, len(chunk)), self.exact
        )
        if len(failing) == 0:
            return chunk
        keep = np.ones(len(chunk), dtype=bool)
        keep[failing] = False
        return chunk[keep]

    def _blocked(self, lo: int, hi: int, c: int, blockers: list[int]) -> bool:
        """Some edge of sub-polygon [lo, hi] breaks condition 2 or 3 for the triangle on
        the base (hi, lo) with apex ``c``; a blocking edge is put first in ``blockers``."""
        xs, ys, sign = self.xs, self.ys, self.sign
        corners = (xs[hi], ys[hi], xs[lo], ys[lo], xs[c], ys[c])
        xmin, xmax = min(corners[0::2]), max(corners[0::2])
        ymin, ymax = min(corners[1::2]), max(corners[1::2])
        for e in blockers:
            if edge_blocks(corners, xmin, ymin, xmax, ymax, xs, ys, e, sign):
                return True
        if self.boxes is not None and hi - lo > SMALL_SEQUENCE:
            return self._blocked_boxes(lo, hi, c, corners, blockers)
        return self._blocked_in(((lo, hi),), corners, blockers)

    def _blocked_boxes(
        self,
        lo: int,
        hi: int,
        c: int,
        corners: tuple[float, float, float, float, float, float],
        blockers: list[int],
    ) -> bool:
        """:meth:`_blocked` for long sub-polygons: the edges are those of the chain boxes
        that the triangle may meet (``ChainBoxes.leaves_meeting``)."""
        return self._blocked_in(self.boxes.leaves_meeting(lo, hi, c, corners), corners, blockers)

    def _blocked_in(
        self,
        runs: Iterable[tuple[int, int]],
        corners: tuple[float, float, float, float, float, float],
        blockers: list[int],
    ) -> bool:
        """Some edge (e, e + 1) with e in one of the ``runs`` [start, end) breaks condition 2
        or 3 for the triangle ``corners``; the first found is put first in ``blockers``."""
        xs, ys, sign = self.xs, self.ys, self.sign
        ax, ay, bx, by, cx, cy = corners
        xmin, xmax = min(ax, bx, cx), max(ax, bx, cx)
        ymin, ymax = min(ay, by, cy), max(ay, by, cy)
        for start, end in runs:
            for e in range(start, end):
                if edge_blocks(corners, xmin, ymin, xmax, ymax, xs, ys, e, sign):
                    _remember(blockers, e)
                    return True
        return False

    def _grid_correct(
        self, lo: int, hi: int, chunk: np.ndarray, exhaustive: bool, blockers: list[np.ndarray]
    ) -> np.ndarray:
        """The correct candidates of ``chunk`` (in order; only the first unless exhaustive).

        Edges that blocked earlier candidates of this base (``blockers``, updated) often block
        the next ones too: they are tried first. The others are looked up in the grid per
        candidate triangle; all (candidate, edge) pairs are tested in one vectorised step.
        """
        sx, sy = self.sx, self.sy
        known = np.unique(np.concatenate(blockers))
        if len(known):
            rows = np.repeat(np.arange(len(chunk)), len(known))
            failing, _ = pairs_failing(
                sx, sy, lo, hi, chunk, rows, np.tile(known, len(chunk)), self.exact
            )
            if len(failing):
                keep = np.ones(len(chunk), dtype=bool)
                keep[failing] = False
                chunk = chunk[keep]
                if len(chunk) == 0:
                    return chunk
        rows, edges = [], []
        corners_x = np.array([sx[hi], sx[lo], 0.0])
        corners_y = np.array([sy[hi], sy[lo], 0.0])
        for index, c in enumerate(chunk.tolist()):
            corners_x[2], corners_y[2] = sx[c], sy[c]
            found = self.grid.query_triangle(corners_x, corners_y)
            found = np.unique(found[(found >= lo) & (found < hi)])
            edges.append(found)
            rows.append(np.full(len(found), index))
        failing, blocking = pairs_failing(
            sx, sy, lo, hi, chunk, np.concatenate(rows), np.concatenate(edges), self.exact
        )
        if len(blocking) and len(known) < _MAX_BLOCKERS:
            blockers.append(blocking)
        mask = np.ones(len(chunk), dtype=bool)
        mask[failing] = False
        correct = chunk[mask]
        return correct if exhaustive else correct[:1]

    def build(self) -> Triangulation:
        return drive(self.build_steps())

    def build_steps(self) -> Steps:
        """:meth:`build` as steps: the small sub-polygons are yielded as one
        :data:`SubtreeRequest`; their :class:`.subtrees.Subtrees` come back from the
        lock-step builder (so that the caller may build those of many polygons at once), or
        None, where the rounds are not worth it, to build them one step at a time."""
        name = self._lockstep_rule()
        rows = None
        if name is not None:
            rows = _Rows(max(self.m - 2, 0))
            deferred: list[tuple[int, int, int, bool, int, int, int]] = []
            try:
                self._restart_watch()
                self._grow([(1, self.m, True, -1, 0, 0)], rows, deferred)
                sub: Subtrees | Refine | None = REFINE
                while deferred and isinstance(sub, Refine):
                    spans = np.array([(lo, hi) for _, lo, hi, *_ in deferred], dtype=np.int64)
                    request = (self.ids, self.sx, self.sy, self.sz, spans)
                    sub = yield (*request, self.prepared.mirrored, name)
                    if isinstance(sub, Refine):  # the larger ones split further, then again
                        rows, deferred = self._refined(rows, deferred)
                if deferred and sub is None:  # not worth the rounds: one step at a time
                    rows = self._with_blocks(rows, deferred)
                elif deferred:
                    rows = self._with_subtrees(rows, deferred, sub)
            except TriangulationError:
                rows = None
        if rows is None:  # one step at a time throughout (and the errors in pre-order)
            rows = _Rows(max(self.m - 2, 0))
            self._restart_watch()
            self._one_step_subtree(1, self.m, True, rows)
        count = rows.count
        return Triangulation(
            vertices=self.prepared.vertices,
            triangles=rows.triangles[:count],
            parent=rows.parent[:count],
            depth=rows.depth[:count],
            side=rows.side[:count],
        )

    def _restart_watch(self) -> None:
        if self.loss_watch is not None:
            self.loss_watch.reversed2 = 0.0

    def _lockstep_rule(self) -> str | None:
        """The rule's name where the small sub-polygons go to the lock-step builder (a long
        sequence under rule first, elevation or delaunay), else None."""
        if self.m <= self._lockstep_positions():
            return None
        if type(self.rule) is FirstRule:
            return "first"
        if type(self.rule) is ElevationRule:
            # a level sequence: every node's apex is rule first's (see _level)
            return "first" if self._level(0, self.m) else "elevation"
        if type(self.rule) is DelaunayRule:
            return "delaunay"
        return None

    def _lockstep_positions(self) -> int:
        """Largest sub-polygon (positions) handed to the lock-step builder: larger under rule
        delaunay, whose one-step search per node costs far more than rule first's."""
        return DELAUNAY_POSITIONS if type(self.rule) is DelaunayRule else MAX_POSITIONS

    def _grow(
        self,
        work: list[tuple[int, int, bool, int, int, int]],
        rows: _Rows,
        deferred: list[tuple[int, int, int, bool, int, int, int]] | None,
        limit: int | None = None,
    ) -> None:
        """Build the subtrees of the work items into ``rows``, in pre-order. With
        ``deferred``, a sub-polygon of fewer than ``limit`` (:meth:`_lockstep_positions`)
        positions is not built but listed there as (row it goes before, lo, hi, v1_at_hi,
        parent, depth, side)."""
        ids, xs, ys = self.ids, self.xs, self.ys
        triangles, parent, depth, side = rows.triangles, rows.parent, rows.depth, rows.side
        # as given: loops cut off at a repeated vertex, each triangulated as a tree of its own
        loops: list[tuple[int, int, bool, int, int, int]] = []
        count = rows.count
        mirrored = self.prepared.mirrored
        tick = self.tick
        limit = self._lockstep_positions() if limit is None else limit
        # rule first: fans in long sub-polygons decided in batches (their nodes never deferred)
        fans = type(self.rule) is FirstRule and self.m > SMALL_SEQUENCE
        fan_above = max(limit if deferred is not None else 0, SMALL_SEQUENCE)
        while work or loops:
            if not work:
                work.append(loops.pop(0))
            lo, hi, v1_at_hi, par, dep, sd = work.pop()
            if deferred is not None and hi - lo < limit:
                deferred.append((count, lo, hi, v1_at_hi, par, dep, sd))
                continue
            if tick is not None and count & 63 == 0:
                tick(count / len(triangles))
            if count >= len(triangles):
                raise TriangulationError(self._label(lo) + ": the BSP tree does not close")
            v1, v2 = (hi, lo) if v1_at_hi else (lo, hi)
            apex = self._apex(lo, hi, v1, v2)
            fallback = apex < 0 and self.as_given
            if fallback:
                apex = self._fallback_apex(lo, hi)
                self.used_fallback = True
                if ids[apex] == ids[lo] or ids[apex] == ids[hi]:
                    # a pinch: no triangle (it would repeat a vertex); the rest of the chain
                    # keeps this node's place, the loop cut off becomes a tree of its own
                    loop, rest = ((lo, apex), (apex, hi))
                    if ids[apex] == ids[hi]:
                        loop, rest = rest, loop
                    if loop[1] - loop[0] > 2:
                        loops.append((loop[0] + 1, loop[1], True, -1, 0, 0))
                    if rest[1] - rest[0] > 1:
                        work.append((*rest, v1_at_hi, par, dep, sd))
                    continue
            if apex < 0:
                raise TriangulationError(
                    f"{self._label(v1)}: no correct triangle on the edge between vertices "
                    f"{ids[v1]} and {ids[v2]} (invalid polygon: self-intersection or "
                    "crossing rings?)"
                )
            node = count
            # counter-clockwise in the working plane before mirroring
            first, second = (lo, hi) if mirrored else (hi, lo)
            # a fallback apex of invalid input may lie right of the chord (a correct one is
            # strictly left): that triangle is turned counter-clockwise in the working plane
            if fallback and self.sign(xs[hi], ys[hi], xs[lo], ys[lo], xs[apex], ys[apex]) < 0:
                first, second = second, first
                if self.loss_watch is not None:
                    self.loss_watch.reversed(self.sx, self.sy, lo, hi, apex)
            triangles[node] = (ids[first], ids[second], ids[apex])
            parent[node] = par
            depth[node] = dep
            side[node] = sd
            count += 1
            if fans and apex - lo > fan_above and (apex == hi - 1 or not v1_at_hi):
                # the node's lower child (lo, apex) may start a fan at lo: a run of nodes on
                # the bases (lo, apex), each taking the next apex back (see _fan_apexes)
                apexes = self._fan_apexes(lo, apex, lo + fan_above)
                if apexes:
                    sd = 2 if v1_at_hi else 1
                    for following in apexes:
                        if apex < hi - 1:
                            # the node's pocket (its upper child, on the right with V1 at
                            # lo) comes after the rest of the fan in pre-order
                            work.append((apex, hi, True, node, dep + 1, 2))
                        hi, apex = apex, following
                        first, second = (lo, hi) if mirrored else (hi, lo)
                        triangles[count] = (ids[first], ids[second], ids[apex])
                        parent[count] = node
                        dep += 1
                        depth[count] = dep
                        side[count] = sd
                        node, sd = count, 1
                        count += 1
                    v1_at_hi = False
                    if tick is not None:
                        tick(count / len(triangles))
            upper = (apex, hi, True)  # sub-range on the hi side, V1 there at hi
            lower = (lo, apex, False)
            left, right = (upper, lower) if v1_at_hi else (lower, upper)
            for (clo, chi, flag), child_side in ((right, 2), (left, 1)):
                if chi - clo > 1:
                    work.append((clo, chi, flag, node, dep + 1, child_side))
        rows.count = count

    def _refined(
        self, rows: _Rows, deferred: list[tuple[int, int, int, bool, int, int, int]]
    ) -> tuple[_Rows, list[tuple[int, int, int, bool, int, int, int]]]:
        """``rows`` and ``deferred`` (from :meth:`_grow`) with each deferred sub-polygon of
        more than ``REFINED_POSITIONS`` positions built by :meth:`_grow` down to sub-polygons
        of at most that many, which are deferred in its place (``subtrees.worth_refining``).
        The tree is the same: a node's apex does not depend on the builder that finds it.
        Where a fallback apex of invalid input turns up (or one did already), the plan stays
        as it was."""
        big = [k for k, item in enumerate(deferred) if item[2] - item[1] >= REFINED_POSITIONS]
        if not big or self.used_fallback:
            return rows, deferred
        # one block per sub-polygon split, as :meth:`_one_step_blocks` makes them (local
        # parents, depths from its root), with the sub-polygons deferred inside it
        blocks = _Rows(sum(deferred[k][2] - deferred[k][1] - 1 for k in big))
        starts: list[int] = []
        inner: list[list[tuple[int, int, int, bool, int, int, int]]] = []
        # progress goes on with the rounds; a fallback's reversed area is counted where the
        # plan builds it
        tick, watch = self.tick, self.loss_watch
        self.tick = self.loss_watch = None
        try:
            for k in big:
                _, lo, hi, v1_at_hi, *_ = deferred[k]
                starts.append(blocks.count)
                inner.append([])
                self._grow([(lo, hi, v1_at_hi, -1, 0, 0)], blocks, inner[-1], REFINED_POSITIONS)
                if self.used_fallback:
                    break
        finally:
            self.tick, self.loss_watch = tick, watch
        if self.used_fallback:  # its sub-polygons go to the rounds as planned
            self.used_fallback = False
            return rows, deferred
        table = np.array([deferred[k] for k in big], dtype=np.int64)
        bounds = np.array([*starts, blocks.count], dtype=np.int64)
        out, moved, placed = _spread(rows, table[:, 0], np.diff(bounds))
        self._place_blocks(out, moved, placed, table, blocks, bounds)
        # the others go just before the row that followed them: the top row they went
        # before, or a block now in front of it
        moved_list, shift = moved.tolist(), (placed - bounds[:-1]).tolist()
        block_of = {k: j for j, k in enumerate(big)}
        follow: dict[int, int] = {}
        new_at: dict[int, int] = {}
        for k in range(len(deferred) - 1, -1, -1):
            row = deferred[k][0]
            if k in block_of:
                follow[row] = int(placed[block_of[k]])
            else:
                ahead = moved_list[row] if row < rows.count else out.count
                new_at[k] = follow.get(row, ahead)
        refined: list[tuple[int, int, int, bool, int, int, int]] = []
        for k, (_, lo, hi, v1_at_hi, above, dep, sd) in enumerate(deferred):
            j = block_of.get(k)
            if j is not None:
                for r, a, b, flag, p, d, side in inner[j]:
                    refined.append((r + shift[j], a, b, flag, p + shift[j], d + dep, side))
            else:
                parent = -1 if above < 0 else moved_list[above]
                refined.append((new_at[k], lo, hi, v1_at_hi, parent, dep, sd))
        return out, refined

    def _with_subtrees(
        self, rows: _Rows, deferred: list[tuple[int, int, int, bool, int, int, int]], sub: Subtrees
    ) -> _Rows:
        """``rows`` with the subtrees ``sub`` of the ``deferred`` sub-polygons in their
        places, built by the lock-step builder; those it finds no tree for (invalid input as
        given) one step at a time (:meth:`_one_step_blocks`)."""
        table = np.array(deferred, dtype=np.int64)
        at, at_hi = table[:, 0], table[:, 3].astype(bool)
        above, dep, sd = table[:, 4], table[:, 5], table[:, 6]
        sizes = sub.count.copy()
        failed = np.flatnonzero(~sub.ok)
        blocks = None
        if len(failed):
            blocks, starts = self._one_step_blocks([deferred[k] for k in failed.tolist()])
            sizes[failed] = np.diff(starts)
        out, moved_rows, block = _spread(rows, at, sizes)
        if blocks is not None:
            self._place_blocks(out, moved_rows, block[failed], table[failed], blocks, starts)
        owner = np.repeat(np.arange(len(table), dtype=np.int64), sub.count)
        local = np.arange(len(owner), dtype=np.int64) - np.repeat(sub.start, sub.count)
        triangles, parent, depth, side = sub.triangles, sub.parent, sub.depth, sub.side
        if len(failed):
            kept = np.flatnonzero(sub.ok[owner])
            owner, local = owner[kept], local[kept]
            triangles, parent = triangles[kept], parent[kept]
            depth, side = depth[kept], side[kept]
        del sub
        # the subtrees were built with V1 at s_hi (the upper sub-range the left child): where
        # V1 is at s_lo, the root's two children trade sides and their subtrees trade places
        swap = ~at_hi[owner]
        second = sizes.copy()  # local row of the root's right child (its lower sub-range)
        right = np.flatnonzero((parent == 0) & (side == 2))
        second[owner[right]] = local[right]
        split = second[owner]
        del second, right
        # (the temporaries go as soon as they are used: these arrays hold a row per
        # triangle of the whole polygon)
        size = sizes[owner]
        start = block[owner]
        place = start + _reordered(local, split, size, swap)
        del local
        out.triangles[place] = triangles
        del triangles
        out.depth[place] = depth + dep[owner]
        del depth
        root = parent < 0
        flip = (parent == 0) & swap
        linked = start + _reordered(np.maximum(parent, 0), split, size, swap)
        del parent, start, size, split
        roots = np.flatnonzero(root)
        top = above[owner[roots]]
        linked[roots] = np.where(top < 0, -1, moved_rows[np.maximum(top, 0)])
        out.parent[place] = linked
        del linked
        out.side[place] = np.where(root, sd[owner], np.where(flip, 3 - side, side))
        return out

    def _with_blocks(
        self, rows: _Rows, deferred: list[tuple[int, int, int, bool, int, int, int]]
    ) -> _Rows:
        """``rows`` with the subtrees of the ``deferred`` sub-polygons built one step at a
        time (:meth:`_one_step_blocks`), each in its place in pre-order as one block."""
        table = np.array(deferred, dtype=np.int64)
        blocks, starts = self._one_step_blocks(deferred)
        out, moved_rows, block = _spread(rows, table[:, 0], np.diff(starts))
        self._place_blocks(out, moved_rows, block, table, blocks, starts)
        return out

    def _one_step_blocks(
        self, deferred: list[tuple[int, int, int, bool, int, int, int]]
    ) -> tuple[_Rows, np.ndarray]:
        """The subtrees of the ``deferred`` sub-polygons built one step at a time, one after
        the other (local parents, -1 at each root), and where each starts (with the end). A
        sub-polygon that cuts off a loop (a pinch of invalid input, whose loop the whole tree
        builds last, as a tree of its own) raises :class:`TriangulationError`: the whole tree
        is then built one step at a time."""
        blocks = _Rows(sum(hi - lo - 1 for _, lo, hi, *_ in deferred))
        starts = []
        tick = self.tick
        total = len(blocks.triangles)
        whole = max(self.m - 2, 1)
        if tick is not None:  # the share of the whole tree, the rest of it built already
            self.tick = lambda share: tick(1.0 - (1.0 - share) * total / whole)
        try:
            for _, lo, hi, v1_at_hi, *_ in deferred:
                start = blocks.count
                starts.append(start)
                self._one_step_subtree(lo, hi, v1_at_hi, blocks)
                if np.count_nonzero(blocks.parent[start + 1 : blocks.count] < 0):
                    raise TriangulationError(self._label(lo) + ": a loop is cut off")
        finally:
            self.tick = tick
        return blocks, np.array([*starts, blocks.count], dtype=np.int64)

    def _one_step_subtree(self, lo: int, hi: int, v1_at_hi: bool, rows: _Rows) -> None:
        """The subtree of sub-polygon [lo, hi] (V1 at hi where ``v1_at_hi``), written to
        ``rows`` from ``rows.count`` on, in pre-order. Under rule "first", in a sub-polygon of
        at most ``MAX_POSITIONS`` positions, its nodes are built with the scalar tests of
        ``one_by_one.first_nodes`` (the same conditions, with less work per node) as far as
        they find correct candidates; :meth:`_grow` builds the rest (invalid input: its
        fallbacks, and its errors)."""
        if type(self.rule) is not FirstRule or hi - lo > MAX_POSITIONS:
            # a long one (a whole tree built one step at a time after the lock-step attempt
            # failed): _grow's chain boxes and shadows keep its nodes near-linear, where the
            # scalar tests scan every edge of the sub-polygon
            self._grow([(lo, hi, v1_at_hi, -1, 0, 0)], rows, None)
            return
        # the straight runs where _straight_runs uses them (long sequences)
        runs = self._runs() if self.boxes is not None else None
        budget = _FIRST_BLOCK_TESTS * (hi - lo)
        nodes, pending = first_nodes(
            self.xs, self.ys, lo, hi, hi - 1, v1_at_hi, self.exact, budget, runs
        )
        start = rows.count
        count = len(nodes)
        if count:
            if start + count > len(rows.triangles):
                raise TriangulationError(self._label(lo) + ": the BSP tree does not close")
            table = np.array(nodes, dtype=np.int64)
            node_lo, node_hi, apex, parent = table[:, 0], table[:, 1], table[:, 2], table[:, 3]
            # counter-clockwise in the working plane before mirroring (as in _grow)
            first, second = (node_lo, node_hi) if self.prepared.mirrored else (node_hi, node_lo)
            out = slice(start, start + count)
            ids = self.ids
            rows.triangles[out, 0] = ids[first]
            rows.triangles[out, 1] = ids[second]
            rows.triangles[out, 2] = ids[apex]
            rows.parent[out] = np.where(parent < 0, -1, parent + start)
            rows.depth[out] = table[:, 4]
            rows.side[out] = table[:, 5]
            rows.count = start + count
            if self.tick is not None:
                self.tick(rows.count / len(rows.triangles))
        if pending:
            work = [
                (w_lo, w_hi, w_at_hi, w_parent + start if w_parent >= 0 else -1, depth, side)
                for w_lo, w_hi, _, w_at_hi, w_parent, depth, side in pending
            ]
            self._grow(work, rows, None)

    def _place_blocks(
        self,
        out: _Rows,
        moved_rows: np.ndarray,
        block: np.ndarray,
        table: np.ndarray,
        blocks: _Rows,
        starts: np.ndarray,
    ) -> None:
        """Write the one-step ``blocks`` (from :meth:`_one_step_blocks`; block k at rows
        ``starts[k]`` to ``starts[k + 1]``) into ``out`` at the rows from ``block[k]`` on, for
        the deferred sub-polygons ``table`` (``_spread`` gave ``out``, ``moved_rows``)."""
        above, dep, sd = table[:, 4], table[:, 5], table[:, 6]
        sizes = np.diff(starts)
        owner = np.repeat(np.arange(len(table), dtype=np.int64), sizes)
        place = np.arange(blocks.count, dtype=np.int64) + (block - starts[:-1])[owner]
        parent = blocks.parent[: blocks.count]
        root = parent < 0
        top = above[owner]
        out.triangles[place] = blocks.triangles[: blocks.count]
        out.parent[place] = np.where(
            root,
            np.where(top < 0, -1, moved_rows[np.maximum(top, 0)]),
            place[np.maximum(parent, 0)],
        )
        out.depth[place] = blocks.depth[: blocks.count] + dep[owner]
        out.side[place] = np.where(root, sd[owner], blocks.side[: blocks.count])

    def _fallback_apex(self, lo: int, hi: int) -> int:
        """Apex for a base of an invalid polygon that has no correct triangle (``as_given``).

        Triangle areas always add up to the sequence's signed area, so the total area stays the
        polygon's as long as no triangle is clockwise. Hence the preference, each the first in
        the paper's order: an apex whose two child sub-polygons both keep a non-negative signed
        area, zero-area triangles (they drop a zero-width spike or a pinch) before triangles on
        the interior side; then any zero-area or interior-side triangle; then the first.
        """
        sx, sy = self.sx, self.sy
        chunk = np.arange(hi - 1, lo, -1)
        facing = orient_many(sx[hi], sy[hi], sx[lo], sy[lo], sx[chunk], sy[chunk])
        if self._prefix is None:
            cross = sx[:-1] * sy[1:] - sx[1:] * sy[:-1]
            self._prefix = np.concatenate([[0.0], np.cumsum(cross)])
        prefix = self._prefix
        lower = prefix[chunk] - prefix[lo] + sx[chunk] * sy[lo] - sx[lo] * sy[chunk]
        upper = prefix[hi] - prefix[chunk] + sx[hi] * sy[chunk] - sx[chunk] * sy[hi]
        balanced = (lower >= 0) & (upper >= 0)
        for wanted in (balanced & (facing == 0), balanced & (facing > 0), facing == 0, facing > 0):
            if wanted.any():
                return int(chunk[np.argmax(wanted)])
        return int(chunk[0])

    def _label(self, position: int) -> str:
        vid = int(self.ids[position])
        return ring_label(int(self.prepared.ring_of[vid]))


def _end_angle(vx: float, vy: float, start: float, near: float) -> float | None:
    """The clockwise angle from the fan's first ray (at angle ``start``) of the point at
    (vx, vy) from the fan's centre (a position of the fan, or an edge's end); None at the
    centre itself, -1 within ``near`` of it in both axes (its angle not trusted)."""
    if vx == 0 and vy == 0:
        return None
    if abs(vx) <= near and abs(vy) <= near:
        return -1.0
    return (start - math.atan2(vy, vx)) % _TWO_PI


def _sectors_of(first: float | None, second: float | None, angles: list[float]) -> tuple[int, int]:
    """(first, last) fan nodes whose sectors (between the rays at ``angles``, clockwise from
    the first ray) an edge may meet, by its ends' angles (:func:`_end_angle`) with a margin:
    every node where an end's angle is not trusted or the edge spans nearly a half-turn; an
    end at the centre puts the edge on the ray to its other end."""
    count = len(angles) - 1
    if first == -1.0 or second == -1.0:
        return 0, count - 1
    if first is None:
        if second is None:
            return 0, -1
        first = second
    elif second is None:
        second = first
    low, high = (first, second) if first <= second else (second, first)
    if high - low > math.pi:
        low, high = high - _TWO_PI, low
    if high - low > math.pi - _FAN_MARGIN:
        return 0, count - 1
    return (
        max(bisect_left(angles, low - _FAN_MARGIN) - 1, 0),
        min(bisect_right(angles, high + _FAN_MARGIN) - 1, count - 1),
    )


def _reordered(
    index: np.ndarray, split: np.ndarray, size: np.ndarray, swap: np.ndarray
) -> np.ndarray:
    """Local rows ``index`` of subtrees of ``size`` rows built with V1 at s_hi, in the
    order of their trees where ``swap`` (V1 at s_lo): the root stays first, the rows from
    ``split`` (the root's right child on) come next, then the rest."""
    moved = np.where(index < split, index + size - split, index - split + 1)
    return np.where(swap & (index > 0), moved, index)


def _spread(rows: _Rows, at: np.ndarray, sizes: np.ndarray) -> tuple[_Rows, np.ndarray, np.ndarray]:
    """The rows of the whole tree with ``rows`` (its one-step part) moved apart so that block
    k of ``sizes[k]`` rows goes just before one-step row ``at[k]``: the new rows (the one-step
    part filled in), where each one-step row went and where each block starts."""
    count = rows.count
    before = np.concatenate([[0], np.cumsum(sizes)])
    mine = np.arange(count, dtype=np.int64)
    moved = mine + before[np.searchsorted(at, mine, side="right")]
    out = _Rows(count + int(before[-1]))
    out.count = len(out.triangles)
    out.triangles[moved] = rows.triangles[:count]
    out.parent[moved] = np.where(
        rows.parent[:count] < 0, -1, moved[np.maximum(rows.parent[:count], 0)]
    )
    out.depth[moved] = rows.depth[:count]
    out.side[moved] = rows.side[:count]
    return out, moved, at + before[:-1]


class _RepairWinsError(Exception):
    """An as-given tree stopped: it surely loses more area than the repair."""


class _LossWatch:
    """Stops an as-given tree (:class:`_RepairWinsError`) as soon as its clockwise fallback
    triangles surely lose more area than the polygon's repair (docs/algorithm.md, section 7).

    The triangles' absolute areas exceed the polygon's by twice the reversed ones' (their
    signed areas add up to it), so the whole tree's loss is at least twice the reversed area so
    far, relative to the polygon's. Once that reaches ``_REPAIR_AT`` (far above _AREA_KEPT and
    the sums' rounding) the repair is made (``repair``, once); the tree stops when its loss
    reaches twice the repair's, where the comparison of the whole tree with the repair would
    surely pick the repair.
    """

    def __init__(
        self,
        prepared: PreparedRings,
        axes: tuple[int, int],
        repair: Callable[[], Triangulation | None],
    ) -> None:
        self.prepared, self.axes, self.repair = prepared, axes, repair
        self.reversed2 = 0.0  # twice the reversed triangles' area (of the tree being built)
        self.limit = -1.0  # set at the first reversed triangle (most trees have none)
        self.polygon2 = 0.0
        self.repair_made = False

    def reversed(self, x: np.ndarray, y: np.ndarray, a: int, b: int, c: int) -> None:
        """Count the clockwise fallback triangle of positions (a, b, c)."""
        cross = (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])
        self.reversed2 += abs(float(cross))
        if self.limit < 0:
            self.polygon2 = _polygon_area2(self.prepared)
            self.limit = _REPAIR_AT * self.polygon2 if self.polygon2 > 0 else math.inf
        if not self.reversed2 > self.limit:  # nan (an overflow): no decision
            return
        if not self.repair_made:
            self.repair_made = True
            fixed = self.repair()
            if fixed is None:
                self.limit = math.inf
                return
            lost = _area_loss(self.prepared, fixed, self.axes)
            self.limit = max(self.limit, lost * self.polygon2)
            if not self.reversed2 > self.limit:  # nan (an overflow): no decision
                return
        raise _RepairWinsError()


def _snap(clean: list[np.ndarray], tolerance: float) -> list[np.ndarray]:
    from ..terrain.planar import snap_to_plane

    return [np.asarray(r, dtype=np.float64) for r in snap_to_plane(clean, tolerance)]


def drive(steps: Steps, alive: Callable[[], None] | None = None) -> Triangulation:
    """The result of ``steps``, each lock-step request built as it comes where its
    sub-polygons are worth the rounds (``subtrees.built_if_worth``, which calls ``alive``
    every round)."""
    try:
        request = next(steps)
        if worth_refining([request]):
            request = steps.send(REFINE)
        while True:
            request = steps.send(built_if_worth([request], alive)[0])
    except StopIteration as done:
        return done.value


def _triangulate(rings: Sequence[object], **options: object) -> Triangulation:
    """:func:`~bsp_triangulate.api.triangulate` of one polygon (:func:`triangulate_steps`
    run through)."""
    return drive(triangulate_steps(rings, **options), options.get("alive"))


def triangulate_steps(
    rings: Sequence[object],
    *,
    rule: str,
    planar_tolerance: float,
    invalid: str,
    plane: str = "auto",
    repair: bool = True,
    tick: Callable[[float], None] | None = None,
    points: object = None,
    mesh: object = None,
    ring_mesh: Triangulation | None = None,
    inserted_mesh: InsertedMesh | None = None,
    alive: Callable[[], None] | None = None,
) -> Steps:
    """:func:`~bsp_triangulate.api.triangulate` of one polygon, as steps (:data:`Steps`:
    the tree's lock-step sub-polygons are yielded, their subtrees sent back); ``repair``: a
    polygon whose rings cross may be repaired (False inside the repair itself); ``tick``:
    called every 64 triangles with the share of the tree built (it may raise to stop);
    ``points``: interior points, each joined as a one-point island; ``mesh``: under rule
    delaunay with points, the constrained Delaunay triangulation if known (see
    :func:`_known_mesh`); ``ring_mesh``: the rings' own triangulation without the points, if
    known (the points go into it); ``inserted_mesh``: the points already inserted into it
    (``points_batch``), used where its points are the rows this polygon gives them;
    ``alive``: called now and then in the steps that tell no share (the touching search,
    the bridges, the lock-step rounds; it may raise to stop)."""
    apex_rule = get_rule(rule)
    as_given = _as_given(invalid)
    clean, axes = normalise_rings(rings, plane)
    given = as_point_array(points)
    unused = np.full(len(given), -1, dtype=np.int64)
    if planar_tolerance > 0 and clean:
        clean = _snap(clean, planar_tolerance)
    prepared = prepare(clean, axes)
    if prepared.is_degenerate and _crosses_with_zero_area(clean, axes):
        # a bow-tie whose lobes cancel: not degenerate, it has area on both sides
        if not as_given:
            raise TriangulationError(
                f"{ring_label(0)}: the ring crosses itself and its signed area is zero "
                "(invalid polygon: self-intersection)"
            )
        if repair:
            repaired = _repaired(clean, rule=rule, plane=plane, points=given)
            if repaired is not None:
                return repaired
    if prepared.is_degenerate or negligible_area(prepared):
        return Triangulation(vertices=prepared.vertices, point_ids=unused)
    ring_count = len(prepared.vertices)
    prepared, point_ids = _with_points(prepared, given, axes)
    has_points = bool((point_ids >= 0).any())
    # the points inserted already, into the batch path's triangulation of the rings (their
    # rows must be these): that path takes no polygon whose rings touch (a vertex on another
    # edge, two vertices at one point), so no ring edge needs splitting
    batch_inserted = inserted_mesh is not None and np.array_equal(
        inserted_mesh.point_ids, point_ids
    )
    if alive is not None:
        alive()
    if batch_inserted:
        ring_ids = prepared.rings
    else:
        ring_ids = split_touching(prepared.x, prepared.y, prepared.rings, alive)

    # rule delaunay with points: the points inserted into the rings' triangulation, whose
    # tree is read off it (section 5b)
    inserted = None
    if has_points and type(apex_rule) is DelaunayRule and not as_given:
        # the points inserted already (their rows must be these), or the mesh given with the
        # polygon where it passes the checks; else one built here
        starts, ends = ring_edges(ring_ids)
        distinct = starts != ends
        walls = (starts[distinct], ends[distinct])
        known = None
        if batch_inserted:
            known = _mesh_rows(prepared, inserted_mesh.triangles)
        elif mesh is not None:
            known = _known_mesh(prepared, mesh)
        if known is not None:
            inserted = _delaunay_by_insertion(prepared, known, walls, tick)
        if inserted is None:
            built = _delaunay_mesh(prepared, ring_ids, ring_count, walls, tick, ring_mesh)
            if built is not None:
                inserted = _delaunay_by_insertion(prepared, built, walls, tick)
    if inserted is not None:
        inserted.point_ids = point_ids
        check_area(prepared, inserted, axes)
        return inserted
    point_rings = [np.array([vid], dtype=np.int64) for vid in point_ids[point_ids >= 0].tolist()]
    sequence = _bridged(
        prepared,
        ring_ids + point_rings,
        prepared.ring_numbers + (-1 - np.flatnonzero(point_ids >= 0)).tolist(),
        apex_rule,
        as_given,
        np.arange(len(prepared.vertices)) >= ring_count if has_points else None,
        alive,
    )
    if len(sequence) < 3:
        return Triangulation(vertices=prepared.vertices, point_ids=point_ids)
    if alive is not None:
        alive()
    tree = _Tree(prepared, sequence, prepared.vertices[:, 2], apex_rule, as_given, tick)
    tree.alive = alive
    repaired: list[Triangulation | None] = []  # the repair, once tried

    def repair_now() -> Triangulation | None:
        if not repaired:
            repaired.append(_repaired(clean, rule=rule, plane=plane, points=given))
        return repaired[0]

    if inserted is None and as_given and repair:
        tree.loss_watch = _LossWatch(prepared, axes, repair_now)
        try:
            result = yield from tree.build_steps()
        except _RepairWinsError:
            return repaired[0]
    else:
        result = yield from tree.build_steps()
    result.point_ids = point_ids
    if tree.used_fallback and repair:
        lost = _area_loss(prepared, result, axes)
        if lost > _AREA_KEPT:
            # crossing rings: a triangulation of the rings as given cannot keep the area
            fixed = repair_now()
            if fixed is not None and _area_loss(prepared, fixed, axes) < lost:
                return fixed
    if not as_given:
        check_area(prepared, result, axes)
    return result


def bridged_sequence(
    rings: Sequence[object], *, rule: str, invalid: str, plane: str = "auto"
) -> tuple[PreparedRings, np.ndarray, tuple[int, int]] | None:
    """The steps of :func:`_triangulate` before the tree, for a polygon without interior
    points or snapping: its prepared rings, its bridged sequence and its axes; None where
    the polygon takes another way there (degenerate, negligible area, a sequence of fewer
    than 3 positions) or a step raises (the engine then says why)."""
    try:
        apex_rule = get_rule(rule)
        as_given = _as_given(invalid)
        clean, axes = normalise_rings(rings, plane)
        prepared = prepare(clean, axes)
        if prepared.is_degenerate or negligible_area(prepared):
            return None
        ring_ids = split_touching(prepared.x, prepared.y, prepared.rings)
        sequence = _bridged(prepared, ring_ids, prepared.ring_numbers, apex_rule, as_given)
    except (TriangulationError, ArithmeticError, ValueError, TypeError, IndexError):
        return None
    return (prepared, sequence, axes) if len(sequence) >= 3 else None


def _bridged(
    prepared: PreparedRings,
    rings: list[np.ndarray],
    numbers: list[int],
    apex_rule: ApexRule,
    as_given: bool,
    is_point: np.ndarray | None = None,
    alive: Callable[[], None] | None = None,
) -> np.ndarray:
    """The bridged sequence of ``rings`` (vertex ids of ``prepared``; ``numbers`` their
    input ring numbers, one-point islands negative), spikes removed (``is_point``: per
    vertex, a given interior point, which stays; ``alive``: see ``bridge_islands``)."""
    sequence = bridge_islands(
        prepared.x,
        prepared.y,
        rings,
        numbers,
        relaxed=as_given,
        delaunay=getattr(apex_rule, "in_plane", False),
        alive=alive,
    )
    return remove_spikes(prepared.x, prepared.y, sequence, is_point)


def _delaunay_mesh(
    prepared: PreparedRings,
    ring_ids: list[np.ndarray],
    ring_count: int,
    walls: tuple[np.ndarray, np.ndarray],
    tick: Callable[[float], None] | None,
    ring_mesh: Triangulation | None = None,
) -> np.ndarray | None:
    """Rule "delaunay" with points (docs/algorithm.md, section 5b): the rings' triangulation
    (``ring_mesh`` where it has these ring vertices, else made here with their own bridges)
    with every point inserted, as (t, 3) vertex ids counter-clockwise in the working plane;
    ``walls``: the start and end vertices of the ring edges (never flipped). None where it
    cannot be built."""
    try:
        # any triangulation of the rings: the flips make it their constrained Delaunay one
        triangles = _ring_triangles(prepared, ring_ids, ring_count, ring_mesh)
        if triangles is None:
            return None
        return points_mesh(
            prepared.x,
            prepared.y,
            triangles,
            ring_count,
            prepared.mirrored,
            tick,
            list(zip(walls[0].tolist(), walls[1].tolist())),
        )
    except (TriangulationError, ValueError):
        return None


def _ring_triangles(
    prepared: PreparedRings,
    ring_ids: list[np.ndarray],
    ring_count: int,
    ring_mesh: Triangulation | None,
) -> np.ndarray | None:
    """Triangles (counter-clockwise in the output's XY) of the rings alone: ``ring_mesh``'s
    where its vertices are the rings' own, else rule first's over their bridged sequence."""
    if (
        ring_mesh is not None
        and len(ring_mesh.triangles)
        and ring_mesh.vertices.shape == (ring_count, 3)
        and np.array_equal(ring_mesh.vertices, prepared.vertices[:ring_count])
    ):
        return ring_mesh.triangles
    rings = bridge_islands(prepared.x, prepared.y, ring_ids, prepared.ring_numbers, delaunay=True)
    rings = remove_spikes(prepared.x, prepared.y, rings)
    if len(rings) < 3:
        return None
    base = _Tree(prepared, rings, prepared.vertices[:, 2], _FIRST).build()
    if len(base.triangles) != len(rings) - 2:
        return None
    return base.triangles


def _known_mesh(prepared: PreparedRings, mesh: object) -> np.ndarray | None:
    """A triangulation given with the polygon (rows of its vertices, counter-clockwise in the
    output's XY) as (t, 3) vertex ids counter-clockwise in the working plane, if it is one the
    insertion could have made: every triangle strictly counter-clockwise, every directed edge
    used once, every interior edge locally Delaunay (exact, with the tie rule); else None.
    Whether it tiles the polygon along its ring edges is checked when the tree is read off
    it, and the area at the end."""
    tri = _mesh_rows(prepared, mesh)
    if tri is None or delaunay_faults(prepared.x, prepared.y, tri, ties=True).any():
        return None
    return tri


def _mesh_rows(prepared: PreparedRings, mesh: object) -> np.ndarray | None:
    """``mesh`` (rows of the polygon's vertices, counter-clockwise in the output's XY) as
    (t, 3) vertex ids counter-clockwise in the working plane, or None where it is not such
    an array."""
    try:
        tri = np.asarray(mesh, dtype=np.int64)
    except (TypeError, ValueError):
        return None
    n = len(prepared.vertices)
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0 or tri.min() < 0 or tri.max() >= n:
        return None
    return tri[:, [1, 0, 2]] if prepared.mirrored else tri


def _delaunay_by_insertion(
    prepared: PreparedRings,
    mesh: np.ndarray,
    walls: tuple[np.ndarray, np.ndarray],
    tick: Callable[[float], None] | None,
) -> Triangulation | None:
    """The tree read off the ``mesh`` of :func:`_delaunay_mesh` (read breadth-first, section
    5b; ``walls``: the ring edges' start and end vertices); None where the mesh does not
    triangulate the rings."""
    return tree_of_cdt(mesh, prepared.vertices, walls, prepared.mirrored, tick)


def _with_points(
    prepared: PreparedRings, given: np.ndarray, axes: tuple[int, int]
) -> tuple[PreparedRings, np.ndarray]:
    """The rings with the usable interior points appended to their vertices, and each given
    point's row in them (-1: outside, on the boundary, or a repeat of an earlier point)."""
    point_ids = np.full(len(given), -1, dtype=np.int64)
    if len(given) == 0:
        return prepared, point_ids
    px, py = given[:, axes[0]].copy(), given[:, axes[1]].copy()
    if prepared.mirrored:
        px = -px
    use = first_occurrences(px, py)
    use[use] = strictly_inside(prepared.x, prepared.y, prepared.rings, px[use], py[use])
    numbers = np.flatnonzero(use)
    point_ids[numbers] = len(prepared.vertices) + np.arange(len(numbers))
    return prepared.with_points(given[numbers], px[numbers], py[numbers], numbers), point_ids


def check_area(prepared: PreparedRings, result: Triangulation, axes: tuple[int, int]) -> None:
    """Raise :class:`TriangulationError` unless the triangles' absolute areas (in the working
    plane) add up to the polygon's area.

    The tree's triangles always add up to the area with their signs; their absolute areas
    do so only when none is reversed, and then they cover the polygon exactly once. A
    result that fails this cannot be right, and is never returned. The tolerance is
    relative (:data:`AREA_TOLERANCE`) plus a bound on the rounding of the sums.
    """
    t = result.triangles
    if len(t) == 0:
        return
    # from the first vertex, scaled by a power of two (exact): no overflow or underflow
    first = prepared.rings[0][0]
    x = prepared.x - prepared.x[first]
    y = prepared.y - prepared.y[first]
    span = max(float(np.abs(x).max()), float(np.abs(y).max()))
    scale = np.ldexp(1.0, -int(np.frexp(span)[1])) if 0 < span < np.inf else 1.0
    x, y = x * scale, y * scale
    rings, ring_terms = _ring_areas2(x, y, prepared.rings)
    polygon = float(rings[0] - rings[1:].sum())
    v = (result.vertices[:, axes] - result.vertices[prepared.rings[0][0], axes]) * scale
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    left = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
    right = (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    total = float(np.abs(left - right).sum())
    terms = float(np.abs(left).sum() + np.abs(right).sum()) + ring_terms
    rounding = 16 * np.finfo(np.float64).eps * terms
    off = abs(total - polygon)
    if polygon > 0 and off <= AREA_TOLERANCE * polygon + rounding:
        return
    share = f"{total / polygon:.6g} times" if polygon > 0 else "a non-zero area for"
    raise TriangulationError(
        f"the triangles' areas add up to {share} the polygon's area "
        f"(relative tolerance {AREA_TOLERANCE:g}): the triangulation cannot be right and "
        "is not output"
    )


def _crosses_with_zero_area(clean: list[np.ndarray], axes: tuple[int, int]) -> bool:
    """The outer ring has zero signed area although its points are not all collinear.

    A ring that is not a line and encloses no net area must cross or touch itself (a simple
    ring of non-collinear points has non-zero area).
    """
    if not clean or len(clean[0]) < 3:
        return False
    x, y = clean[0][:, axes[0]], clean[0][:, axes[1]]
    if ring_area_sign(x, y) != 0:
        return False
    far = np.flatnonzero((x != x[0]) | (y != y[0]))
    if len(far) == 0:
        return False
    b = far[0]
    return bool(np.any(orient_many(x[0], y[0], x[b], y[b], x, y) != 0))


# Relative area difference below which a triangulation counts as keeping the polygon's area.
_AREA_KEPT = 1e-12
# Relative difference between the triangles' absolute areas and the polygon's beyond which a
# result is wrong (rounding of sums of many products stays orders of magnitude below it).
AREA_TOLERANCE = 1e-9


# Share of the polygon's area that an as-given tree's reversed triangles reach before its
# repair is made (_LossWatch).
_REPAIR_AT = 1e-6


def _polygon_area2(prepared: PreparedRings) -> float:
    """Twice (outer ring area - island areas), in the working plane."""
    rings, _ = _ring_areas2(prepared.x, prepared.y, prepared.rings)
    return float(rings[0] - rings[1:].sum())


def _area_loss(prepared: PreparedRings, result: Triangulation, axes: tuple[int, int]) -> float:
    """|sum of triangle areas - (outer ring area - island areas)| relative to the latter."""
    polygon = _polygon_area2(prepared)
    t = result.triangles
    if len(t) == 0 or polygon <= 0:
        return 0.0 if len(t) == 0 and polygon <= 0 else float("inf")
    v = result.vertices[:, axes]
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    return float(abs(np.abs(cross).sum() - polygon) / polygon)


def _ring_areas2(
    x: np.ndarray, y: np.ndarray, rings: Sequence[np.ndarray]
) -> tuple[np.ndarray, float]:
    """Twice the absolute shoelace area of each ring (vertex ids into ``x``, ``y``), taken
    from its first vertex, and the sum of the absolute values of every product in them."""
    ids = np.concatenate(rings)
    sizes = np.array([len(ring) for ring in rings])
    starts = np.cumsum(sizes) - sizes
    first = np.repeat(ids[starts], sizes)
    rx, ry = x[ids] - x[first], y[ids] - y[first]
    following = np.arange(1, len(ids) + 1)
    following[starts + sizes - 1] = starts
    left, right = rx * ry[following], rx[following] * ry
    areas = np.abs(np.add.reduceat(left - right, starts))
    return areas, float(np.abs(left).sum() + np.abs(right).sum())


def _repaired(
    clean: list[np.ndarray], *, rule: str, plane: str, points: np.ndarray | None = None
) -> Triangulation | None:
    """Triangulation of the rings made valid (shapely's make_valid, "structure" method).

    The parts are triangulated one by one and merged (one root per part); points where the
    input rings cross become vertices; each interior point goes to the part that holds it.
    None when shapely is not available or repair fails.
    """
    try:
        import shapely
    except ImportError:  # pragma: no cover - shapely is optional at run time
        return None
    try:
        holes = [ring for ring in clean[1:] if len(ring) >= 3]
        polygon = shapely.Polygon(clean[0], holes)
        fixed = shapely.make_valid(polygon, method="structure", keep_collapsed=False)
    except (ValueError, shapely.errors.GEOSException):
        return None
    parts = [g for g in getattr(fixed, "geoms", [fixed]) if g.geom_type == "Polygon"]
    parts = [p for g in parts for p in getattr(g, "geoms", [g]) if not p.is_empty]
    known = np.concatenate(clean)
    pieces = []
    for part in parts:
        rings = [np.asarray(r.coords) for r in (part.exterior, *part.interiors)]
        rings = [_with_z(r, known) for r in rings]
        # a repaired part can still fail where it touches itself: as given, without repair
        pieces.append(
            _triangulate(
                rings,
                rule=rule,
                planar_tolerance=0.0,
                invalid="as_given",
                plane=plane,
                repair=False,
                points=points,
            )
        )
    merged = merge_triangulations(pieces)
    if points is not None and len(points) and not pieces:
        merged.point_ids = np.full(len(points), -1, dtype=np.int64)
    return merged


def _with_z(ring: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(n, 3) ring; a point without z (a crossing point) takes the z of the nearest input vertex."""
    out = np.zeros((len(ring), 3))
    out[:, : min(ring.shape[1], 3)] = ring[:, :3]
    missing = ring.shape[1] < 3 or ~np.isfinite(out[:, 2])
    missing = np.broadcast_to(missing, (len(ring),)).copy()
    if missing.any():
        d2 = ((out[missing, None, :2] - known[None, :, :2]) ** 2).sum(axis=2)
        out[missing, 2] = known[np.argmin(d2, axis=1), 2]
    return out


def merge_triangulations(pieces: list[Triangulation]) -> Triangulation:
    """One Triangulation of several parts: vertices concatenated, one tree root per part."""
    if not pieces:
        return Triangulation()
    offsets = np.cumsum([0] + [len(p.vertices) for p in pieces[:-1]])
    starts = np.cumsum([0] + [len(p.triangles) for p in pieces[:-1]])
    parent = [np.where(p.parent < 0, -1, p.parent + s) for p, s in zip(pieces, starts)]
    point_ids = np.full(len(pieces[0].point_ids), -1, dtype=np.int64)
    for piece, offset in zip(pieces, offsets):
        used = piece.point_ids >= 0
        point_ids[used] = piece.point_ids[used] + offset
    return Triangulation(
        vertices=np.concatenate([p.vertices for p in pieces]),
        triangles=np.concatenate([p.triangles + o for p, o in zip(pieces, offsets)]),
        parent=np.concatenate(parent).astype(np.int64),
        depth=np.concatenate([p.depth for p in pieces]),
        side=np.concatenate([p.side for p in pieces]),
        point_ids=point_ids,
    )


def _as_given(invalid: str) -> bool:
    if invalid not in INVALID_MODES:
        raise ValueError(f"invalid must be one of {INVALID_MODES}, not {invalid!r}")
    return invalid == "as_given"


def _clear_area(prepared: PreparedRings, x0: float, y0: float) -> bool:
    """The area is surely not negligible (:func:`negligible_area`), decided for all rings at
    once with a margin for any summation order (False: too close to call here)."""
    ids = np.concatenate(prepared.rings)
    counts = np.array([len(r) for r in prepared.rings], dtype=np.int64)
    starts = np.cumsum(counts) - counts
    x, y = prepared.x[ids] - x0, prepared.y[ids] - y0
    span = max(float(np.abs(x).max()), float(np.abs(y).max()))
    if not 0 < span < math.inf:
        return False
    scale = np.ldexp(1.0, -int(np.frexp(span)[1]))
    x, y = x * scale, y * scale
    left, right = shoelace_products(x, y, starts, starts + counts - 1)
    net = float(np.sum(left - right))
    magnitude = float(np.sum(np.abs(left)) + np.sum(np.abs(right)))
    return bool(area_surely_clear(net, magnitude, len(ids)))


def negligible_area(prepared: PreparedRings) -> bool:
    """The polygon's area (outer ring less islands) is zero to within double rounding.

    Measured relative to the magnitudes of the shoelace terms (taken from the outer ring's
    first vertex, so an offset does not matter): such a polygon is a degenerate sliver, e.g.
    an island that repeats the outer ring up to 1e-28, and gives no triangles.
    """
    x0, y0 = prepared.x[prepared.rings[0][0]], prepared.y[prepared.rings[0][0]]
    if len(prepared.rings) > 1 and _clear_area(prepared, x0, y0):
        return False
    spans = [np.abs(prepared.x[r] - x0).max() for r in prepared.rings]
    spans += [np.abs(prepared.y[r] - y0).max() for r in prepared.rings]
    # a power-of-two scale (exact) keeps the products away from underflow and overflow
    scale = np.ldexp(1.0, -int(np.frexp(max(spans))[1])) if max(spans) > 0 else 1.0
    net = 0.0
    magnitude = 0.0
    for ring in prepared.rings:
        x = (prepared.x[ring] - x0) * scale
        y = (prepared.y[ring] - y0) * scale
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        net += float(np.sum(x * yn - xn * y))
        magnitude += float(np.sum(np.abs(x * yn)) + np.sum(np.abs(xn * y)))
    return abs(net) <= 8 * np.finfo(np.float64).eps * magnitude
