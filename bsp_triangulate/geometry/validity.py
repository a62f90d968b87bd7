"""A cheap proof that polygons are valid in the OGC sense (as GEOS's ``isValid`` judges them).

``proven_valid`` looks at the flat rings of many (multi)polygons at once and answers True only
where it can prove validity; False means "not proven" (GEOS has to decide). A polygon is proven
valid when

- no part is empty; every ring is closed in XY, has at least 4 points and finite coordinates
  (|x|, |y| <= 1e150), and is star-shaped around a point ``c`` (its vertex mean, or a
  point a few steps nearer its kernel where the mean does not see the whole ring): every
  edge turns strictly the same way around ``c`` and the ring winds around ``c`` exactly
  once. Such a ring
  is simple: each ray from ``c`` meets it exactly once, so no two edges meet except adjacent
  ones at their common vertex, and it has no repeated point and no zero area. A ring of at
  most ``SMALL_RING_EDGES`` edges that is not star-shaped (an L, T or U building outline) is
  simple too where every two edges that are not neighbours surely have no common point and
  every two neighbours surely turn at their common vertex;
- every island's first point lies strictly inside the outer ring (ray crossing), and no edge
  of the island meets an edge of the outer ring: then the island lies in the interior;
- the islands' bounding boxes are pairwise disjoint (no two islands meet or nest), and so are
  the parts' outer rings' bounding boxes (no two parts meet or nest).

Every sign that decides is a float64 orientation outside Shewchuk's static error bound, so it
is the exact sign, which GEOS's own robust orientation (a filter, then double-double
arithmetic) finds as well: on these polygons GEOS finds no self-intersection, no ring
crossing, no hole outside its shell, no nested holes or shells and a connected interior.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..formats.wkb import PolygonTable
from .predicates import CCW_ERRBOUND, UNDERFLOW_SLACK, orient_sure_many
from .rings_batch import covers_in_order, ragged_index

# Coordinates beyond this stay finite in every product below.
_LARGEST = 1e150
# Larger polygons (in islands, parts or island-edge pairs) are left to GEOS.
MAX_ISLANDS = 32
MAX_PARTS = 32
MAX_PAIRS = 1 << 20
# Rings of at most this many edges that are not star-shaped are tested edge pair by edge pair.
SMALL_RING_EDGES = 16
# Steps of _kernel_guess (8 find the kernel of every ring of the radial test cases).
_KERNEL_STEPS = 8


def _segments_apart(p1x, p1y, p2x, p2y, q1x, q1y, q2x, q2y) -> np.ndarray:
    """The closed segments p1p2 and q1q2 surely have no point in common."""
    apart = (np.maximum(p1x, p2x) < np.minimum(q1x, q2x)) | (
        np.maximum(q1x, q2x) < np.minimum(p1x, p2x)
    )
    apart |= (np.maximum(p1y, p2y) < np.minimum(q1y, q2y)) | (
        np.maximum(q1y, q2y) < np.minimum(p1y, p2y)
    )
    first = orient_sure_many(p1x, p1y, p2x, p2y, q1x, q1y)
    apart |= (first != 0) & (first == orient_sure_many(p1x, p1y, p2x, p2y, q2x, q2y))
    third = orient_sure_many(q1x, q1y, q2x, q2y, p1x, p1y)
    apart |= (third != 0) & (third == orient_sure_many(q1x, q1y, q2x, q2y, p2x, p2y))
    return apart


@dataclass
class _Rings:
    """The rings still in question: points, extents and boxes (each ring has >= 4 points)."""

    x: np.ndarray
    y: np.ndarray
    first: np.ndarray  # first point of each ring in x, y
    length: np.ndarray
    geometry: np.ndarray  # geometry of each ring
    part: np.ndarray  # part (table index) of each ring
    lo_x: np.ndarray = field(init=False)
    hi_x: np.ndarray = field(init=False)
    lo_y: np.ndarray = field(init=False)
    hi_y: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.lo_x = np.minimum.reduceat(self.x, self.first)
        self.hi_x = np.maximum.reduceat(self.x, self.first)
        self.lo_y = np.minimum.reduceat(self.y, self.first)
        self.hi_y = np.maximum.reduceat(self.y, self.first)

    def boxes_apart(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The closed boxes of rings a and b have no point in common."""
        return (
            (self.hi_x[a] < self.lo_x[b])
            | (self.hi_x[b] < self.lo_x[a])
            | (self.hi_y[a] < self.lo_y[b])
            | (self.hi_y[b] < self.lo_y[a])
        )


