"""The BSP tree of many bridged sequences in lock-step rounds (docs/algorithm.md, 3-5).

Every open node (sub-polygon) of every polygon tests candidates in the same round; the tests
are those of ``one_polygon.facing_candidates`` and ``correct_candidates`` over flat ragged arrays.
Each node knows its pre-order index when it is created (a node on the range [lo, hi] has
hi - lo - 1 triangles below and including it), so its record goes straight to its final row.

Where the time goes (rule "first"): conditions 1 and 4 are a few orientations per candidate
(``_facing``); conditions 2 and 3 test every vertex of the sub-polygon (``_bad_rows``, padded
tables of float64 signs with an exact fallback), which grows with the square of the
sub-polygon size as the trees are fan-shaped. A vertex found strictly inside a candidate's
triangle is tested first against the node's next candidates (``_strictly_inside``), which
rules out most failing candidates without a table. Candidates in proven-valid polygons test
only the sub-polygon's bent vertices (``_bent_in_triangle``); where a node of such a tree
then finds no candidate, the wrong ancestor's subtree is built again in place with every
table (``_reopened``), or failing that the whole tree (``Trees.again``).

Rule "delaunay" (``_delaunay_apex``) compares every candidate of a node with its largest-angle
guess in padded float tables, decided beyond static error bounds; nodes it cannot decide so
take exact tries (``_delaunay_tries``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..geometry.predicates import (
    CCW_ERRBOUND,
    UNDERFLOW_SLACK,
    grid_exact,
    incircle_sos_many,
    orient_many,
    strictly_between,
    sum_error,
)
from ..geometry.predicates_batch import (
    crossing,
    orient_items,
    orient_rows,
    row_bound,
    sure_signs,
)
from ..geometry.rings_batch import ragged_index
from .one_by_one import first_nodes

# test items x sub-polygon vertices per numpy pass: tables of about 1 MB stay in the cache
_CHUNK_ELEMENTS = 1 << 17

# columns of the per-position table: coordinates, the edge to the next position, the edge
# from the previous position, the error bound of the sequence's orientations, the turn
_X, _Y, _EX, _EY, _PX, _PY, _BOUND, _TURN = range(8)
# _TURN values: the sign of the turn s_{j-1} s_j s_{j+1}, or _SPIKE for a collinear turn back
_SPIKE = 2.0
_EPS = 2.0**-53
# |fl(q - p)| <= (1 + eps) |q - p|, the extents and the bound itself are rounded: margin
_BOUND_FACTOR = CCW_ERRBOUND * (1.0 + 32.0 * _EPS)
# sequences of more positions are long (see _edges_across)
LONG_SEQUENCE = 256


@dataclass
class Trees:
    """BSP results of many sequences: triangle rows of sequence i at ``start[i]``, read
    where ``ok``."""

    triangles: np.ndarray  # (T, 3) local vertex indices
    parent: np.ndarray
    depth: np.ndarray
    side: np.ndarray
    start: np.ndarray
    count: np.ndarray
    ok: np.ndarray
    # per sequence: proven valid, but its tree did not complete (build it with every table)
    again: np.ndarray


@dataclass
class Sequences:
    """Per position of the flat sequences (each with its closing repeat): coordinates (also
    as (x, y) rows), the other position of the same vertex (``twin``, bridge ends) or -1,
    the extents of its sequence, and the ``table`` of the columns above; ``exact``: every
    float orientation is exact (grid coordinates). ``proven``: the position's polygon is
    proven valid; ``bent``: the positions of proven sequences that are not a strict left
    turn or are a bridge end (``bent_xy``: their coordinates; ``bent_xy32``: the same rounded
    to float32, one complex64 each), and ``bent_rank[p]`` how many of them come before
    position p; ``loops``: the outermost ranges [p, q] between the two positions of a bridge
    end of a proven sequence (an island, its bridges and the islands joined to it), as rows
    (p, q, x0, x1, y0, y1) with their boxes, in order; ``run_after[p]`` and ``run_before[p]``:
    the first position at or after p, and the last at or before it, where the sequence
    bends (:func:`straight_runs`); ``long``: the position's sequence has more than
    ``LONG_SEQUENCE`` positions, ``any_long``: some sequence has."""

    sx: np.ndarray
    sy: np.ndarray
    xy: np.ndarray
    twin: np.ndarray
    extent_x: np.ndarray
    extent_y: np.ndarray
    table: np.ndarray
    exact: bool
    starts: np.ndarray
    proven: np.ndarray
    bent: np.ndarray
    bent_xy: np.ndarray
    bent_xy32: np.ndarray
    bent_rank: np.ndarray
    loops: np.ndarray
    run_after: np.ndarray
    run_before: np.ndarray
    long: np.ndarray
    runs: RunBoxes | None = None
    circle_bounds: np.ndarray | None = None
    any_long: bool = False

    def rows_at(self, positions: np.ndarray) -> np.ndarray:
        """The ``table`` rows of ``positions`` (gathered as four complex numbers per row,
        which numpy copies faster than eight floats)."""
        return np.take(self.table.view(np.complex128), positions, axis=0).view(np.float64)

    def circle_bounds_at(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per position, the error bounds of :func:`_delaunay_guess` for its sequence: of a
        cross product of two coordinate differences and of the in-circle value (gathered as
        one complex number, computed once, when first needed)."""
        if self.circle_bounds is None:
            ex, ey = self.extent_x, self.extent_y
            bounds = np.empty(len(ex), dtype=np.complex128)
            bounds.real = 16.0 * _EPS * ex * ey + UNDERFLOW_SLACK
            bounds.imag = 128.0 * _EPS * ex * ey * (ex * ex + ey * ey) + UNDERFLOW_SLACK
            self.circle_bounds = bounds
        both = np.take(self.circle_bounds, positions)
        return both.real, both.imag

    def run_boxes(self) -> RunBoxes:
        """The boxes of the runs of every sequence (computed once, when first needed)."""
        if self.runs is None:
            self.runs = RunBoxes.of(self.sx, self.sy, self.starts)
        return self.runs

    @classmethod
    def of(
        cls,
        sx: np.ndarray,
        sy: np.ndarray,
        twin: np.ndarray,
        starts: np.ndarray,
        exact: bool,
        proven: np.ndarray | None = None,
    ) -> Sequences:
        """``proven``: per sequence, its polygon is proven valid (none if omitted)."""
        n = len(sx)
        lengths = np.diff(np.r_[starts, n])
        extent_x, extent_y = _extents(sx, sy, starts)
        table = np.zeros((n, 8))
        table[:, _X] = sx
        table[:, _Y] = sy
        np.subtract(sx[1:], sx[:-1], out=table[:-1, _EX])
        np.subtract(sy[1:], sy[:-1], out=table[:-1, _EY])
        table[1:, _PX] = table[:-1, _EX]
        table[1:, _PY] = table[:-1, _EY]
        if not exact:
            # every coordinate difference in a sequence is within its extents
            bound = _BOUND_FACTOR * 2.0 * extent_x * extent_y + UNDERFLOW_SLACK
            table[:, _BOUND] = np.repeat(bound, lengths)
        if n > 2:
            px, py, vx, vy, nx, ny = sx[:-2], sy[:-2], sx[1:-1], sy[1:-1], sx[2:], sy[2:]
            turn = orient_items(px, py, vx, vy, nx, ny, exact).astype(np.float64)
            z = np.flatnonzero(turn == 0)
            if len(z):
                dot = (nx[z] - vx[z]) * (px[z] - vx[z]) + (ny[z] - vy[z]) * (py[z] - vy[z])
                turn[z[dot > 0]] = _SPIKE
            table[1:-1, _TURN] = turn
        extent_x, extent_y = np.repeat(extent_x, lengths), np.repeat(extent_y, lengths)
        xy = np.ascontiguousarray(table[:, :2])
        if proven is None:
            proven_at = np.zeros(n, dtype=bool)
        else:
            proven_at = np.repeat(np.asarray(proven, dtype=bool), lengths)
        # a bridge end is bent as a vertex (two left turns that together turn more than 180
        # degrees, around the island), whatever the turn of each of its positions
        bent_at = proven_at & ((table[:, _TURN] != 1.0) | (twin >= 0))
        bent_rank = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(bent_at, out=bent_rank[1:])
        bent = np.flatnonzero(bent_at)
        bent_xy = xy[bent]
        with np.errstate(over="ignore"):  # beyond float32's range: +-inf, still in order
            bent_xy32 = bent_xy.astype(np.float32).view(np.complex64).ravel()
        loops = _loops(sx, sy, twin, proven_at)
        run_after, run_before = straight_runs(sx, sy, table[:, _TURN], starts)
        long = np.repeat(lengths > LONG_SEQUENCE, lengths)
        return cls(
            sx, sy, xy, twin, extent_x, extent_y, table, exact, starts, proven_at, bent,
            bent_xy, bent_xy32, bent_rank, loops, run_after, run_before, long,
            any_long=bool(lengths.max(initial=0) > LONG_SEQUENCE),
        )  # fmt: skip