def _ragged(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, position within owner) of ``counts[i]`` items per owner i."""
    owner = np.repeat(np.arange(len(counts)), counts)
    return owner, np.arange(len(owner)) - (np.cumsum(counts) - counts)[owner]


def _pairs(group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All (i, j), i < j, of positions in ``group`` (sorted) with the same group value."""
    if not len(group):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    _values, first, sizes = np.unique(group, return_index=True, return_counts=True)
    member = np.arange(len(group)) - np.repeat(first, sizes)
    # each member pairs with the members after it in its group
    i, offset = _ragged(np.repeat(sizes, sizes) - member - 1)
    return i, i + 1 + offset


def proven_valid(table: PolygonTable, wanted: np.ndarray) -> np.ndarray:
    """Per geometry of ``table``: proven valid (see the module docstring). Only geometries
    with ``wanted`` set are examined; the others are False."""
    proven = np.asarray(wanted, dtype=bool) & table.parsed
    proven &= (table.geometry_parts >= 1) & (table.geometry_parts <= MAX_PARTS)
    proven &= table.geometry_empty_parts == 0
    if not proven.any():
        return proven
    with np.errstate(all="ignore"):
        rings = _rings_in_question(table, proven)
        if rings is not None:
            _check_rings(rings, proven)
            _check_islands(rings, proven)
            _check_boxes(rings, proven)
    return proven


def proven_valid_rings(
    x: np.ndarray,
    y: np.ndarray,
    ring_start: np.ndarray,
    ring_len: np.ndarray,
    ring_poly: np.ndarray,
    wanted: np.ndarray,
) -> np.ndarray:
    """Per polygon of open rings (first point not repeated; a polygon's outer ring first, its
    islands after it): proven valid as ``proven_valid`` proves it, so no two of its vertices
    coincide and none lies on an edge other than its own two. Only polygons with ``wanted``
    set are examined; the others are False."""
    count = len(wanted)
    proven = np.zeros(count, dtype=bool)
    if not len(ring_len):
        return proven
    rings_of = np.bincount(ring_poly, minlength=count)
    proven[:] = wanted & (rings_of >= 1) & (rings_of <= MAX_ISLANDS + 1)
    proven[ring_poly[ring_len < 3]] = False
    chosen = np.flatnonzero(proven[ring_poly])
    if not len(chosen):
        return proven
    # closed copies of the rings in question: each ring's first point again after its last
    open_len = ring_len[chosen]
    length = open_len + 1
    ends = np.cumsum(open_len)
    starts = ends - open_len
    if covers_in_order(ring_start[chosen], open_len, len(x)):
        open_x, open_y = x, y
    else:
        source = np.repeat(ring_start[chosen] - starts, open_len)
        source += np.arange(len(source))
        open_x, open_y = x[source], y[source]
    geometry = ring_poly[chosen]
    rings = _Rings(
        x=np.insert(open_x, ends, open_x[starts]),
        y=np.insert(open_y, ends, open_y[starts]),
        first=np.cumsum(length) - length,
        length=length,
        geometry=geometry,
        part=geometry,
    )
    with np.errstate(all="ignore"):
        _check_rings(rings, proven)
        _check_islands(rings, proven)
        _check_boxes(rings, proven)
    return proven