def straight_runs(
    sx: np.ndarray, sy: np.ndarray, turn: np.ndarray, starts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per position p of the sequences laid out from ``starts`` (each with its closing
    repeat): the first position at or after p, and the last at or before p, where its
    sequence bends: the position is not strictly between its neighbours on their line
    (``turn``, the exact sign of each position's turn, is 0 and the coordinates strictly
    monotone; comparisons of floats are exact), or begins or ends a sequence. Between two such
    positions the sequence runs straight on."""
    n = len(sx)
    straight = np.zeros(n, dtype=bool)
    if n > 2:
        xa, xb, xc, ya, yb, yc = sx[:-2], sx[1:-1], sx[2:], sy[:-2], sy[1:-1], sy[2:]
        between = ((xa < xb) & (xb < xc)) | ((xa > xb) & (xb > xc))
        between |= (xa == xb) & (xb == xc) & (((ya < yb) & (yb < yc)) | ((ya > yb) & (yb > yc)))
        straight[1:-1] = (turn[1:-1] == 0.0) & between
    # each sequence's first position and its closing repeat
    straight[starts] = False
    straight[starts[1:] - 1] = False
    straight[n - 1 :] = False
    index = np.arange(n, dtype=np.int64)
    after = np.minimum.accumulate(np.where(straight, n, index)[::-1])[::-1]
    before = np.maximum.accumulate(np.where(straight, -1, index))
    return after, before


def _past_runs(seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Rule first's next candidates ``c`` of the bases (s_hi, s_lo), moved past those in a
    straight run back from s_hi (s_hi-1 then lies in the relative interior of their side from
    s_hi) or on from s_lo (s_lo+1 on their side from s_lo): all fail condition 3, and s_lo+1
    comes last. A run back from s_hi to s_lo+1 leaves no candidate (c = lo)."""
    top = np.maximum(seqs.run_before[hi - 1], lo + 1)
    c = np.where((c >= top) & (c <= hi - 2), top - 1, c)
    low = np.minimum(seqs.run_after[lo + 1], hi - 1)
    return np.where((c >= lo + 2) & (c <= low), lo + 1, c)


def _loops(sx: np.ndarray, sy: np.ndarray, twin: np.ndarray, proven: np.ndarray) -> np.ndarray:
    """:attr:`Sequences.loops`: (k, 6) float rows (p, q, x0, x1, y0, y1)."""
    p = np.flatnonzero(proven & (twin > np.arange(len(twin))))
    q = twin[p]
    # outermost: not within an earlier range (the ranges of one sequence nest or are apart)
    outer = q > np.maximum.accumulate(np.r_[-1, q[:-1]])
    p, q = p[outer], q[outer]
    rows = np.empty((len(p), 6))
    rows[:, 0], rows[:, 1] = p, q
    if len(p):
        # each range's extremes: reductions over [p, q], the gaps between ranges dropped
        cuts = np.column_stack([p, q + 1]).ravel()
        for column, values in ((2, sx), (4, sy)):
            padded = np.append(values, 0.0)
            rows[:, column] = np.minimum.reduceat(padded, cuts)[::2]
            rows[:, column + 1] = np.maximum.reduceat(padded, cuts)[::2]
    return rows


@dataclass
class RunBoxes:
    """Each sequence cut into runs of ``_RUN`` edges from its first position (run j holds
    positions start + _RUN j .. start + _RUN (j + 1), fewer at the end): per position the
    start of its sequence and the index of that sequence's first run, and per run its box."""

    start_of: np.ndarray
    first_run: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    y0: np.ndarray
    y1: np.ndarray

    @classmethod
    def of(cls, sx: np.ndarray, sy: np.ndarray, starts: np.ndarray) -> RunBoxes:
        lengths = np.diff(np.r_[starts, len(sx)])
        count = (lengths - 1 + _RUN - 1) // _RUN
        first_run = np.cumsum(count) - count
        run_start = ragged_index(np.zeros(len(starts), dtype=np.int64), count) * _RUN
        run_start += np.repeat(starts, count)
        run_last = np.repeat(starts + lengths - 1, count)
        index = np.arange(_RUN + 1, dtype=np.int64)[:, None] + run_start
        np.minimum(index, run_last, out=index)
        x, y = sx[index], sy[index]
        return cls(
            np.repeat(starts, lengths),
            np.repeat(first_run, lengths),
            x.min(axis=0),
            x.max(axis=0),
            y.min(axis=0),
            y.max(axis=0),
        )


def _candidates(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every candidate of every node (lo, hi), in candidate order (hi - 1 down to lo + 1):
    (node, candidate position) pairs."""
    span = hi - lo - 1
    owner = np.repeat(np.arange(len(lo), dtype=np.int64), span)
    c = np.repeat(hi - 1, span) - ragged_index(np.zeros(len(lo), np.int64), span)
    return owner, c


def _facing_candidates(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    pairs: tuple[np.ndarray, np.ndarray] | None = None,
    corners: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """The (node, candidate position) ``pairs`` (default: every candidate of every node
    (lo, hi), :func:`_candidates`) that face their base, in their order; with ``corners``,
    those :func:`_within_corners` keeps."""
    owner, c = _candidates(lo, hi) if pairs is None else pairs
    facing = _facing(seqs, lo[owner], hi[owner], c)
    owner, c = owner[facing], c[facing]
    if corners:
        inside = _within_corners(seqs, lo, hi, owner, c)
        owner, c = owner[inside], c[inside]
    return owner, c


def _facing(seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Per candidate position ``c`` on the base of the sub-polygon [lo, hi]: conditions 1 (c
    strictly left of the chord s_hi -> s_lo) and 4 (the interior angle at c)."""
    n = len(c)
    at_c = seqs.rows_at(c)
    # dx[0], dy[0] = a - c, dx[1], dy[1] = b - c (a = s_hi, b = s_lo)
    ab = np.take(seqs.xy, np.stack([hi, lo]), axis=0)
    dx = ab[..., 0] - at_c[:, _X]
    dy = ab[..., 1] - at_c[:, _Y]
    det = np.empty((5, n))
    # 0: orient(a, b, c) = (a - c) x (b - c); 1, 2: orient(c, c+1, t) = e_c x (t - c);
    # 3, 4: orient(c-1, c, t) = e_{c-1} x (t - c), t = a, b (each one float orientation with
    # c as the common point, within the sequence's bound)
    np.multiply(dx[0], dy[1], out=det[0])
    det[0] -= dy[0] * dx[1]
    np.multiply(at_c[:, _EX], dy, out=det[1:3])
    det[1:3] -= at_c[:, _EY] * dx
    np.multiply(at_c[:, _PX], dy, out=det[3:5])
    det[3:5] -= at_c[:, _PY] * dx
    bound = at_c[:, _BOUND]
    positive = det > bound
    negative = det < -bound
    if not seqs.exact:
        unsure = ~(positive | negative)
        # exact zeros: a is c + 1 (the candidate next to hi), b is c - 1
        unsure[1] &= c + 1 != hi
        unsure[4] &= c - 1 != lo
        items = np.flatnonzero(unsure.any(axis=0))
        if len(items):
            # few items, mostly at bridge ends: the known zeros are looked up for them alone
            some = unsure[:, items]
            near_x, near_y = dx[:, items], dy[:, items]
            _drop_known_zeros(seqs, lo[items], hi[items], c[items], near_x, near_y, some)
            unsure[:, items] = some
            if some.any():
                _decide(seqs, lo, hi, c, unsure, positive, negative, _ALL_ROWS)
    turn = at_c[:, _TURN]
    # a and b not right of the edge after c, and not right of the edge before c: the angle
    # holds them where c is a strict left turn if both hold, at a right turn if either
    # does, where straight if the first does, and at a spike always
    angle = ~negative[1:3]
    before = ~negative[3:5]
    angle &= before | (turn != 1.0)
    before &= turn == -1.0
    angle |= before
    angle |= turn == _SPIKE
    return positive[0] & angle[0] & angle[1]


def _drop_known_zeros(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
    unsure: np.ndarray,
) -> None:
    """Clears the ``unsure`` entries of :func:`_facing`'s determinants that are exactly 0
    because their point is one of their line's points: c at a or at b (``dx``, ``dy``: a - c
    and b - c, exactly 0 only there), or a or b the other position (twin) of the line's end
    c + 1 or c - 1, a bridge end. These are most of the unsure entries in polygons with
    islands, and :func:`_decide` would find them at a higher fixed cost."""
    at_c = (dx == 0) & (dy == 0)
    unsure[0] &= ~(at_c[0] | at_c[1])
    unsure[1:3] &= ~at_c
    unsure[3:5] &= ~at_c
    twin = np.take(seqs.twin, np.stack([hi, lo]))
    unsure[1:3] &= twin != c + 1
    unsure[3:5] &= twin != c - 1


# rows 1-4 of the determinants in :func:`_facing`: the line's first position relative to c
# (the line is that position -> the next) and whether the point is hi (else lo)
_SHIFT_A = np.array([0, 0, 0, -1, -1], dtype=np.int64)
_POINT_AT_HI = np.array([False, True, False, True, False])


def _facing_ear(seqs: Sequences, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """:func:`_facing` of the candidates c = hi - 1: a = s_hi is c + 1, so the orientation
    of a against the edge c -> c + 1 is 0 and that of b equals condition 1's. Conditions 1
    and 4 reduce to orient(a, b, c) > 0 and, where c is a strict left turn, neither a nor b
    right of the edge c - 1 -> c (the same float determinants as :func:`_facing`'s)."""
    n = len(lo)
    c = hi - 1
    at_c = seqs.rows_at(c)
    # a - c is the edge c -> c + 1; b - c
    dxa, dya = at_c[:, _EX], at_c[:, _EY]
    b = np.take(seqs.xy, lo, axis=0)
    dxb = b[:, 0] - at_c[:, _X]
    dyb = b[:, 1] - at_c[:, _Y]
    det = np.empty((3, n))
    np.multiply(dxa, dyb, out=det[0])
    det[0] -= dya * dxb
    np.multiply(at_c[:, _PX], dya, out=det[1])
    det[1] -= at_c[:, _PY] * dxa
    np.multiply(at_c[:, _PX], dyb, out=det[2])
    det[2] -= at_c[:, _PY] * dxb
    bound = at_c[:, _BOUND]
    positive = det > bound
    negative = det < -bound
    if not seqs.exact:
        unsure = ~(positive | negative)
        # exact zero: b is c - 1
        unsure[2] &= c - 1 != lo
        if unsure.any():
            _decide(seqs, lo, hi, c, unsure, positive, negative, _EAR_ROWS)
    return positive[0] & ((at_c[:, _TURN] != 1.0) | ~(negative[1] | negative[2]))


# the rows of :func:`_facing`'s determinants, and those that :func:`_facing_ear` computes
_ALL_ROWS = np.arange(5, dtype=np.int64)
_EAR_ROWS = np.array([0, 3, 4], dtype=np.int64)


def _decide(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    unsure: np.ndarray,
    positive: np.ndarray,
    negative: np.ndarray,
    det_rows: np.ndarray,
) -> None:
    """Exact signs of the ``unsure`` entries of ``positive`` and ``negative``, whose rows are
    the determinants ``det_rows`` of :func:`_facing`."""
    rows, items = np.nonzero(unsure)
    det = det_rows[rows]
    # per determinant: the line c + _SHIFT_A -> the next position (0: hi -> lo) and the
    # point, lo or hi (0: c)
    at_c = c[items]
    line_a = at_c + _SHIFT_A[det]
    line_b = line_a + 1
    point = np.where(_POINT_AT_HI[det], hi[items], lo[items])
    row0 = np.flatnonzero(det == 0)
    if len(row0):
        line_a[row0], line_b[row0], point[row0] = hi[items[row0]], lo[items[row0]], at_c[row0]
    sx, sy = seqs.sx, seqs.sy
    ax, ay, bx, by, px, py = sx[line_a], sy[line_a], sx[line_b], sy[line_b], sx[point], sy[point]
    # a point equal to one of the line's points: exactly 0
    rest = np.flatnonzero(~(((px == ax) & (py == ay)) | ((px == bx) & (py == by))))
    signs = np.zeros(len(rows), dtype=np.int8)
    if len(rest):
        signs[rest] = orient_many(ax[rest], ay[rest], bx[rest], by[rest], px[rest], py[rest])
    positive[rows, items] = signs > 0
    negative[rows, items] = signs < 0


# below this many table entries a round uses one table for all items
_ONE_TABLE = 1 << 16
# padded row widths of the sub-polygon vertex tables (rows pad with the position hi)
_WIDTHS = np.array([4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024])


def _pass_tables(
    seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray, every_above: int | None = None
) -> np.ndarray:
    """Per candidate ``c`` that passes conditions 1 and 4 on the base of the sub-polygon
    [lo, hi]: it passes conditions 2 and 3 too, so that its triangle is correct. Sub-polygons
    of more than ``every_above`` positions are tested against every position, also in proven
    polygons."""
    return _table_results(seqs, lo, hi, c, every_above)[0]


def _table_results(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    every_above: int | None = None,
    crossings: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_pass_tables`, and per candidate a position found strictly inside its triangle
    or -1; ``crossings``: see :func:`_tables`."""
    ok = np.ones(len(c), dtype=bool)
    inside = np.full(len(c), -1, dtype=np.int64)
    # a 3-vertex sub-polygon has only its corners and its own sides: conditions 2 and 3 hold
    idx = np.flatnonzero(hi - lo > 2)
    if not len(idx):
        return ok, inside
    every = np.zeros(len(idx), dtype=bool)
    if every_above is not None:
        every = hi[idx] - lo[idx] > every_above
    for part, every_table in ((idx[every], True), (idx[~every], False)):
        if len(part):
            if every_table:
                bad, inside[part] = _all_tables(seqs, lo[part], hi[part], c[part])
            else:
                bad, inside[part] = _tables(seqs, lo[part], hi[part], c[part], crossings)
            ok[part[bad]] = False
    return ok, inside


def _known_then_tables(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    owner: np.ndarray,
    c: np.ndarray,
    known: np.ndarray,
    known_above: int,
    every_above: int | None,
    crossings: bool = False,
) -> np.ndarray:
    """:func:`_pass_tables` of candidates ``c`` of nodes ``owner``, those of sub-polygons of
    more than ``known_above`` positions holding their node's ``known`` position (found
    inside an earlier candidate's triangle, -1: none) strictly inside failing without the
    tables; positions the tables find inside become their nodes' known ones.
    ``every_above``: as for :func:`_pass_tables`; ``crossings``: see :func:`_tables`."""
    ok = np.ones(len(c), dtype=bool)
    b = known[owner]
    some = np.flatnonzero((b >= 0) & (hi[owner] - lo[owner] > known_above))
    if len(some):
        o = owner[some]
        ok[some] = ~_strictly_inside(seqs, hi[o], lo[o], c[some], b[some])
    rest = np.flatnonzero(ok)
    o = owner[rest]
    ok[rest], inside = _table_results(seqs, lo[o], hi[o], c[rest], every_above, crossings)
    found = inside >= 0
    known[o[found]] = inside[found]
    return ok


def _tables(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    crossings: bool = False,
    across: np.ndarray | None = None,
    least: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Conditions 2 and 3 for facing candidates ``c`` of sub-polygons [lo, hi] of at least 4
    vertices: per item whether it fails, and a position strictly inside its triangle or -1.

    In proven-valid polygons only the bent positions are tested (:func:`_bent_in_triangle`,
    with ``crossings`` some edges too, and ``across`` and ``least`` as there).
    """
    proven = seqs.proven[lo]
    if proven.all():
        return _bent_in_triangle(seqs, lo, hi, c, crossings, across, least)
    if not proven.any():
        return _all_tables(seqs, lo, hi, c)
    bad = np.zeros(len(c), dtype=bool)
    inside = np.full(len(c), -1, dtype=np.int64)
    idx = np.flatnonzero(proven)
    part = None if across is None else across[idx]
    some = None if least is None else least[idx]
    bad[idx], inside[idx] = _bent_in_triangle(seqs, lo[idx], hi[idx], c[idx], crossings, part, some)
    if across is not None:
        across[idx] = part
    if least is not None:
        least[idx] = some
    idx = np.flatnonzero(~proven)
    bad[idx], inside[idx] = _all_tables(seqs, lo[idx], hi[idx], c[idx])
    return bad, inside


def _bent_in_triangle(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    crossings: bool = False,
    across: np.ndarray | None = None,
    least: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_tables` for a proven-valid polygon, by its bent positions (not a strict left
    turn, or a bridge end) between lo and hi alone: a candidate fails where one of them lies
    in the closed triangle other than at a corner (exact signs) or where
    :func:`_bridge_at_corner` finds an edge across it, and passes otherwise, which is right
    provided that the polygon's tree completes.

    Why a tree that completes is the one every table gives: each node splits its chain into
    its triangle and two sub-chains, so the triangles' winding numbers add up to the
    sequence's, 1 inside the polygon and 0 outside. All are strictly counter-clockwise
    (condition 1), so they tile the polygon without overlap. Every edge of the sequence is a
    side of exactly one triangle, which lies on its left: a bridge's two copies have
    triangles on both sides, a ring edge has the exterior on its right. So no edge meets
    another triangle's open interior (condition 2), and no vertex lies in the relative
    interior of a side (condition 3: the triangles on both sides would cover the exterior
    next to its ring edges). Condition 4 is tested exactly before. So every triangle is
    correct. A failure found here is real: a vertex strictly inside brings its edges into
    the open triangle, and so does an edge across a side; a vertex on a new side fails
    condition 3; and none lies on the base, a side of the correct parent (or a ring edge at
    the root). A candidate passed wrongly thus leaves a tree that cannot complete: some node
    finds no candidate, and :func:`build_trees` builds the wrong ancestor's subtree again
    with every table (or, failing that, marks the tree to be built again).

    These tests find most failures: any boundary inside an ear comes in across its only new
    side, and its vertex farthest from that side is bent (the part of the ear beyond it is
    interior). A triangle with two new sides can also be crossed by a notch of the exterior,
    an island or a bridge with no vertex inside. With ``crossings`` (rule first, whose fans
    make many such triangles in large sub-polygons, and rule elevation, whose closest
    elevation often lies far across), :func:`_edges_across` looks for the edges most likely
    to cross one, so that fewer trees are built twice; ``across`` (per candidate, if given)
    then takes the first position e of an edge e -> e + 1 found across it. ``least`` (per
    candidate, if given) takes, for an ear (c = hi - 1) that fails, the apex of its base
    where :func:`_least_angle` finds it.
    """
    n = len(lo)
    corners = np.take(seqs.xy, np.stack([hi, lo, c]), axis=0)
    (ax, bx, cx), (ay, by, cy) = corners[..., 0], corners[..., 1]
    bad = _bridge_at_corner(seqs, lo, hi, c)
    if crossings:
        bad |= _edges_across(seqs, lo, hi, c, corners, across)
    found = np.full(n, -1, dtype=np.int64)
    first = seqs.bent_rank[lo + 1]
    # an ear's range ends before its candidate hi - 1, a corner (bent in most tests)
    count = seqs.bent_rank[np.where(c == hi - 1, c, hi)] - first
    index = ragged_index(first, count)
    if not len(index):
        return bad, found
    # the bent positions in the triangle's bounding box, first in float32: rounding is
    # monotone, so a point within the box is within it after rounding too (half the bytes
    # of float64 per entry; the exact tests below decide)
    with np.errstate(over="ignore"):
        low = np.minimum(np.minimum(corners[0], corners[1]), corners[2]).astype(np.float32)
        high = np.maximum(np.maximum(corners[0], corners[1]), corners[2]).astype(np.float32)
    low = np.repeat(low.view(np.complex64).ravel(), count).view(np.float32)
    high = np.repeat(high.view(np.complex64).ravel(), count).view(np.float32)
    pxy = np.take(seqs.bent_xy32, index).view(np.float32)
    within = pxy >= low
    within &= pxy <= high
    at = np.flatnonzero(within.view(np.uint16) == _BOTH)
    if not len(at):
        return bad, found
    owner = np.repeat(np.arange(n, dtype=np.int64), count)[at]
    qxy = np.take(seqs.bent_xy, index[at], axis=0)
    qx, qy = qxy[:, 0], qxy[:, 1]
    # a position at a corner's point (the candidate itself, a bridge end's twin) is neither
    # inside nor a failure: left out before any orientation (its signs are zeros)
    oax, oay = ax[owner], ay[owner]
    away = _off_corners(qx, qy, oax, oay, bx[owner], by[owner], cx[owner], cy[owner])
    if not away.all():
        kept = np.flatnonzero(away)
        at, owner, qx, qy, oax, oay = (v[kept] for v in (at, owner, qx, qy, oax, oay))
    o = owner
    closed, strictly = _in_triangle(
        oax, oay, bx[o], by[o], cx[o], cy[o], qx, qy, seqs.table[lo, _BOUND][o], seqs.exact
    )
    bad[owner[closed]] = True
    if least is not None:
        entry = (index, at)
        _least_angle(seqs, lo, hi, c, corners, bad, owner, closed, entry, qx, qy, least)
    strictly = np.flatnonzero(strictly)
    if len(strictly):
        # the first position strictly inside, per candidate (owners and positions ascend)
        who = owner[strictly]
        head = strictly[np.r_[True, who[1:] != who[:-1]]]
        found[owner[head]] = seqs.bent[index[at[head]]]
    return bad, found


# two True bytes read as one 2-byte value
_BOTH = np.array([True, True]).view(np.uint16)[0]


def _off_corners(
    px: np.ndarray,
    py: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
) -> np.ndarray:
    """Per item: the point (px, py) is none of the triangle's corners' points (exactly)."""
    away = (px != ax) | (py != ay)
    away &= (px != bx) | (py != by)
    away &= (px != cx) | (py != cy)
    return away


# _least_angle: fewer failing ears than this in a call are left to walk on
_LEAST_FEW = 16


def _least_angle(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    corners: np.ndarray,
    bad: np.ndarray,
    owner: np.ndarray,
    closed: np.ndarray,
    entry: tuple[np.ndarray, np.ndarray],
    qx: np.ndarray,
    qy: np.ndarray,
    least: np.ndarray,
) -> None:
    """Per failing ear (c = hi - 1, ``bad``) among the items (``corners``: their s_hi, s_lo
    and s_c, as :func:`_bent_in_triangle` takes them): the apex of its base, into
    ``least``. The bent positions in the items' triangles are ``seqs.bent[index[at]]`` for
    ``entry`` = (index, at), at ``qx``, ``qy``, of the item ``owner`` (ascending), in the
    closed triangle where ``closed``.

    The first correct candidate back from hi is the vertex visible from s_lo nearest in
    angle to the base (tree/visible_apex.py); the edge (hi - 1, hi) hides every point behind
    it, so that is the vertex in the ear's triangle of least angle at s_lo (the nearest
    along a ray). Its two edges turn away from s_lo on one side, so it is bent, unless an
    edge goes to a corner: lo + 1 and hi - 2 are tested too. Left out (-1) where the least
    angle is not surely below the next one's by the float angles' rounding, where that
    vertex is a bridge end whose twin lies in the sub-polygon, or where a corner's twin
    does (a bridge from s_hi may cross the ear with no vertex in it; one from s_lo or
    s_{hi-1} may have a left turn of least angle next to it)."""
    items = np.flatnonzero(bad & (c == hi - 1))
    if len(items) < _LEAST_FEW:
        return  # a few nodes walk on for less than this search's fixed calls
    for corner in (hi, lo, c):
        twin = seqs.twin[corner[items]]
        items = items[(twin <= lo[items]) | (twin >= hi[items])]
    if not len(items):
        return
    first = np.searchsorted(owner, items, side="left")
    count = np.searchsorted(owner, items, side="right") - first
    e = ragged_index(first, count)
    e = e[closed[e]]
    index, at = entry
    o = owner[e]
    position = seqs.bent[index[at[e]]]
    px, py = qx[e], qy[e]
    # lo + 1 and hi - 2 where they are not bent (a strict left turn, no bridge end) and lie
    # in the closed triangle other than at a corner's point
    near_item = np.concatenate([items, items])
    near = np.concatenate([lo[items] + 1, hi[items] - 2])
    keep = (near > lo[near_item]) & (near < hi[near_item] - 1)
    keep &= seqs.bent_rank[near + 1] == seqs.bent_rank[near]
    near, near_item = near[keep], near_item[keep]
    (kx, lx, cx), (ky, ly, cy) = corners[..., 0], corners[..., 1]
    if len(near):
        kx, ky, lx, ly = kx[near_item], ky[near_item], lx[near_item], ly[near_item]
        cx, cy = cx[near_item], cy[near_item]
        nx, ny = seqs.sx[near], seqs.sy[near]
        away = _off_corners(nx, ny, kx, ky, lx, ly, cx, cy)
        inside, _ = _in_triangle(
            kx, ky, lx, ly, cx, cy, nx, ny, seqs.table[lo[near_item], _BOUND], seqs.exact
        )
        keep = np.flatnonzero(inside & away)
        o = np.concatenate([o, near_item[keep]])
        position = np.concatenate([position, near[keep]])
        px, py = np.concatenate([px, nx[keep]]), np.concatenate([py, ny[keep]])
    ax, ay, bx, by = corners[0, o, 0], corners[0, o, 1], corners[1, o, 0], corners[1, o, 1]
    ux, uy = ax - bx, ay - by
    vx, vy = px - bx, py - by
    angle = np.arctan2(uy * vx - ux * vy, ux * vx + uy * vy)
    distance2 = vx * vx + vy * vy
    # the angles' rounding: coordinates' differences off by their magnitudes' ulp, over
    # the lengths of the two rays
    scale = np.abs(ax) + np.abs(ay) + np.abs(px) + np.abs(py) + np.abs(bx) + np.abs(by)
    with np.errstate(divide="ignore", invalid="ignore"):
        slack = 16.0 * _EPS * scale * (1.0 / np.sqrt(distance2) + 1.0 / np.hypot(ux, uy))
    slack += 1e-15
    order = np.lexsort((distance2, angle, o))
    o_sorted = o[order]
    head = np.flatnonzero(np.r_[True, o_sorted[1:] != o_sorted[:-1]])
    best = order[head]
    sure = angle[best] > slack[best]
    # the runner-up of the same item: its angle surely larger
    then = head + 1
    has_next = then < len(order)
    has_next[has_next] = o_sorted[then[has_next]] == o_sorted[head[has_next]]
    second = order[np.minimum(then, len(order) - 1)]
    apart = angle[second] - angle[best] > slack[best] + slack[second]
    sure &= ~has_next | apart
    item, position = o[best], position[best]
    twin = seqs.twin[position]
    sure &= (twin <= lo[item]) | (twin >= hi[item])
    least[item[sure]] = position[sure]


def _in_triangle(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    qx: np.ndarray,
    qy: np.ndarray,
    bound: np.ndarray,
    exact: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Whether each point q lies in the closed counter-clockwise triangle (a, b, c), and
    whether strictly inside (exact). The float orientations, as (v - u) x (q - a) +
    (v - u) x (a - u), are within 4 times the sequence's ``bound`` of the exact ones; the
    lowest of them decides, and only where it is within that of zero are exact signs taken."""
    if exact:
        signs = _triangle_signs(ax, ay, bx, by, cx, cy, qx, qy, True)
        return (signs >= 0).all(axis=0), (signs > 0).all(axis=0)
    dx, dy = qx - ax, qy - ay
    ex, ey = cx - bx, cy - by
    low = (bx - ax) * dy - (by - ay) * dx
    np.minimum(low, (ax - cx) * dy - (ay - cy) * dx, out=low)
    side = ex * dy - ey * dx
    side += ex * (ay - by) - ey * (ax - bx)
    np.minimum(low, side, out=low)
    tolerance = 4.0 * bound
    strictly = low > tolerance
    closed = strictly.copy()
    u = np.flatnonzero(np.abs(low) <= tolerance)
    if len(u):
        signs = _triangle_signs(ax[u], ay[u], bx[u], by[u], cx[u], cy[u], qx[u], qy[u], False)
        closed[u] = (signs >= 0).all(axis=0)
        strictly[u] = (signs > 0).all(axis=0)
    return closed, strictly


def _triangle_signs(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    qx: np.ndarray,
    qy: np.ndarray,
    exact: bool,
) -> np.ndarray:
    """Exact signs (3, n) of each point q against the sides a -> b, b -> c, c -> a of its
    triangle (a, b, c)."""
    return np.stack(
        [
            orient_items(ux, uy, vx, vy, qx, qy, exact)
            for ux, uy, vx, vy in ((ax, ay, bx, by), (bx, by, cx, cy), (cx, cy, ax, ay))
        ]
    )


def _bridge_at_corner(seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Per candidate other than the ear hi - 1: an edge at the other occurrence (a bridge end)
    of the corner s_lo or s_hi crosses the opposite new side (c s_hi or s_lo c) at a point
    inside both (exact signs). Such an edge runs through the open triangle (condition 2
    fails) with no vertex in it: a bridge from the fan's centre, say."""
    bad = np.zeros(len(lo), dtype=bool)
    other = np.flatnonzero(c != hi - 1)
    lo_o, hi_o = lo[other], hi[other]
    t_lo, t_hi = seqs.twin[lo_o], seqs.twin[hi_o]
    at_lo = other[(t_lo > lo_o) & (t_lo < hi_o)]
    at_hi = other[(t_hi > lo_o) & (t_hi < hi_o)]
    if not (len(at_lo) or len(at_hi)):
        return bad
    # rows: the side c s_hi against the edges at lo's twin t, then s_lo c against hi's
    rows = np.concatenate([at_lo, at_hi])
    t = seqs.twin[np.concatenate([lo[at_lo], hi[at_hi]])]
    end = np.concatenate([hi[at_lo], lo[at_hi]])
    rows, u, v = np.tile(rows, 2), np.tile(c[rows], 2), np.tile(end, 2)
    p = np.concatenate([t - 1, t])
    bad[rows[_cross(seqs, u, v, p, p + 1)]] = True
    return bad


def _edges_across(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    corners: np.ndarray,
    across: np.ndarray | None = None,
) -> np.ndarray:
    """Per candidate at least ``_ACROSS_CORNER`` positions from either base corner, in a
    sub-polygon of more than ``_RUN_MIN`` positions (``_ACROSS_LONG`` in a long sequence): an
    edge crosses its side c -> a (a = s_hi). Nearer a corner, a side that spans a couple of
    chain edges is hardly ever crossed without a bent position inside, and the search would
    cost more than the rare tree it mends. Edges looked at: those
    of the islands (and bridges) in [lo, hi) whose box meets the triangle's, and the chain's
    ``_WINDOW`` edges on either side of c. Not every edge: a crossing missed still leaves a
    tree that does not complete (see :func:`_bent_in_triangle`); a crossing found is real.

    One side is enough: with no bent position in the triangle, an edge that meets it crosses
    it from side to side, and no edge crosses the base (an edge or a correct side).
    ``across`` (per candidate, if given) takes the first position e of an edge e -> e + 1
    found across it.
    """
    bad = np.zeros(len(lo), dtype=bool)
    least = np.where(seqs.long[lo], _ACROSS_LONG, _RUN_MIN)
    other = np.flatnonzero(
        (c >= lo + _ACROSS_CORNER) & (c <= hi - _ACROSS_CORNER) & (hi - lo > least)
    )
    if not len(other):
        return bad
    low, high = corners.min(axis=0)[other], corners.max(axis=0)[other]
    lo_o, hi_o, c_o = lo[other], hi[other], c[other]
    # ranges [first, first + count) of edges per item: islands, then the chain around c
    firsts, counts, owners = [], [], []
    loops = seqs.loops
    if len(loops):
        start, end = loops[:, 0].astype(np.int64), loops[:, 1].astype(np.int64)
        first = np.searchsorted(end, lo_o, side="right")
        count = np.maximum(np.searchsorted(start, hi_o, side="left") - first, 0)
        item = np.repeat(np.arange(len(other)), count)
        row = ragged_index(first, count)
        box = loops[row]
        meet = (box[:, 3] >= low[item, 0]) & (box[:, 2] <= high[item, 0])
        meet &= (box[:, 5] >= low[item, 1]) & (box[:, 4] <= high[item, 1])
        item, row = item[meet], row[meet]
        e_first = np.maximum(start[row], lo_o[item])
        firsts.append(e_first)
        counts.append(np.maximum(np.minimum(end[row], hi_o[item]) - e_first, 0))
        owners.append(item)
    e_first = np.maximum(c_o - _WINDOW, lo_o)
    firsts.append(e_first)
    counts.append(np.minimum(c_o + _WINDOW, hi_o) - e_first)
    owners.append(np.arange(len(other)))
    first, count, owner = (np.concatenate(v) for v in (firsts, counts, owners))
    count = np.maximum(count, 0)
    # each range's points once: an edge can cross the segment c -> a only where its two
    # ends are not surely on one side of the line (float signs beyond the sequence's error
    # bound; within it, 0) and its box meets the segment's; only those get exact tests
    points = ragged_index(first, count + 1)
    item = np.repeat(owner, count + 1)
    ux, uy, vx, vy = seqs.sx[c_o], seqs.sy[c_o], seqs.sx[hi_o], seqs.sy[hi_o]
    dx, dy = vx - ux, vy - uy
    bound = row_bound(dx, dy, seqs.extent_x[c_o], seqs.extent_y[c_o])
    pxy = np.take(seqs.xy, points, axis=0)
    px, py = pxy[:, 0], pxy[:, 1]
    det = np.take(dx, item) * (py - np.take(uy, item))
    det -= np.take(dy, item) * (px - np.take(ux, item))
    b = np.take(bound, item)
    side = (det > b).view(np.int8) - (det < -b).view(np.int8)
    # edge k runs from entry k to entry k + 1 of the same range (not from a range's last)
    apart = side[:-1] * side[1:] <= 0
    apart[np.cumsum(count + 1)[:-1] - 1] = False
    k = np.flatnonzero(apart)
    item, e = item[k], points[k]
    x0, x1, y0, y1 = px[k], px[k + 1], py[k], py[k + 1]
    ax, ay, cx, cy = vx[item], vy[item], ux[item], uy[item]
    keep = (np.maximum(x0, x1) >= np.minimum(ax, cx)) & (np.minimum(x0, x1) <= np.maximum(ax, cx))
    keep &= (np.maximum(y0, y1) >= np.minimum(ay, cy)) & (np.minimum(y0, y1) <= np.maximum(ay, cy))
    keep &= (e != c_o[item]) & (e + 1 != c_o[item])
    keep = np.flatnonzero(keep)
    if len(keep):
        k = k[keep]
        hit = _crossing_signs(
            seqs.exact, side[k], side[k + 1], px[k], py[k], px[k + 1], py[k + 1],
            cx[keep], cy[keep], ax[keep], ay[keep],
        )  # fmt: skip
        crossed = other[item[keep[hit]]]
        bad[crossed] = True
        if across is not None:
            across[crossed] = e[keep[hit]]
    return bad


def _crossing_signs(
    exact: bool,
    o1: np.ndarray,
    o2: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    qx: np.ndarray,
    qy: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
) -> np.ndarray:
    """Per item: the segments pq and uv cross at a point inside both, given sure signs
    ``o1`` and ``o2`` of p and q against the line u -> v (0 where not sure: taken exactly,
    and written into ``o1`` and ``o2`` in place)."""
    for o, x, y in ((o1, px, py), (o2, qx, qy)):
        unsure = np.flatnonzero(o == 0)
        if len(unsure):
            o[unsure] = orient_items(
                ux[unsure], uy[unsure], vx[unsure], vy[unsure], x[unsure], y[unsure], exact
            )
    return crossing(o1, o2, px, py, qx, qy, ux, uy, vx, vy, exact)


# _edges_across looks at candidates at least this many positions from either base corner
_ACROSS_CORNER = 3
# chain edges looked at on either side of a candidate by _edges_across
_WINDOW = 16
# ... and in the sub-polygons of long sequences (``Sequences.long``), of more than this many
# positions (more than _RUN_MIN in short ones): there a tree built twice costs the tables of
# up to _REOPEN_LEVELS large ancestors and rounds of both kinds of tables, which in a short
# polygon's shallow tree cost less than the test of every candidate
_ACROSS_LONG = 8


def _cross(
    seqs: Sequences, u: np.ndarray, v: np.ndarray, p: np.ndarray, q: np.ndarray
) -> np.ndarray:
    """Per item: the segments s_u s_v and s_p s_q cross at a point inside both (exact)."""
    points = np.take(seqs.xy, np.stack([u, v, p, q]), axis=0)
    (ux, vx, px, qx), (uy, vy, py, qy) = points[..., 0], points[..., 1]
    # no sign known yet: all taken exactly
    o1, o2 = np.zeros(len(u), dtype=np.int8), np.zeros(len(u), dtype=np.int8)
    return _crossing_signs(seqs.exact, o1, o2, px, py, qx, qy, ux, uy, vx, vy)


def _all_tables(
    seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_tables` over every position of the sub-polygons.

    Items go in passes of bounded size: run by run (:func:`_bad_runs`) where a pass holds a
    sub-polygon of more than ``_RUN_MIN`` positions, else in tables of a few padded widths.
    """
    n = len(c)
    bad = np.zeros(n, dtype=bool)
    inside = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return bad, inside
    size = hi - lo + 1
    work = np.cumsum(size)
    cuts = np.searchsorted(work, np.arange(_CHUNK_ELEMENTS, work[-1], _CHUNK_ELEMENTS))
    bounds = np.unique(np.concatenate([[0], cuts, [n]])).tolist()
    for first, stop in zip(bounds[:-1], bounds[1:]):
        idx = np.arange(first, stop)
        part = size[first:stop]
        if (part > _RUN_MIN).any():
            # the small ones too run by run: one table call, not two (in the rounds of few
            # items, a large polygon's subtrees, the calls are most of the cost)
            bad[idx], inside[idx] = _bad_runs(seqs, lo[idx], hi[idx], c[idx])
            continue
        widths = np.minimum(np.searchsorted(_WIDTHS, part), len(_WIDTHS) - 1)
        if len(idx) * int(part.max()) <= _ONE_TABLE:
            widths[:] = widths.max()  # few items: one table, fewer numpy calls
        for k in np.unique(widths).tolist():
            rows = idx[widths == k]
            width = max(int(_WIDTHS[k]), int(part[widths == k].max()))
            bad[rows], inside[rows] = _bad_rows(
                seqs.sx, seqs.sy, lo[rows], hi[rows], c[rows], seqs.extent_x[c[rows]],
                seqs.extent_y[c[rows]], seqs.twin, width, seqs.exact,
            )  # fmt: skip
    return bad, inside


# sub-polygons of more than this many vertices are tested run by run (``_bad_runs``), and
# so are the others of the same pass of ``_all_tables``
_RUN_MIN = 64
# positions per run: a run's table column holds its _RUN + 1 vertices, the edges between them
_RUN = 8


def _bad_runs(
    seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_bad_rows` of large sub-polygons, run by run: a run of the sequence (see
    :class:`RunBoxes`) whose bounding box lies strictly outside one side of the triangle
    (exact sign at the box's corner nearest to that side) holds no vertex in the closed
    triangle and no edge that meets it; only the other runs that overlap lo .. hi are tested
    (their positions outside lo .. hi count as lo or hi)."""
    boxes = seqs.run_boxes()
    n = len(lo)
    start = boxes.start_of[lo]
    first = (lo - start) // _RUN
    runs = (hi - 1 - start) // _RUN - first + 1
    item = np.repeat(np.arange(n, dtype=np.int64), runs)
    within = ragged_index(first, runs)
    run = within + boxes.first_run[lo][item]
    a, b, cc = hi[item], lo[item], c[item]
    sx, sy = seqs.sx, seqs.sy
    extent_x, extent_y = seqs.extent_x[cc], seqs.extent_y[cc]
    # the three sides as rows: the inside is left of a -> b, b -> c and c -> a
    u, v = np.stack([a, b, cc]), np.stack([b, cc, a])
    ux, uy = sx[u], sy[u]
    dx, dy = sx[v] - ux, sy[v] - uy
    # orient(u, v, p) = dx (py - uy) - dy (px - ux) is largest at this corner of the box
    px = np.where(dy > 0, boxes.x0[run], boxes.x1[run])
    py = np.where(dx > 0, boxes.y1[run], boxes.y0[run])
    py -= uy
    px -= ux
    det = dx * py
    det -= dy * px
    if seqs.exact:
        keep = (det >= 0).all(axis=0)
    else:
        # a run leaves only where it is surely outside a side: a product that overflows
        # (nan) keeps it for the tables, which decide such signs exactly
        keep = ~(det < -row_bound(dx, dy, extent_x, extent_y)).any(axis=0)
    bad = np.zeros(n, dtype=bool)
    inside = np.full(n, -1, dtype=np.int64)
    tested = np.flatnonzero(keep)
    if len(tested):
        owner = item[tested]
        offset = start[owner] + within[tested] * _RUN - lo[owner]
        column_bad, found = _bad_rows(
            sx, sy, lo[owner], hi[owner], c[owner], extent_x[tested], extent_y[tested],
            seqs.twin, _RUN + 1, seqs.exact, offset,
        )  # fmt: skip
        bad[owner[column_bad]] = True
        hit = found >= 0
        inside[owner[hit]] = found[hit]
    return bad, inside


# candidates tested per node and round after a node's first candidate failed
_SPAN = 4
# ... and in sub-polygons tested run by run, where a round costs more than a facing test
_SPAN_LARGE = 12
# rounds of closest-first tests (1, 2, 4, ... candidates at once) of rule "elevation" before
# a node tests all its candidates
_ELEVATION_ROUNDS = 7
# rule "elevation": a node of more than twice this many candidates takes about this many of
# its closest first
_NEAR_CANDIDATES = 16
# ... and a node left undecided by them takes this many times as many next
_WIDER = 8
# largest-angle-first tries of rule "delaunay", one candidate per node at a time...
_DELAUNAY_TRIES = 8
# ... then each node's next this many of its candidates left at once, twice as many each time
_DELAUNAY_WIDTH = 8
# rounds of at least this many nodes test first candidates with _facing_ear
_EAR_ROUND = 1024
# candidates tested per node in rounds of fewer nodes, its first one included
_SMALL_ROUND_SPAN = 16
# candidates tested at once by a node already a whole span back from its first
_REACH = 48


def _first_correct(seqs: Sequences, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One round of rule "first" for the open nodes ``state``.

    A node tests a span of its candidates in order for conditions 1 and 4 and against its
    recorded blocker; the first that passes goes on to the tables. In rounds of many nodes, a
    node tests its first candidate (hi - 1) alone with the cheaper ear test, and where that
    fails, or where the first candidate failed in an earlier round, up to ``_SPAN``
    candidates (``_SPAN_LARGE`` in large sub-polygons) in two passes (:func:`_span_passing`),
    in the same round. In rounds of fewer nodes, whose cost is mostly their fixed numpy calls,
    a node tests up to ``_SMALL_ROUND_SPAN`` candidates at once. Where some sequence is long,
    a node already a whole span back from its first candidate tests ``_REACH`` at once: the
    deepest trees' nodes walk long stretches of failing candidates, a round per span, and
    their recorded blockers (a vertex inside, or an edge across) rule most of them out
    without a table. Returns per node whether its candidate ``apex`` is correct, the apex
    (or the next candidate to test) and the blocker to keep.
    """
    lo, hi, cand, block = state[_LO], state[_HI], state[_CAND], state[_BLOCK]
    n = len(lo)
    fresh = cand == hi - 1
    # nodes at their first candidate (no blocker yet) come after the ones that try again
    # (see _next_state)
    r = n - int(np.count_nonzero(fresh))
    if n >= _EAR_ROUND and fresh[r:].all():
        passed = np.zeros(n, dtype=bool)
        apex = cand.copy()
        passed[r:] = _facing_ear(seqs, lo[r:], hi[r:])
        apex[r:] -= ~passed[r:]
        going = np.flatnonzero(~passed & (apex > lo))
        large = hi[going] - lo[going] > _RUN_MIN
        span = np.where(large, _SPAN_LARGE, _SPAN)
        if seqs.any_long:
            # nodes already a whole span back from their first candidate reach further
            span = np.where(cand[going] < hi[going] - 1 - span, _REACH, span)
        span = np.minimum(apex[going] - lo[going], span)
        hit, found = _span_passing(seqs, lo, hi, block, going, apex[going], span)
        passed[going] = hit
        apex[going] = np.where(hit, found, apex[going] - span)
    else:
        # few nodes: the round costs mostly its fixed numpy calls, a longer span little
        span = np.minimum(cand - lo, _SMALL_ROUND_SPAN)
        if seqs.any_long:
            far = np.flatnonzero(cand < hi - 1 - _SMALL_ROUND_SPAN)
            span[far] = np.minimum(cand[far] - lo[far], _REACH)
        passed, found = _first_passing(seqs, lo, hi, block, np.arange(n), cand, span)
        apex = np.where(passed, found, cand - span)
    correct = np.zeros(n, dtype=bool)
    blocker = block.copy()
    _tables_of(seqs, lo, hi, np.flatnonzero(passed), apex, correct, blocker)
    going = np.flatnonzero(~correct & (apex > lo + 1))
    if len(going):
        apex[going] = _past_runs(seqs, lo[going], hi[going], apex[going])
    return correct, apex, blocker


def _tables_of(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    nodes: np.ndarray,
    apex: np.ndarray,
    correct: np.ndarray,
    blocker: np.ndarray,
) -> None:
    """The tables (conditions 2 and 3) of the ``nodes``' candidates ``apex``, which pass
    conditions 1 and 4: ``correct`` where they pass; where they fail, ``apex`` moves to the
    next candidate and a vertex found strictly inside becomes the ``blocker`` (or, where
    none is, an edge found across, coded -2 - its first position)."""
    small = hi[nodes] - lo[nodes] == 2
    correct[nodes[small]] = True
    table = nodes[~small]
    if len(table):
        across = np.full(len(table), -1, dtype=np.int64) if seqs.any_long else None
        least = np.full(len(table), -1, dtype=np.int64)
        bad, inside = _tables(seqs, lo[table], hi[table], apex[table], True, across, least)
        took = np.flatnonzero(least >= 0)
        if len(took):
            # a failing ear's apex: the vertex in it of least angle at s_lo (conditions 1
            # and 4 checked here; 2 and 3 hold, see _least_angle)
            node = table[took]
            took = took[_facing(seqs, lo[node], hi[node], least[took])]
            apex[table[took]] = least[took]
            bad[took] = False
        correct[table[~bad]] = True
        found = inside >= 0
        blocker[table[found]] = inside[found]
        if across is not None:
            # no position inside, an edge across: that edge, coded -2 - its first position
            edge = bad & ~found & (across >= 0)
            blocker[table[edge]] = -2 - across[edge]
        # a failed candidate: the next test starts below it
        apex[table[bad]] -= 1


def _span_passing(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    block: np.ndarray,
    nodes: np.ndarray,
    top: np.ndarray,
    count: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_first_passing` of the ``nodes`` (nodes trying again) in two passes: the next
    candidate alone, then the rest of the span where that fails (the next candidate passes
    for over half of them, in small and large sub-polygons alike)."""
    passed, apex = _first_passing(seqs, lo, hi, block, nodes, top, np.ones_like(count))
    more = np.flatnonzero(~passed & (count > 1))
    if len(more):
        hit, found = _first_passing(
            seqs, lo, hi, block, nodes[more], top[more] - 1, count[more] - 1
        )
        passed[more[hit]] = True
        apex[more[hit]] = found[hit]
    return passed, apex


def _first_passing(
    seqs: Sequences,
    lo: np.ndarray,
    hi: np.ndarray,
    block: np.ndarray,
    nodes: np.ndarray,
    top: np.ndarray,
    count: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Per node of ``nodes``: the first of its candidates ``top``, ``top`` - 1, ... (``count``
    of them) that passes conditions 1 and 4 and does not hold the node's recorded blocker
    (if any) strictly inside its triangle, or its recorded edge across the side c -> s_hi;
    (whether one does, that candidate)."""
    c = np.repeat(top, count)
    single = len(c) == len(nodes)
    owner = nodes
    if not single:
        owner = np.repeat(nodes, count)
        c -= ragged_index(np.zeros(len(nodes), dtype=np.int64), count)
    lo_o, hi_o = lo[owner], hi[owner]
    ok = _facing(seqs, lo_o, hi_o, c)
    tested = np.flatnonzero(ok & (hi_o - lo_o > 2) & (block[owner] >= 0))
    if len(tested):
        inside = _strictly_inside(seqs, hi_o[tested], lo_o[tested], c[tested], block[owner[tested]])
        ok[tested[inside]] = False
    # a recorded edge (coded -2 - its first position e) across the side c -> s_hi
    crossed = np.flatnonzero(ok & (block[owner] <= -2)) if seqs.any_long else ()
    if len(crossed):
        e = -2 - block[owner[crossed]]
        ok[crossed[_cross(seqs, c[crossed], hi_o[crossed], e, e + 1)]] = False
    if single:
        return ok, c
    index = np.arange(len(c))
    first = np.minimum.reduceat(np.where(ok, index, len(c)), np.cumsum(count) - count)
    hit = first < len(c)
    return hit, c[np.minimum(first, len(c) - 1)]


def _strictly_inside(
    seqs: Sequences, a: np.ndarray, b: np.ndarray, c: np.ndarray, p: np.ndarray
) -> np.ndarray:
    """Position ``p`` lies strictly inside the counter-clockwise triangle (a, b, c) (exact)."""
    # a blocker is often the next candidate itself (a corner: not inside), left out before
    # the orientations, whose zeros would take the exact path
    inside = np.zeros(len(p), dtype=bool)
    t = np.flatnonzero(p != c)
    b = b[t]
    points = np.take(seqs.xy, np.stack([a[t], b, c[t], p[t]]), axis=0)
    (ax, bx, cx, px), (ay, by, cy, py) = points[..., 0], points[..., 1]
    inside[t] = _in_triangle(ax, ay, bx, by, cx, cy, px, py, seqs.table[b, _BOUND], seqs.exact)[1]
    return inside


def _bad_rows(
    sx: np.ndarray,
    sy: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    c: np.ndarray,
    extent_x: np.ndarray,
    extent_y: np.ndarray,
    twin: np.ndarray,
    width: int,
    exact: bool,
    offset: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Conditions 2 and 3 of the correct triangle for items of one padded width, and per
    item a position strictly inside the triangle, or -1.

    Tables are (width, items): column i holds the positions lo_i .. hi_i, padded with hi_i,
    so that per-item values broadcast along long contiguous rows. With ``offset``, column i
    holds only the positions from lo_i + offset_i on (one run of the sub-polygon's boundary:
    its vertices and the edges between them).
    """
    n = len(lo)
    first = lo if offset is None else lo + offset
    pos = np.arange(width, dtype=np.int64)[:, None] + first
    np.minimum(pos, hi, out=pos)
    if offset is not None:
        np.maximum(pos, lo, out=pos)
    px, py = sx[pos], sy[pos]
    ax, ay, bx, by, cx, cy = sx[hi], sy[hi], sx[lo], sy[lo], sx[c], sy[c]
    last = hi - lo
    ccol = c - lo

    def bound(ux: np.ndarray, uy: np.ndarray) -> np.ndarray | None:
        return None if exact else row_bound(ux, uy, extent_x, extent_y)

    # entries known to be exactly zero: p at position lo (b), hi and the padding (a), c, and
    # the other occurrence (twin) of a corner inside the range: p is then a or b itself
    def twin_col(position: np.ndarray) -> np.ndarray:
        t = twin[position]
        return np.where((t > lo) & (t < hi), t - lo, -1)

    ta, tb, tc = twin_col(hi), twin_col(lo), twin_col(c)
    if offset is None:
        # how many there are, so that tables without any other zero skip the search
        pad_count = int((width - last).sum())
        n_ta, n_tb, n_tc = int((ta >= 0).sum()), int((tb >= 0).sum()), int((tc >= 0).sum())
        known_ab = n + pad_count + n_ta + n_tb
        known_ca = n + pad_count + n_ta + n_tc
        known_bc = 2 * n + n_tb + n_tc
        zero_row = np.zeros(n, dtype=np.int64)
    else:
        # runs: rows count from lo_i + offset_i (the rows before lo_i hold lo_i)
        last = last - offset
        ccol = ccol - offset
        ta, tb, tc = (np.where(t >= 0, t - offset, -1) for t in (ta, tb, tc))
        zero_row = -offset
        at_b = int(np.clip(zero_row + 1, 0, width).sum())
        at_a = int(np.clip(width - last, 0, width).sum())
        n_ta, n_tb, n_tc, n_c = (int(((t >= 0) & (t < width)).sum()) for t in (ta, tb, tc, ccol))
        known_ab = at_b + at_a + n_ta + n_tb
        known_ca = n_c + at_a + n_ta + n_tc
        known_bc = at_b + n_c + n_tb + n_tc
    dxa, dya = px - ax, py - ay
    pos_ab, _, _ = orient_rows(
        ax, ay, bx, by, px, py, dxa, dya, bound(bx - ax, by - ay), known_ab,
        lambda k, r: (k <= zero_row[r]) | (k >= last[r]) | (k == ta[r]) | (k == tb[r]),
    )  # fmt: skip
    # orient(a, c, p) = -orient(c, a, p), sharing p - a with the line a -> b
    _, pos_ca, zero_ca = orient_rows(
        ax, ay, cx, cy, px, py, dxa, dya, bound(cx - ax, cy - ay), known_ca,
        lambda k, r: (k == ccol[r]) | (k >= last[r]) | (k == ta[r]) | (k == tc[r]),
    )  # fmt: skip
    pos_bc, _, zero_bc = orient_rows(
        bx, by, cx, cy, px, py, px - bx, py - by, bound(cx - bx, cy - by), known_bc,
        lambda k, r: (k <= zero_row[r]) | (k == ccol[r]) | (k == tb[r]) | (k == tc[r]),
    )  # fmt: skip
    # a vertex strictly inside: the edges at it meet the open triangle
    inside = pos_ab & pos_bc
    inside &= pos_ca
    bad = inside.any(axis=0)
    found = np.full(n, -1, dtype=np.int64)
    if bad.any():
        found[bad] = first[bad] + inside[:, bad].argmax(axis=0)
    # condition 3: a vertex in the relative interior of a new side (the known zeros are the
    # corners themselves)
    for (k, r), ux, uy in ((zero_bc, bx, by), (zero_ca, ax, ay)):
        if len(r):
            between = strictly_between(px[k, r], py[k, r], ux[r], uy[r], cx[r], cy[r])
            bad[r[between]] = True
    # condition 2 where no vertex is inside: an edge with an end strictly inside every side
    # that passes no corner outside (the padding adds only point edges at a, where f_ab is 0
    # at both ends: never inward)
    inward = pos_ab[:-1] | pos_ab[1:]
    inward &= pos_bc[:-1] | pos_bc[1:]
    inward &= pos_ca[:-1] | pos_ca[1:]
    inward &= ~bad
    flat = np.flatnonzero(inward)
    if len(flat):
        k, r = np.divmod(flat, n)
        ex0, ey0, ex1, ey1 = px[k, r], py[k, r], px[k + 1, r], py[k + 1, r]
        m = len(r)
        g = orient_items(
            np.tile(ex0, 3), np.tile(ey0, 3), np.tile(ex1, 3), np.tile(ey1, 3),
            np.concatenate([ax[r], bx[r], cx[r]]), np.concatenate([ay[r], by[r], cy[r]]),
            exact,
        ).reshape(3, m)  # fmt: skip
        lowest, highest = g.min(axis=0), g.max(axis=0)
        degenerate = (ex0 == ex1) & (ey0 == ey1)
        bad[r[((lowest < 0) & (highest > 0)) | degenerate]] = True
    return bad, found


def _elevation_apex(
    seqs: Sequences, sz: np.ndarray, state: np.ndarray, top_z: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rule "elevation" for the open nodes ``state``: per node whether it has a correct
    apex, and the one ``_choose_elevation`` picks among all of them (or -1).

    The candidate whose elevation is closest to the base's mean (the first in candidate order
    among equally close ones) is tested first: where it is correct and every other candidate
    that passes conditions 1 and 4 is surely farther or at the same elevation, it is the
    rule's choice; where it is not correct it drops out and the next closest is tried, up to
    in rounds of 1, 2, 4, ... closest candidates at once (``_ELEVATION_ROUNDS`` rounds).
    Nodes where the choice is not sure test all their candidates. In proven polygons a
    candidate takes the bent positions' tables and, as rule first's fans do, the test of the
    edges most likely to cross it (``_ELEVATION_CROSSINGS``): the closest elevation is often
    far across the sub-polygon, a triangle with two new sides.

    A node of many candidates takes only those whose elevation lies within a share of its
    candidates' spread of the closest: about ``_NEAR_CANDIDATES`` of them, from the spread
    alone, or the number its ``_BLOCK`` row holds (0: all of them). Where its choice among
    them is not sure to hold against all the others (each surely farther), it is undecided:
    the caller tries it again with ``_WIDER`` times as many (:func:`_wider`), or with all.
    ``top_z``: the largest |z| of ``sz``, which bounds the error of every candidate's
    distance. Returns found, apex and undecided per node.
    """
    lo, hi = state[_LO], state[_HI]
    n = len(lo)
    at_hi = state[_AT_HI] == 1
    v1 = np.where(at_hi, hi, lo)
    v2 = np.where(at_hi, lo, hi)
    z1, z2 = sz[v1], sz[v2]  # per node
    span = hi - lo - 1
    owner, c = _candidates(lo, hi)
    # per node a lower bound of |2 z - z1 - z2| (its float value less its error) of every
    # candidate left out (none: infinite)
    floor = np.full(n, np.inf)
    nearest = _nearest_count(state)
    wide = np.flatnonzero((span > 2 * nearest) & (nearest > 0))
    if len(wide):
        approx = _elevation_approx(np.take(sz, c), np.take(z1, owner), np.take(z2, owner))
        first = (np.cumsum(span) - span)[wide]
        # each wide node's extremes: reductions over its own range, the gaps dropped
        cuts = np.column_stack([first, first + span[wide]]).ravel()
        padded = np.append(approx, 0.0)
        low = np.minimum.reduceat(padded, cuts)[::2]
        high = np.maximum.reduceat(padded, cuts)[::2]
        threshold = np.full(n, np.inf)
        threshold[wide] = low + (high - low) * (nearest[wide] / span[wide])
        near = approx <= threshold[owner]
        owner, c = owner[near], c[near]
        # the error bound of a candidate at the largest |z|: at least any candidate's
        bound = _elevation_error(top_z, z1[wide], z2[wide])
        # one step down: the float difference may round up
        floor[wide] = np.nextafter(threshold[wide] - bound, -np.inf)
    owner, c = _facing_candidates(seqs, lo, hi, (owner, c), corners=True)
    return _closest_correct(seqs, sz, lo, hi, owner, c, floor, v1, v2)


def _nearest_count(state: np.ndarray) -> np.ndarray:
    """Per open node of rule "elevation", the number of its nearest candidates it takes
    (0: all): ``_NEAR_CANDIDATES`` at first, then what its ``_BLOCK`` row holds."""
    return np.where(state[_BLOCK] < 0, _NEAR_CANDIDATES, state[_BLOCK])


def _wider(state: np.ndarray) -> np.ndarray:
    """Per open node of rule "elevation" left undecided (:func:`_elevation_apex`), the
    number of nearest candidates to take next: ``_WIDER`` times as many, or all (0) where
    that would be most of its candidates."""
    taken = _nearest_count(state) * _WIDER
    return np.where(2 * taken < state[_HI] - state[_LO] - 1, taken, 0)


def _within_corners(
    seqs: Sequences, lo: np.ndarray, hi: np.ndarray, owner: np.ndarray, c: np.ndarray
) -> np.ndarray:
    """Per candidate ``c`` of node ``owner`` (strictly left of its chord): not surely outside
    the sub-polygon's angle at a convex corner of the base. Where lo + 1 lies strictly left
    of the chord s_hi -> s_lo, a candidate strictly right of the edge lo -> lo + 1 has that
    edge strictly inside its triangle's angle at s_lo, so the edge meets the open triangle
    (condition 2); likewise the edge hi - 1 -> hi at s_hi (``shadows``' corner shadows, as
    sure float signs: a doubtful candidate is kept for the tables)."""
    keep = np.ones(len(c), dtype=bool)
    big = hi - lo > 2
    if not len(c) or not big.any():
        return keep
    x, y = seqs.sx, seqs.sy
    ax, ay, bx, by = x[hi], y[hi], x[lo], y[lo]
    for at_lo, nx, ny in ((True, x[lo + 1], y[lo + 1]), (False, x[hi - 1], y[hi - 1])):
        convex = big & (sure_signs(ax, ay, bx, by, nx, ny) > 0)
        at = np.flatnonzero(convex[owner])
        if not len(at):
            continue
        o, cx, cy = owner[at], x[c[at]], y[c[at]]
        if at_lo:  # the edge lo -> lo + 1
            signs = sure_signs(bx[o], by[o], nx[o], ny[o], cx, cy)
        else:  # the edge hi - 1 -> hi
            signs = sure_signs(nx[o], ny[o], ax[o], ay[o], cx, cy)
        keep[at[signs < 0]] = False
    return keep


def _closest_correct(
    seqs: Sequences,
    sz: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    owner: np.ndarray,
    c: np.ndarray,
    floor: np.ndarray,
    v1: np.ndarray,
    v2: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_elevation_apex` among the candidates ``c`` of nodes ``owner`` (in candidate
    order per node, each passing conditions 1 and 4); ``floor``: per node a bound below the
    distances of the candidates left out (infinite: none). Returns found, apex and, per node,
    whether its choice among these is not sure against those left out (undecided)."""
    n = len(lo)
    found = np.zeros(n, dtype=bool)
    apex = np.full(n, -1, dtype=np.int64)
    undecided = np.zeros(n, dtype=bool)
    if not len(c):
        undecided[:] = floor < np.inf
        return found, apex, undecided
    zc = sz[c]
    z1, z2 = sz[v1], sz[v2]  # per node
    approx, error = _elevation_distance(zc, z1[owner], z2[owner])
    # per node its candidates closest first (the first in candidate order among equally
    # close ones); rounds test each node's next 1, 2, 4, ... closest at once (a candidate
    # found not correct drops out), then all that are left
    order = _by_owner(owner, approx)
    owner, c, zc, approx, error = owner[order], c[order], zc[order], approx[order], error[order]
    alive = np.ones(len(c), dtype=bool)
    trying = np.ones(len(c), dtype=bool)
    known = np.full(n, -1, dtype=np.int64)  # per node a position inside a failed triangle
    take = 1
    for _ in range(_ELEVATION_ROUNDS):
        left = np.flatnonzero(alive & trying)
        if not len(left):
            break
        o = owner[left]
        starts, sizes, group, rank = _owner_runs(o)
        taken = np.flatnonzero(rank < take)
        t = left[taken]
        ok = _known_then_tables(
            seqs, lo, hi, owner[t], c[t], known,
            _ELEVATION_KNOWN, _ELEVATION_EVERY, _ELEVATION_CROSSINGS,
        )  # fmt: skip
        # per node the first correct one among those taken (its rank), or take
        first = np.full(len(starts), take, dtype=np.int64)
        np.minimum.at(first, group[taken[ok]], rank[taken[ok]])
        has = first < take
        pick = starts + np.minimum(first, sizes - 1)  # index into left
        a, e, z = approx[left], error[left], zc[left]
        # sure where every other candidate left after it is surely farther, or at the same
        # elevation (then after it in candidate order: the rule's tie-break picks it too),
        # or exactly as far on the other side of the mean and after it in candidate order
        # (terraced elevations: base corners on two levels, candidates on both), and those
        # left out are surely farther
        nodes = o[starts]
        limit = (a + e)[pick]
        z_pick = z[pick][group]
        farther = (rank <= first[group]) | (a - e > limit[group]) | (z == z_pick)
        position = c[left]
        later = position < position[pick][group]
        farther |= later & _mirrored(z, z_pick, z1[o], z2[o])
        sure = has & np.logical_and.reduceat(farther, starts) & (limit <= floor[nodes])
        found[nodes[sure]] = True
        apex[nodes[sure]] = c[left[pick[sure]]]
        alive[left[sure[group]]] = False
        # near-ties: every candidate left is tested; none correct: those taken drop out
        trying[left[(has & ~sure)[group]]] = False
        alive[t[~has[group[taken]]]] = False
        take *= 2
    # the other nodes: every candidate left (each passed conditions 1 and 4 above), back in
    # candidate order, then the rule's choice among the correct ones; a node with candidates
    # left out is decided again with all of them
    undecided = ~found & (floor < np.inf)
    rest = np.flatnonzero(alive & ~found[owner] & ~undecided[owner])
    rest = rest[np.argsort(order[rest])]
    owner, c = owner[rest], c[rest]
    good = _known_then_tables(
        seqs, lo, hi, owner, c, known, _ELEVATION_KNOWN, _ELEVATION_EVERY, _ELEVATION_CROSSINGS
    )
    if good.any():
        chosen = np.bincount(owner[good], minlength=n) > 0
        found[chosen] = True
        apex[chosen] = _choose_elevation(sz, owner[good], c[good], v1, v2)
    return found, apex, undecided


def _owner_runs(owner: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For items grouped by ``owner`` (each owner's items in one run): the runs' starts and
    sizes, and per item its run and its rank within the run."""
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    sizes = np.diff(np.r_[starts, len(owner)])
    group = np.repeat(np.arange(len(starts)), sizes)
    return starts, sizes, group, np.arange(len(owner)) - starts[group]


def _mirrored(zd: np.ndarray, zc: np.ndarray, z1: np.ndarray, z2: np.ndarray) -> np.ndarray:
    """Exactly zd + zc = z1 + z2 (so zd and zc are exactly as far from the mean of z1 and
    z2), where both float sums are exact (else False)."""
    left, right = zd + zc, z1 + z2
    return (left == right) & (sum_error(zd, zc, left) == 0) & (sum_error(z1, z2, right) == 0)


def _by_owner(owner: np.ndarray, key: np.ndarray) -> np.ndarray:
    """A stable order of items by ``owner`` (non-decreasing integers), then by ``key`` (>= 0)
    as far as one float sort key, the owner plus the key scaled into [0, 1/2], tells keys
    apart (a stable sort of one float key is several times faster than a lexsort of two):
    items of one owner whose keys differ by under about 2**-30 of the largest key keep their
    order, so callers take it as a guess and decide near-ties themselves."""
    scale = 2.0 * float(key.max(initial=0.0))
    combined = owner + (key / scale if 0 < scale < np.inf else np.zeros(len(key)))
    return np.argsort(combined, kind="stable")


def _delaunay_apex(seqs: Sequences, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rule "delaunay" for the open nodes ``state``: per node whether it has a correct apex,
    and the one ``rules.DelaunayRule.choose_in_plane`` picks among all of them (or -1).

    First for every node at once (:func:`_delaunay_guess`): the candidate seeing the base
    under the largest angle in float; where every other candidate is surely not better, and
    the guess passes conditions 1 and 4 and the tables, it is the rule's choice. The other
    nodes (near-cocircular candidates, a guess that fails) go to :func:`_delaunay_tries`."""
    lo, hi = state[_LO], state[_HI]
    n = len(lo)
    span = hi - lo - 1
    # a node of one candidate has nothing to compare
    guess = hi - 1
    clear = np.ones(n, dtype=bool)
    more = np.flatnonzero(span > 1)
    if len(more):
        # nodes by span, so that each table's width is about its nodes' own
        sizes = span[more]
        order = np.argsort(sizes, kind="stable")
        more, sizes = more[order], sizes[order]
        total = len(more)
        first = 0
        while first < total:
            # as many nodes as fit a table of the widest of them
            last = min(first + max(_GUESS_CHUNK // int(sizes[first]), 1), total)
            while True:
                width = int(sizes[last - 1])
                fits = min(first + max(_GUESS_CHUNK // width, 1), total)
                if fits >= last:
                    break
                last = fits
            part = more[first:last]
            guess[part], clear[part] = _delaunay_guess(seqs, lo[part], hi[part], width)
            first = last
    found = np.zeros(n, dtype=bool)
    nodes = np.flatnonzero(clear)
    passed = _facing(seqs, lo[nodes], hi[nodes], guess[nodes])
    tested = nodes[passed]
    # a sure guess in a proven polygon needs no table: its circle holds no vertex of the
    # sub-polygon, so the only way it can be wrong is an edge across both new sides. The
    # edges most likely to cross are looked for (those at a bridge end at a base corner,
    # of the islands near the triangle and of the chain around the apex: on concave
    # polygons, long edges of spikes). A crossing missed leaves a tree that cannot complete,
    # which is mended or built again with every table (see build_trees)
    proven = seqs.proven[lo[tested]]
    sure, checked = tested[proven], tested[~proven]
    sure = sure[~_edge_across_sure(seqs, lo[sure], hi[sure], guess[sure])]
    good = np.concatenate(
        [sure, checked[_pass_tables(seqs, lo[checked], hi[checked], guess[checked])]]
    )
    found[good] = True
    apex = np.full(n, -1, dtype=np.int64)
    apex[good] = guess[good]
    rest = np.flatnonzero(~found)
    if len(rest):
        found[rest], apex[rest] = _delaunay_tries(seqs, state[:, rest])
    return found, apex


def _edge_across_sure(seqs: Sequences, lo: np.ndarray, hi: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Per sure guess ``c`` of rule "delaunay" (no vertex in its triangle but corners) in a
    sub-polygon of more than ``_RUN_MIN`` positions: an edge found across it
    (:func:`_bridge_at_corner`, :func:`_edges_across`)."""
    bad = np.zeros(len(c), dtype=bool)
    large = np.flatnonzero(hi - lo > _RUN_MIN)
    if len(large):
        lo, hi, c = lo[large], hi[large], c[large]
        corners = np.take(seqs.xy, np.stack([hi, lo, c]), axis=0)
        bad[large] = _bridge_at_corner(seqs, lo, hi, c) | _edges_across(seqs, lo, hi, c, corners)
    return bad


# rules "delaunay" and "elevation" test their candidates against every position in
# sub-polygons of more than this many positions, also in proven polygons: the candidates
# they try are often wide triangles that an edge crosses with no vertex inside, which the
# bent positions miss (on 1,000 concave polygons of 260-600 vertices with z, rule elevation
# mended 1,025 nodes, or built 948 of 1,000 trees twice), and whose many bent positions
# cost those tables more than the run tables
_DELAUNAY_EVERY = _RUN_MIN
# rule "elevation" in proven polygons: sub-polygons of more than this many positions test
# every position (None: none; the bent positions' tables with ``_ELEVATION_CROSSINGS`` leave
# few trees to mend), and those of more than _ELEVATION_KNOWN test a base's known position first
_ELEVATION_EVERY: int | None = None
_ELEVATION_KNOWN = _RUN_MIN
# ... and its candidates are tested against the edges most likely to cross them (_tables)
_ELEVATION_CROSSINGS = True
# table entries per call of :func:`_delaunay_guess`
_GUESS_CHUNK = 1 << 14


def _delaunay_guess(
    seqs: Sequences, lo: np.ndarray, hi: np.ndarray, width: int
) -> tuple[np.ndarray, np.ndarray]:
    """Per node of the sub-polygons [lo, hi] (at most ``width`` candidates each): the
    candidate c seeing the base under the largest angle in float (the first in candidate
    order among equal values), and whether every other candidate d is surely not better: d
    strictly outside the circle through the base and c, or not strictly left of the base
    (float values beyond their error bounds), or at a corner of the base, or at c's point
    and after it in candidate order. Tables are (candidates, nodes), padded with lo + 1.
    """
    m = len(lo)
    # points as complex numbers: one gather brings both coordinates (the nodes lie all over
    # the sequences, so each gather is mostly cache misses)
    sxy = seqs.xy.view(np.complex128).ravel()
    # columns are nodes: every operation runs along a row of all nodes
    k = np.arange(width, dtype=np.int64)[:, None]
    pos = (hi - 1) - k
    np.maximum(pos, lo + 1, out=pos)
    # base a = s_hi -> b = s_lo; per candidate d: D = d - a, E = D . (d - b), the cross
    # product B x D (> 0: d strictly left); the circle through a, b and d has its centre at
    # E / (B x D) times half the base's normal, so the smaller that key, the larger the angle
    a, b = sxy[hi], sxy[lo]
    ax, ay = a.real, a.imag
    bx, by = b.real - ax, b.imag - ay
    d = np.take(sxy, pos)
    dx = np.subtract(d.real, ax)
    dy = np.subtract(d.imag, ay)
    e = dx - bx
    e *= dx
    f = dy - by
    f *= dy
    e += f
    cross = bx * dy
    cross -= by * dx
    with np.errstate(divide="ignore", invalid="ignore"):
        key = e / cross
    # a nan key (overflow) leaves its node to the tries: its values fail every bound below
    np.copyto(key, np.inf, where=cross <= 0)
    # the first row at the lowest key (numpy's argmin along the rows is slow on few rows)
    if width >= 16:
        head = key.argmin(axis=0)
    else:
        head = np.where(key == key.min(axis=0), k, width).min(axis=0)
    rows = np.arange(m, dtype=np.int64)
    lost = head >= width
    head[lost] = 0
    guess = pos[head, rows]
    # every other candidate surely not better: (B x C) E_d - E_c (B x D) > 0 (d strictly
    # outside the circle through a, b and c) beyond its error bound, or B x D < 0 beyond its
    # bound; with X, Y the sequence's extents, |D|, |B|, |d - b| <= (X, Y) per axis, so
    # |E| <= 2 (X^2 + Y^2) and |B x D| <= 2 X Y, and each float value is within a few
    # roundings of those magnitudes (16 eps and 128 eps cover them)
    cross_bound, circle_bound = seqs.circle_bounds_at(lo)
    value = cross[head, rows] * e
    value -= e[head, rows] * cross
    clear = value > circle_bound
    clear |= cross < -cross_bound
    clear[head, rows] = True
    sure = ~lost
    # the padding repeats lo + 1: its entries are that candidate's, and the guess's own
    # (where the guess is lo + 1) pass as the guess itself does
    np.logical_not(clear, out=clear)
    if clear.any():
        col, r = np.nonzero(clear)
        p = pos[col, r]
        px, py = seqs.sx[p], seqs.sy[p]
        g = guess[r]
        at_a = (px == ax[r]) & (py == ay[r])
        at_b = (px == b.real[r]) & (py == b.imag[r])
        fine = at_a | at_b
        fine |= (px == seqs.sx[g]) & (py == seqs.sy[g]) & (p <= g)
        sure[r[~fine]] = False
    return guess, sure


def _delaunay_tries(seqs: Sequences, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_delaunay_apex` of nodes whose first guess does not decide.

    The candidates that pass conditions 1 and 4 are tried in order of their circle's centre
    offset along the base's normal (in float: largest angle first; ties in candidate order),
    one per node and try. A candidate found correct becomes the node's best, and every
    untried candidate that is not better (exact in-circle with the tie rule of
    ``predicates.cocircular_sign``: outside its circle, or its point later in candidate
    order) drops out. The best left when none remains is the best of all correct candidates
    in that order, whatever the order of the tries: the rule's choice. After
    ``_DELAUNAY_TRIES`` tries a node tests its next ``_DELAUNAY_WIDTH`` candidates left at
    once, then twice as many each time (a correct one found drops most of the others). In
    sub-polygons of more than ``_DELAUNAY_EVERY`` positions every position is tested, even if
    proven: there these candidates are mostly wide triangles behind a spike, which edges
    cross with no vertex inside (missed by :func:`_bent_in_triangle`, their trees would often
    need mending), and whose many bent positions cost that more than the run tables. In smaller
    proven ones the tables are those of :func:`_bent_in_triangle`: a candidate passed
    wrongly is chosen only if it is the best of those passed, and then its tree cannot
    complete (it is mended or built again with every table, see :func:`build_trees`).
    """
    lo, hi = state[_LO], state[_HI]
    n = len(lo)
    found = np.zeros(n, dtype=bool)
    apex = np.full(n, -1, dtype=np.int64)
    owner, c = _facing_candidates(seqs, lo, hi, corners=True)
    if not len(c):
        return found, apex
    sx, sy = seqs.sx, seqs.sy
    # base a = s_hi -> b = s_lo; the candidates lie on its left
    ax, ay, bx, by = sx[hi], sy[hi], sx[lo], sy[lo]
    key = _centre_offset(ax[owner], ay[owner], bx[owner], by[owner], sx[c], sy[c])
    # by node, then key; a stable sort keeps candidate order among equal keys
    order = np.lexsort((key, owner))
    owner, c = owner[order], c[order]
    alive = np.ones(len(c), dtype=bool)
    tested = np.zeros(len(c), dtype=bool)
    best = np.full(n, -1, dtype=np.int64)
    blocker = np.full(n, -1, dtype=np.int64)  # per node a position inside a failed triangle
    tries = 0
    width = _DELAUNAY_WIDTH
    while True:
        live = np.flatnonzero(alive)
        if tries >= _DELAUNAY_TRIES and len(live):
            untested = live[~tested[live]]
            if len(untested):
                # each node's next few (a correct one found drops most of the others)
                *_, rank = _owner_runs(owner[untested])
                untested = untested[rank < width]
                width *= 2
                t = owner[untested]
                good = _known_then_tables(
                    seqs, lo, hi, t, c[untested], blocker, _DELAUNAY_EVERY, _DELAUNAY_EVERY
                )
                tested[untested] = True
                alive[untested[~good]] = False
                live = live[alive[live]]
        if not len(live):
            break
        tries += 1
        live_owner = owner[live]
        head = live[np.r_[True, live_owner[1:] != live_owner[:-1]]]
        test = head[~tested[head]]
        if len(test):
            t = owner[test]
            good = _known_then_tables(
                seqs, lo, hi, t, c[test], blocker, _DELAUNAY_EVERY, _DELAUNAY_EVERY
            )
            tested[test] = True
            alive[test[~good]] = False
        better = head[alive[head]]
        if not len(better):
            continue
        nodes = owner[better]
        best[nodes] = c[better]
        alive[better] = False
        changed = np.zeros(n, dtype=bool)
        changed[nodes] = True
        rest = np.flatnonzero(alive)
        rest = rest[changed[owner[rest]]]
        if len(rest):
            o = owner[rest]
            b = best[o]
            d = c[rest]
            inside = incircle_sos_many(ax[o], ay[o], bx[o], by[o], sx[b], sy[b], sx[d], sy[d])
            keep = (inside > 0) | ((inside == 0) & (d > b))
            alive[rest[~keep]] = False
    found = best >= 0
    return found, best


def _centre_offset(
    ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray, cx: np.ndarray, cy: np.ndarray
) -> np.ndarray:
    """Per candidate c left of the base a -> b: the offset of the centre of the circle
    through a, b and c along the base's left normal, in float (smaller: c sees the base
    under a larger angle); inf where c is not clearly on the left. Only an order of tries."""
    mx, my = 0.5 * (ax + bx), 0.5 * (ay + by)
    ux, uy = cx - mx, cy - my
    toward = ux * (ay - by) + uy * (bx - ax)
    half2 = 0.25 * ((bx - ax) ** 2 + (by - ay) ** 2)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        key = np.where(toward > 0, (ux * ux + uy * uy - half2) / toward, np.inf)
    key[np.isnan(key)] = np.inf
    return key


def _elevation_distance(
    zc: np.ndarray, z1: np.ndarray, z2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Twice the elevation rule's distance of an apex at ``zc`` from the mean of ``z1`` and
    ``z2``, in floats (:func:`_elevation_approx`), and a bound on its rounding error."""
    return _elevation_approx(zc, z1, z2), _elevation_error(zc, z1, z2)


def _elevation_approx(zc: np.ndarray, z1: np.ndarray, z2: np.ndarray) -> np.ndarray:
    """|2 zc - z1 - z2| in floats, in that order of operations, in one new array of
    ``zc``'s shape (the near-first filter takes it for every candidate of every node,
    without the error bound)."""
    approx = zc * 2.0
    approx -= z1
    approx -= z2
    return np.abs(approx, out=approx)


def _elevation_error(zc: np.ndarray | float, z1: np.ndarray, z2: np.ndarray) -> np.ndarray:
    """A bound on the rounding error of :func:`_elevation_approx`."""
    return 8.0 * 2.0**-53 * (2.0 * np.abs(zc) + np.abs(z1) + np.abs(z2)) + 1e-300


def _choose_elevation(
    sz: np.ndarray, owner: np.ndarray, cand: np.ndarray, v1: np.ndarray, v2: np.ndarray
) -> np.ndarray:
    """``rules.ElevationRule.choose`` per owner: ``cand`` grouped by owner in candidate order;
    ``v1``, ``v2`` per owner. Returns the chosen position per owner."""
    starts, _, group, _ = _owner_runs(owner)
    z1, z2 = sz[v1][owner[starts]], sz[v2][owner[starts]]
    zc = sz[cand]
    approx, error = _elevation_distance(zc, z1[group], z2[group])
    top = np.minimum.reduceat(approx + error, starts)
    close = approx - error <= top[group]
    n = len(cand)
    first_close = np.minimum.reduceat(np.where(close, np.arange(n), n), starts)
    zmin = np.minimum.reduceat(np.where(close, zc, np.inf), starts)
    zmax = np.maximum.reduceat(np.where(close, zc, -np.inf), starts)
    chosen = cand[first_close]
    # near-ties between different z values: decided exactly as the rule does
    for g in np.flatnonzero(zmin != zmax).tolist():
        members = np.flatnonzero(close & (group == g))
        target = Fraction(float(z1[g])) + Fraction(float(z2[g]))
        exact = [abs(2 * Fraction(float(zc[i])) - target) for i in members]
        chosen[g] = cand[members[exact.index(min(exact))]]
    return chosen


def _extents(sx: np.ndarray, sy: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sequence: max - min of x and of y (bounds every coordinate difference in it)."""
    extent_x = np.maximum.reduceat(sx, starts) - np.minimum.reduceat(sx, starts)
    extent_y = np.maximum.reduceat(sy, starts) - np.minimum.reduceat(sy, starts)
    return extent_x, extent_y


# rows of the open-node state (one column per node): sub-polygon [lo, hi], next candidate,
# parent (pre-order index), depth, side, output row of the node, V1 at hi (1) or at lo (0),
# output row of its sequence's first triangle, sequence, a position to test first (or -1;
# under rule "first" -2 - e for an edge e -> e + 1 found across a side, see _tables_of; under
# rule "elevation" the number of nearest candidates to take, see _wider);
# an emitted node's first _RECORD rows (its apex in _CAND) are its output record, and its
# rows up to _AT_HI all that its emission reads
_LO, _HI, _CAND, _PARENT, _DEPTH, _SIDE, _ROW, _AT_HI, _FIRST, _SEQ, _BLOCK = range(11)
_RECORD = 6


def _next_state(
    state: np.ndarray,
    emit: np.ndarray,
    done: np.ndarray,
    apex: np.ndarray,
    retry: np.ndarray,
    blocker: np.ndarray,
) -> np.ndarray:
    """The open nodes of the next round: the nodes ``retry`` (columns of ``state``) with
    their next candidate ``apex`` and ``blocker``, then below the nodes ``emit`` (their
    columns ``done``) with their ``apex`` the left children (base V1 V3), then the right
    children (base V2 V3), where they have a triangle.

    With V1 at hi the left child is the upper part [apex, hi], else the lower part [lo, apex];
    the left subtree comes first in pre-order, the right child's row is after it.
    """
    lo, hi = done[_LO], done[_HI]
    a = apex[emit]
    at_hi = done[_AT_HI] == 1
    left_lo = np.where(at_hi, a, lo)
    left_hi = np.where(at_hi, hi, a)
    right_lo = np.where(at_hi, lo, a)
    right_hi = np.where(at_hi, a, hi)
    left = np.flatnonzero(left_hi - left_lo > 1)
    right = np.flatnonzero(right_hi - right_lo > 1)
    rows = np.concatenate([retry, emit[left], emit[right]])
    out = np.take(state, rows, axis=1)
    r = len(retry)
    out[_CAND, :r] = apex[retry]
    out[_BLOCK, :r] = blocker[retry]
    children = out[:, r:]
    children[_PARENT] = children[_ROW] - children[_FIRST]
    children[_DEPTH] += 1
    children[_BLOCK] = -1
    lefts, rights = out[:, r : r + len(left)], out[:, r + len(left) :]
    lefts[_LO] = left_lo[left]
    lefts[_HI] = left_hi[left]
    lefts[_ROW] += 1
    lefts[_SIDE] = 1
    rights[_LO] = right_lo[right]
    rights[_HI] = right_hi[right]
    rights[_ROW] += (left_hi - left_lo)[right]
    rights[_SIDE] = 2
    rights[_AT_HI] ^= 1
    children[_CAND] = children[_HI] - 1
    return out


def build_trees(
    ids: np.ndarray,
    twin: np.ndarray,
    sx: np.ndarray,
    sy: np.ndarray,
    sz: np.ndarray,
    seq_start: np.ndarray,
    seq_len: np.ndarray,
    mirrored: np.ndarray,
    rule: str,
    proven: np.ndarray | None = None,
    alive: Callable[[], None] | None = None,
) -> Trees:
    """BSP trees of sequences laid out with their closing repeat (length ``seq_len + 1``) at
    ``seq_start``; ``ids`` are the output vertex indices of every position, ``twin`` the other
    position of the same vertex or -1; ``rule``: "first", "elevation" or "delaunay" (the
    apex rule); ``proven``: per sequence, its polygon is proven valid
    (``validity.proven_valid``), which lets its candidates skip most tables
    (:func:`_bent_in_triangle`; where a node of such a tree finds no candidate, the subtree
    of the wrong ancestor is built again in place with every table (:func:`_reopened`), and
    where that fails the polygon is marked ``again``, for the caller to build with every
    table, with the trees of other groups). ``alive``: called every round (it may raise to
    stop)."""
    count = len(seq_start)
    # a sample that is not grid-exact rules out the whole (cheap for float data)
    exact = grid_exact(sx[:1024], sy[:1024]) and grid_exact(sx, sy)
    seqs = Sequences.of(sx, sy, twin, seq_start, exact, proven)
    m = seq_len
    tri_count = np.maximum(m - 2, 0)
    tri_start = np.cumsum(tri_count) - tri_count
    total = int(tri_count.sum())
    # half the memory where positions and rows fit (always, for groups of usual size)
    small = max(len(sx), total) < 2**31
    record = np.zeros((total, _RECORD), dtype=np.int32 if small else np.int64)
    # one record as one item: numpy scatters those faster than rows of a 2-D array
    record_item = np.dtype((np.void, record.itemsize * _RECORD))
    records = record.view(record_item).reshape(total)
    ok = np.ones(count, dtype=bool)
    state = _roots(np.flatnonzero(m >= 3), seq_start, m, tri_start)
    top_z = float(np.abs(sz).max(initial=0.0)) if rule == "elevation" else 0.0
    # the rows of reopened nodes whose ranges take the shortcut again once they are emitted,
    # and reopenings per sequence
    waiting = np.zeros(0, dtype=np.int64)
    reopenings = np.zeros(count, dtype=np.int64)
    # rows are written as they are emitted; a sequence that fails is not read
    # sequences whose nodes stay in the rounds
    one_off = np.zeros(count, dtype=bool)
    while state.shape[1]:
        if alive is not None:
            alive()
        if rule == "first" and state.shape[1] < _ONE_BY_ONE and _few_positions(seqs, state):
            built = _one_by_one(seqs, state, record, one_off)
            if built.any():
                if len(waiting):
                    waiting = waiting[~np.isin(waiting, state[_ROW, built])]
                state = state[:, ~built]
                if not state.shape[1]:
                    break
        lo = state[_LO]
        if rule == "delaunay":
            found, apex = _delaunay_apex(seqs, state)
            failed = ~found
            # no node tries again: the rule tested all its candidates
            retry, blocker = np.zeros(0, dtype=np.int64), apex
        elif rule == "elevation":
            found, apex, undecided = _elevation_apex(seqs, sz, state, top_z)
            failed = ~found & ~undecided
            # a node undecided among its nearest candidates tries again with more of them
            retry = np.flatnonzero(undecided)
            blocker = np.zeros(len(apex), dtype=np.int64)
            blocker[retry] = _wider(state[:, retry])
        else:
            found, apex, blocker = _first_correct(seqs, state)
            failed = ~found & (apex <= lo)
            retry = np.flatnonzero(~found & ~failed)
        reopened = None
        if failed.any():
            hopeless = failed
            shortcut = failed & seqs.proven[lo]
            if shortcut.any():
                # a node of a proven polygon finds no candidate where an ancestor was passed
                # wrongly: that ancestor's subtree is built again, with every table
                reopened, repaired = _reopened(seqs, record, state[:, shortcut])
                hopeless = failed.copy()
                hopeless[np.flatnonzero(shortcut)[repaired]] = False
            # a failed tree's other nodes leave: none is emitted or tried again
            seq = state[_SEQ]
            ok[seq[hopeless]] = False
            kept = ok[seq]
            found &= kept
            retry = retry[kept[retry]]
        emit = np.flatnonzero(found)
        done = np.take(state[: _AT_HI + 1], emit, axis=1)
        done[_CAND] = apex[emit]
        emitted = np.empty((len(emit), _RECORD), dtype=record.dtype)
        emitted[...] = done[:_RECORD].T
        records[done[_ROW]] = emitted.view(record_item).reshape(len(emit))
        if len(waiting):
            waiting = _shortcut_again(seqs, waiting, done)
        state = _next_state(state, emit, done, apex, retry, blocker)
        if reopened is not None:
            state = _with_reopened(state, reopened, seqs)
            waiting = _waiting_with(waiting, reopened, reopenings)
    again = ~ok & seqs.proven[seq_start]
    # triangles (s_hi, s_lo, apex), (s_lo, s_hi, apex) where mirrored: counter-clockwise in
    # the output coordinates
    first, second = record[:, _HI], record[:, _LO]
    if mirrored.any():
        flip = np.repeat(mirrored, tri_count)
        first, second = np.where(flip, second, first), np.where(flip, first, second)
    triangles = np.empty((total, 3), dtype=np.int64)
    triangles[:, 0] = ids[first]
    triangles[:, 1] = ids[second]
    triangles[:, 2] = ids[record[:, _CAND]]
    parent, depth = record[:, _PARENT].astype(np.int64), record[:, _DEPTH].astype(np.int64)
    side = record[:, _SIDE].astype(np.int8)
    return Trees(triangles, parent, depth, side, tri_start, tri_count, ok, again)


def _reopened(
    seqs: Sequences, record: np.ndarray, failing: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """For open nodes ``failing`` (columns of the state) of proven polygons that find no
    candidate: their topmost ancestors within ``_REOPEN_LEVELS`` whose triangle every table
    rejects, as fresh open nodes (state columns, each once, none inside another's subtree),
    and per failing node whether it has one. (A wrong ancestor higher up makes the subtree
    built again fail too; its tree is then built again as a whole.)

    Why that ancestor's subtree is all there is to build again: in a proven polygon every
    rejection of a node whose ancestors are correct is real (section 4 of
    docs/algorithm.md), so a node whose ancestors are correct and whose triangle is
    correct took the rule's choice; a node finds no candidate only below a wrong one. The
    tree, once complete, is checked as a whole by the argument of section 4."""
    first = failing[_FIRST]
    count = failing.shape[1]
    owners, rows = [], []
    who = np.arange(count)
    local = failing[_PARENT]
    for _ in range(_REOPEN_LEVELS):
        up = local >= 0
        who, row = who[up], local[up] + first[who[up]]
        owners.append(who)
        rows.append(row)
        local = record[row, _PARENT].astype(np.int64)
        if not len(who):
            break
    repaired = np.zeros(count, dtype=bool)
    if not owners:
        return np.zeros((11, 0), dtype=np.int64), repaired
    owner, row = np.concatenate(owners), np.concatenate(rows)
    lo, hi, c = (record[row, k].astype(np.int64) for k in (_LO, _HI, _CAND))
    bad = np.zeros(len(row), dtype=bool)
    big = np.flatnonzero(hi - lo > 2)
    bad[big] = _all_tables(seqs, lo[big], hi[big], c[big])[0]
    owner, row, lo, hi = owner[bad], row[bad], lo[bad], hi[bad]
    if not len(row):
        return np.zeros((11, 0), dtype=np.int64), repaired
    # per failing node its topmost wrong ancestor (the lowest depth)
    order = np.lexsort((record[row, _DEPTH], owner))
    owner, row, lo, hi = owner[order], row[order], lo[order], hi[order]
    top = np.r_[True, owner[1:] != owner[:-1]]
    owner, row, lo, hi = owner[top], row[top], lo[top], hi[top]
    repaired[owner] = True
    row, pick = np.unique(row, return_index=True)
    owner, lo, hi = owner[pick], lo[pick], hi[pick]
    # none inside another's subtree (its rows follow that node's in pre-order)
    seq = failing[_SEQ][owner]
    inner = (seq[:, None] == seq) & (row[:, None] > row) & (row[:, None] < row + hi - lo - 1)
    keep = ~inner.any(axis=1)
    row, owner, lo, hi, seq = row[keep], owner[keep], lo[keep], hi[keep], seq[keep]
    nodes = np.zeros((11, len(row)), dtype=np.int64)
    nodes[_LO], nodes[_HI], nodes[_CAND] = lo, hi, hi - 1
    nodes[_PARENT] = record[row, _PARENT]
    nodes[_DEPTH] = record[row, _DEPTH]
    nodes[_SIDE] = record[row, _SIDE]
    nodes[_ROW] = row
    # V1 is at hi exactly where the node is its parent's upper part (or the root)
    parent = nodes[_PARENT] + first[owner]
    nodes[_AT_HI] = (nodes[_PARENT] < 0) | (record[np.maximum(parent, 0), _HI] == hi)
    nodes[_FIRST] = first[owner]
    nodes[_SEQ] = seq
    nodes[_BLOCK] = -1
    return nodes, repaired


# ancestors of a failing node looked at for the wrong one (on the benchmark's concave
# polygons of 260-600 vertices, it is 4-23 levels up)
_REOPEN_LEVELS = 32


def _with_reopened(state: np.ndarray, nodes: np.ndarray, seqs: Sequences) -> np.ndarray:
    """The open nodes ``state`` without those in the subtrees of ``nodes`` (fresh open nodes
    from :func:`_reopened`), then ``nodes``, whose sub-polygons are tested with every table
    until they are emitted (see :func:`_shortcut_again`)."""
    for lo, hi in zip(nodes[_LO].tolist(), nodes[_HI].tolist()):
        seqs.proven[lo:hi] = False
    return np.concatenate([state[:, ~_in_subtrees(state[_ROW], nodes)], nodes], axis=1)


def _in_subtrees(rows: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Per record row of ``rows``: it lies in the subtree of one of the open ``nodes`` (the
    hi - lo - 1 rows from the node's own, in pre-order; record rows are those of every
    sequence, so a range holds rows of one sequence only)."""
    inside = np.zeros(len(rows), dtype=bool)
    for row, lo, hi in zip(*(nodes[k].tolist() for k in (_ROW, _LO, _HI))):
        inside |= (rows >= row) & (rows < row + hi - lo - 1)
    return inside


def _shortcut_again(seqs: Sequences, waiting: np.ndarray, done: np.ndarray) -> np.ndarray:
    """The ``waiting`` reopened nodes (their rows) not among the emitted nodes ``done``
    (state columns); the ranges of those emitted take the shortcut again.

    A reopened node is tested with every table; once it is emitted its triangle is correct,
    and its subtree is no different from any other below correct ancestors (a wrong node in
    it is found and reopened in turn)."""
    back = np.isin(done[_ROW], waiting)
    if not back.any():
        return waiting
    for lo, hi in zip(done[_LO, back].tolist(), done[_HI, back].tolist()):
        seqs.proven[lo:hi] = True
    return waiting[~np.isin(waiting, done[_ROW, back])]


def _waiting_with(waiting: np.ndarray, nodes: np.ndarray, reopenings: np.ndarray) -> np.ndarray:
    """``waiting`` (see :func:`_shortcut_again`) without the nodes inside the subtrees of the
    fresh reopened ``nodes``, with the rows of those of the ``nodes`` whose sequence has been
    reopened at most ``_SHORTCUT_RETURNS`` times (after that a reopened subtree keeps every
    table, so that no tree is built again and again)."""
    seq = nodes[_SEQ]
    np.add.at(reopenings, seq, 1)
    waiting = waiting[~_in_subtrees(waiting, nodes)]
    return np.concatenate([waiting, nodes[_ROW, reopenings[seq] <= _SHORTCUT_RETURNS]])


# reopenings of a sequence after which reopened subtrees keep every table
_SHORTCUT_RETURNS = 8


def _roots(
    poly: np.ndarray, seq_start: np.ndarray, m: np.ndarray, tri_start: np.ndarray
) -> np.ndarray:
    """The open-node state of the root nodes of the sequences ``poly``."""
    state = np.zeros((11, len(poly)), dtype=np.int64)
    state[_LO] = seq_start[poly] + 1
    state[_HI] = seq_start[poly] + m[poly]
    state[_CAND] = state[_HI] - 1
    state[_ROW] = tri_start[poly]
    state[_FIRST] = tri_start[poly]
    state[_PARENT] = -1
    state[_AT_HI] = 1
    state[_SEQ] = poly
    state[_BLOCK] = -1
    return state


# open nodes below which the lock-step rounds (mostly their fixed numpy calls) give way to one
# Python step per node (on earcut's water-huge3, 213 rounds of under 16 nodes took 0.05 s,
# their subtrees one node at a time 0.011 s)
_ONE_BY_ONE = 16
# edge tests per position of a sub-polygon built one node at a time, after which its nodes go
# back to the rounds (a fan of s positions takes about s * s / 2; the rounds, at least s)
_ONE_BY_ONE_TESTS = 256
# the sum of the open nodes' squared spans up to which they go one node at a time, per
# position of the largest span (see _few_positions), and where some is proven valid
_ONE_BY_ONE_WORK = 1024
_ONE_BY_ONE_WORK_PROVEN = 256


def _few_positions(seqs: Sequences, state: np.ndarray) -> bool:
    """The open nodes' subtrees cost less one node at a time than in rounds: a fan of s
    positions tests about s * s / 2 edges one node at a time (about 0.3 us each), and takes s
    rounds (about 250 us each with every table, about 100 us where a proven polygon's
    candidates take the bent positions' tables), which the deepest subtree bounds."""
    spans = state[_HI] - state[_LO]
    work = _ONE_BY_ONE_WORK_PROVEN if seqs.proven[state[_LO]].any() else _ONE_BY_ONE_WORK
    return int((spans * spans).sum()) <= work * int(spans.max(initial=0))


def _one_by_one(
    seqs: Sequences, state: np.ndarray, record: np.ndarray, off: np.ndarray
) -> np.ndarray:
    """Rule "first": the subtrees of the open nodes ``state`` built one node at a time
    (``one_by_one.first_nodes``, exact), written to ``record``; per column whether it was
    built. A node that finds no candidate, or a subtree over its budget of edge tests, leaves
    its column to the rounds (which mend or fail its tree) and marks its sequence ``off``."""
    built = np.zeros(state.shape[1], dtype=bool)
    for j, column in enumerate(state.T.tolist()):
        lo, hi, top, parent, depth, side, row, at_hi, first, seq, _ = column
        if off[seq]:
            continue
        xs = seqs.sx[lo : hi + 1].tolist()
        ys = seqs.sy[lo : hi + 1].tolist()
        budget = _ONE_BY_ONE_TESTS * (hi - lo)
        runs = (
            (seqs.run_after[lo : hi + 1] - lo).tolist(),
            (seqs.run_before[lo : hi + 1] - lo).tolist(),
        )
        nodes, left = first_nodes(
            xs, ys, 0, hi - lo, top - lo, at_hi == 1, seqs.exact, budget, runs
        )
        if left:
            off[seq] = True
            continue
        built[j] = True
        out = np.array(nodes, dtype=np.int64)
        rows = row + np.arange(len(out))
        out[:, :3] += lo
        above = out[:, 3]
        out[:, 3] = np.where(above < 0, parent, row + above - first)
        out[:, 4] += depth
        out[0, 5] = side
        record[rows] = out
    return built