def _rings_in_question(table: PolygonTable, proven: np.ndarray) -> _Rings | None:
    """The rings of the geometries still in question; rules out geometries with too many
    islands or a ring of fewer than 4 points."""
    part_geometry = np.repeat(np.arange(len(proven)), table.geometry_parts)
    proven[part_geometry[table.part_rings > MAX_ISLANDS + 1]] = False
    ring_part = np.repeat(np.arange(len(table.part_rings)), table.part_rings)
    ring_geometry = part_geometry[ring_part]
    proven[ring_geometry[table.ring_len < 4]] = False
    in_question = proven[ring_geometry]
    if in_question.all():
        length = table.ring_len
        x, y = table.points[:, 0].copy(), table.points[:, 1].copy()
    else:
        chosen = np.flatnonzero(in_question)
        if not len(chosen):
            return None
        ring_part, ring_geometry = ring_part[chosen], ring_geometry[chosen]
        length = table.ring_len[chosen]
        owner, within = _ragged(length)
        points = table.points[table.ring_start[chosen][owner] + within]
        x, y = np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])
    return _Rings(
        x=x,
        y=y,
        first=np.cumsum(length) - length,
        length=length,
        geometry=ring_geometry,
        part=ring_part,
    )


def _check_rings(rings: _Rings, proven: np.ndarray) -> None:
    """Each ring closed, finite, and star-shaped around its vertex mean or, failing that,
    around a point found nearer its kernel (:func:`_kernel_guess`), winding once."""
    x, y, first, length = rings.x, rings.y, rings.first, rings.length
    last = first + length - 1
    # the largest magnitude of each ring, from its extents (NaN where a coordinate is NaN)
    largest = np.maximum(np.maximum(-rings.lo_x, rings.hi_x), np.maximum(-rings.lo_y, rings.hi_y))
    reject = ~(largest <= _LARGEST)
    reject |= (x[first] != x[last]) | (y[first] != y[last])
    edges = length - 1
    cx = (np.add.reduceat(x, first) - x[last]) / edges
    cy = (np.add.reduceat(y, first) - y[last]) / edges
    star = _star_shaped(x, y, first, length, cx, cy)
    # the vertex mean lies outside the kernel of many star-shaped rings (unevenly digitised,
    # or with edges that point almost at the centre): one more try around another point
    again = np.flatnonzero(~star & ~reject & (edges > SMALL_RING_EDGES) & proven[rings.geometry])
    if len(again):
        source = ragged_index(first[again], length[again])
        sub_first = np.cumsum(length[again]) - length[again]
        gx, gy = _kernel_guess(x[source], y[source], sub_first, length[again], cx[again], cy[again])
        star[again] = _star_shaped(x[source], y[source], sub_first, length[again], gx, gy)
    # a small ring that is not star-shaped (an L, T or U outline) may still be proven simple
    small = np.flatnonzero(~star & ~reject & (edges <= SMALL_RING_EDGES) & proven[rings.geometry])
    if len(small):
        star[small] = _small_rings_simple(rings, small)
    reject |= ~star
    proven[rings.geometry[reject]] = False


def _star_shaped(
    x: np.ndarray,
    y: np.ndarray,
    first: np.ndarray,
    length: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
) -> np.ndarray:
    """Per closed ring (points ``first`` .. ``first + length - 1`` of x, y): every edge turns
    strictly the same way around the ring's centre (cx, cy), and the ring winds around it
    exactly once (exact signs)."""
    last = first + length - 1
    # coordinates relative to the ring's centre c: orient(a, b, c) from them is Shewchuk's
    # orient2d(a, b, c) operation for operation, so its error bound holds; signs are exact
    rx = x - np.repeat(cx, length)
    ry = y - np.repeat(cy, length)
    ax, ay, bx, by = rx[:-1], ry[:-1], rx[1:], ry[1:]
    left = ax * by
    right = ay * bx
    det = left - right
    bound = np.abs(left)
    bound += np.abs(right)
    bound *= CCW_ERRBOUND
    bound += UNDERFLOW_SLACK
    counter = det > bound
    clockwise = det < -bound
    # winding number around the centre: edges crossing the horizontal ray to its right are
    # the upward ones of a counter-clockwise ring, the downward ones of a clockwise ring
    # (a NaN coordinate rejects its ring through ``largest``: its crossings do not count)
    above = ry > 0
    upward = above[1:] > above[:-1]
    downward = above[:-1] > above[1:]
    # pairs of consecutive points of one ring only: the pair from a ring's last point to the
    # next ring's first point counts for nothing
    junk = last[:-1]
    counter[junk] = clockwise[junk] = True
    upward[junk] = downward[junk] = False
    counter = np.logical_and.reduceat(counter, first)
    clockwise = np.logical_and.reduceat(clockwise, first)
    crossings = np.where(
        counter,
        np.add.reduceat(upward, first, dtype=np.int64),
        np.add.reduceat(downward, first, dtype=np.int64),
    )
    return (counter | clockwise) & (crossings == 1)


def _kernel_guess(
    x: np.ndarray,
    y: np.ndarray,
    first: np.ndarray,
    length: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    steps: int = _KERNEL_STEPS,
) -> tuple[np.ndarray, np.ndarray]:
    """Per closed ring, a point likelier to lie in its kernel (the points that see the whole
    ring) than (cx, cy): a few steps, each across the line of the edge that (cx, cy) lies
    farthest behind, half as far again beyond it. Only a guess: :func:`_star_shaped`
    decides, exactly."""
    cx, cy = cx.copy(), cy.copy()
    with np.errstate(all="ignore"):
        ex, ey = np.diff(x), np.diff(y)
        junk = (first + length - 1)[:-1]
        # the ring's orientation: twice its signed area
        cross = x[:-1] * y[1:] - y[:-1] * x[1:]
        cross[junk] = 0.0
        area = np.add.reduceat(cross, first)
        turn = np.repeat(np.sign(area), length)[:-1]
        norm = np.hypot(ex, ey)
        nx, ny = -ey * turn / norm, ex * turn / norm  # unit normals into the ring
        owner = np.repeat(np.arange(len(first)), length)[:-1]
        for _ in range(steps):
            depth = (cx[owner] - x[:-1]) * nx + (cy[owner] - y[:-1]) * ny
            depth[junk] = np.inf
            depth[~np.isfinite(depth)] = np.inf
            worst = np.minimum.reduceat(depth, first)
            behind = worst < 0
            if not behind.any():
                break
            # the first edge of each ring at its worst depth
            at = np.flatnonzero(depth == worst[owner])
            at = at[np.r_[True, owner[at][1:] != owner[at][:-1]]]
            ring = owner[at]
            move = behind[ring]
            at, ring = at[move], ring[move]
            cx[ring] -= 1.5 * worst[ring] * nx[at]
            cy[ring] -= 1.5 * worst[ring] * ny[at]
    return cx, cy


def _small_rings_simple(rings: _Rings, chosen: np.ndarray) -> np.ndarray:
    """Per ring of ``chosen`` (closed, finite): surely simple, by every pair of its edges.

    Each two edges that are not neighbours surely have no point in common, and each two
    neighbours surely turn (their common vertex is the only point they share): then no two
    edges meet except neighbours at their common vertex, which makes the closed polyline a
    simple ring."""
    x, y = rings.x, rings.y
    edges = rings.length[chosen] - 1
    first = rings.first[chosen]
    # the turn at every vertex: edge i and edge i + 1 (the last with the first)
    ring, i = _ragged(edges)
    a = first[ring] + i
    b = a + 1
    c = np.where(i + 1 < edges[ring], b + 1, first[ring] + 1)
    simple = np.logical_and.reduceat(
        orient_sure_many(x[a], y[a], x[b], y[b], x[c], y[c]) != 0, np.cumsum(edges) - edges
    )
    # every pair i < j of edges that are not neighbours: j from i + 2 to the last edge, but
    # not the last edge when i is the first (they meet at the ring's first point)
    count = np.maximum(edges[ring] - i - 2 - (i == 0), 0)
    pair, k = _ragged(count)
    p = a[pair]
    q = p + 2 + k
    apart = _segments_apart(x[p], y[p], x[p + 1], y[p + 1], x[q], y[q], x[q + 1], y[q + 1])
    broken = np.bincount(ring[pair[~apart]], minlength=len(chosen)) > 0
    return simple & ~broken


def _check_islands(rings: _Rings, proven: np.ndarray) -> None:
    """Every island's first point strictly inside its part's outer ring, and no island edge
    meets an outer ring edge."""
    x, y, first, length = rings.x, rings.y, rings.first, rings.length
    is_outer = np.r_[True, rings.part[1:] != rings.part[:-1]]
    outer_of = np.maximum.accumulate(np.where(is_outer, np.arange(len(length)), 0))
    islands = np.flatnonzero(~is_outer & proven[rings.geometry])
    if not len(islands):
        return
    outers = outer_of[islands]
    outer_edges = length[outers] - 1
    work = np.bincount(
        rings.geometry[islands],
        weights=outer_edges * (1 + length[islands]),
        minlength=len(proven),
    )
    proven[work > MAX_PAIRS] = False
    keep = proven[rings.geometry[islands]]
    islands, outers, outer_edges = islands[keep], outers[keep], outer_edges[keep]
    if not len(islands):
        return
    # every edge of the outer ring with the island (its first point, its box), island by island
    pair = np.repeat(np.arange(len(islands)), outer_edges)
    a = np.repeat(first[outers] - (np.cumsum(outer_edges) - outer_edges), outer_edges)
    a += np.arange(len(a))
    # y[1:][a] is y[a + 1] without the index array a + 1
    ay, by = y[a], y[1:][a]
    point = first[islands]
    py = np.repeat(y[point], outer_edges)
    # ray crossings to the right of the point: only straddling edges need an orientation
    straddle = np.flatnonzero((ay > py) != (by > py))
    a_straddle = a[straddle]
    side = orient_sure_many(
        x[a_straddle],
        ay[straddle],
        x[1:][a_straddle],
        by[straddle],
        x[point][pair[straddle]],
        py[straddle],
    )
    crossing = np.where(by[straddle] > ay[straddle], side > 0, side < 0)
    proven[rings.geometry[islands[pair[straddle[side == 0]]]]] = False
    inside = np.bincount(pair[straddle[crossing]], minlength=len(islands)) % 2 == 1
    proven[rings.geometry[islands[~inside]]] = False
    # outer edges whose box meets the island's box, against every island edge
    near = (np.maximum(ay, by) >= np.repeat(rings.lo_y[islands], outer_edges)) & (
        np.minimum(ay, by) <= np.repeat(rings.hi_y[islands], outer_edges)
    )
    near = np.flatnonzero(near)
    owner_island = islands[pair[near]]
    a_near = a[near]
    ax, bx = x[a_near], x[1:][a_near]
    near = near[
        (np.maximum(ax, bx) >= rings.lo_x[owner_island])
        & (np.minimum(ax, bx) <= rings.hi_x[owner_island])
    ]
    if not len(near):
        return
    island = islands[pair[near]]
    owner, within = _ragged(length[island] - 1)
    edge = a[near][owner]
    b = first[island][owner] + within
    apart = _segments_apart(
        x[edge], y[edge], x[edge + 1], y[edge + 1], x[b], y[b], x[b + 1], y[b + 1]
    )
    proven[rings.geometry[island[owner[~apart]]]] = False


def _check_boxes(rings: _Rings, proven: np.ndarray) -> None:
    """The islands of a part, and the outer rings of a geometry, have pairwise disjoint
    boxes."""
    is_outer = np.r_[True, rings.part[1:] != rings.part[:-1]]
    islands = np.flatnonzero(~is_outer)
    outers = np.flatnonzero(is_outer)
    for members, group in ((islands, rings.part[islands]), (outers, rings.geometry[outers])):
        i, j = _pairs(group)
        i, j = members[i], members[j]
        proven[rings.geometry[i[~rings.boxes_apart(i, j)]]] = False
