"""Ring normalisation for the batch path, as flat arrays over many polygons.

Gives the same vertices, working coordinates, orientation and ring order as ``rings.py`` for
the polygons it accepts; a polygon it cannot decide the same way (steep faces, rings that
touch, zero-area islands, near-zero areas, unusual input) is marked as not handled.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import chain
from operator import attrgetter

import numpy as np

from .predicates import (
    UNDERFLOW_SLACK,
    area_surely_clear,
    orient_many,
    ring_area_signs,
    shoelace_products,
)
from .rings import WALL_RATIO

_EPS = 2.0**-53
_FLOAT64 = np.dtype(np.float64)


@dataclass
class FlatRings:
    """Cleaned rings of many polygons, in input order, as flat arrays.

    - ``vertices``: (N, 3) every cleaned vertex (output coordinates, not mirrored);
      ``vx, vy, vz`` its columns.
    - ``ring_start``, ``ring_len``, ``ring_poly``: the rings (vertices contiguous in ``v*``).
    - ``poly_ring0``, ``poly_rings``: first ring and number of rings of each polygon.
    - ``poly_vstart``, ``poly_vcount``: each polygon's vertices (its output ``vertices``).
    - ``handled``: polygons the batch path decides like the engine.
    - ``empty``: handled polygons whose result is an empty triangulation.
    - ``mirrored``: the outer ring is clockwise (x is negated in the working plane).
    - ``ring_reversed``: the ring is traversed backwards (islands that are counter-clockwise
      after mirroring).
    """

    vertices: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    vz: np.ndarray
    ring_start: np.ndarray
    ring_len: np.ndarray
    ring_poly: np.ndarray
    poly_ring0: np.ndarray
    poly_rings: np.ndarray
    poly_vstart: np.ndarray
    poly_vcount: np.ndarray
    handled: np.ndarray
    empty: np.ndarray
    mirrored: np.ndarray
    ring_reversed: np.ndarray


def ragged_index(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(s, s + c)`` for every (s, c) (none where c <= 0)."""
    counts = np.maximum(counts, 0)
    ends = np.cumsum(counts)
    total = int(ends[-1]) if len(ends) else 0
    # each run's start minus the run's first output index, plus the output index
    out = np.repeat((starts - ends + counts).astype(np.int64, copy=False), counts)
    out += np.arange(total)
    return out


def ring_edge_keys(starts: np.ndarray, sizes: np.ndarray, n: int) -> np.ndarray:
    """Every edge of the closed rings (ring r: the vertices ``starts[r]`` to ``starts[r] +
    sizes[r] - 1`` of ``n``) as the integer min * n + max of its ends."""
    start = ragged_index(starts, sizes)
    end = start + 1
    filled = sizes > 0
    end[(np.cumsum(sizes) - 1)[filled]] = starts[filled]  # each ring's last back to its first
    return np.minimum(start, end) * n + np.maximum(start, end)


def covers_in_order(starts: np.ndarray, counts: np.ndarray, total: int) -> bool:
    """The ranges [starts, starts + counts) are the positions 0 .. total - 1 one after
    another: ``ragged_index(starts, counts)`` is then ``arange(total)``, and a gather by it
    can be left out."""
    used = counts > 0
    return int(counts.sum()) == total and np.array_equal(
        starts[used], (np.cumsum(counts) - counts)[used]
    )


def _parse_plain(polygons: Sequence[Sequence[object]]) -> tuple | None:
    """:func:`_parse` where every polygon is a list or tuple of (n > 0, 2 to 4) float64
    arrays (the common input), without a Python step per ring; None for any other input."""
    if not set(map(type, polygons)) <= {list, tuple}:
        return None
    arrays = list(chain.from_iterable(polygons))
    if not set(map(type, arrays)) <= {np.ndarray}:
        return None
    if not set(map(attrgetter("dtype"), arrays)) <= {_FLOAT64}:
        return None
    if not set(map(attrgetter("ndim"), arrays)) <= {2}:
        return None
    # every shape has two entries: both columns of the (ring, entry) table in one pass
    shapes = np.fromiter(
        chain.from_iterable(map(attrgetter("shape"), arrays)), np.int64, 2 * len(arrays)
    ).reshape(-1, 2)
    lengths, widths = shapes[:, 0], shapes[:, 1]
    if not ((lengths > 0) & (widths >= 2) & (widths <= 4)).all():
        return None
    counts = [count or -1 for count in map(len, polygons)]
    return arrays, counts, widths, lengths


def _parse(polygons: Sequence[Sequence[object]]) -> tuple:
    """Input rings as float arrays; the ring count per polygon (-1: not handled), the
    columns and the points of each ring."""
    arrays: list[np.ndarray] = []
    counts: list[int] = []
    widths: list[int] = []
    ndarray, float64 = np.ndarray, np.float64
    for rings in polygons:
        if isinstance(rings, ndarray) and rings.ndim == 2:
            rings = [rings]
        before = len(arrays)
        try:
            for ring in rings:
                if type(ring) is not ndarray or ring.dtype != float64:
                    ring = np.asarray(ring, dtype=float64)
                shape = ring.shape
                if len(shape) != 2 or shape[1] not in (2, 3, 4) or shape[0] == 0:
                    raise ValueError("unusual ring")
                arrays.append(ring)
                widths.append(shape[1])
        except (TypeError, ValueError):
            del arrays[before:], widths[before:]
        counts.append(len(arrays) - before or -1)
    lengths = np.array([len(a) for a in arrays], dtype=np.int64)
    return arrays, counts, np.array(widths, dtype=np.int64), lengths


def as_xyz(points: np.ndarray) -> np.ndarray:
    """Points of 2 to 4 columns as (N, 3): z = 0 where absent, a 4th column (m) dropped; the
    array itself when it has 3 columns."""
    width = points.shape[1]
    if width == 3:
        return points
    if width > 3:
        return np.ascontiguousarray(points[:, :3])
    out = np.zeros((len(points), 3))
    out[:, :width] = points
    return out


def _joined(arrays: list[np.ndarray], width: int) -> np.ndarray:
    """The float64 rings of ``width`` columns one after another, as one (N, width) array
    (joined as bytes where every ring is C-contiguous: no step per ring in NumPy)."""
    try:
        return np.frombuffer(b"".join(arrays), dtype=np.float64).reshape(-1, width)
    except (BufferError, TypeError, ValueError):
        return np.concatenate(arrays)


def stack_rings(arrays: list[np.ndarray], widths: np.ndarray) -> np.ndarray:
    """All rings (``widths`` columns each) as one (N, 3) array, z = 0 where absent."""
    if not arrays:
        return np.zeros((0, 3))
    if (widths == 2).all():
        return _with_zero_z(_joined(arrays, 2))[0]
    if (widths == widths[0]).all():
        joined = _joined(arrays, int(widths[0]))
        # a joined array may be read-only: as_xyz copies 4 columns, 3 are copied here
        return joined.copy() if widths[0] == 3 else as_xyz(joined)
    return np.concatenate([as_xyz(a) for a in arrays])


def _with_zero_z(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 3) points of the (N, 2) ``xy`` with z = 0, and their x and y as contiguous
    arrays."""
    x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    points = np.zeros((len(x), 3))
    points[:, 0] = x
    points[:, 1] = y
    return points, x, y


def _sum_with_bound(terms: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> tuple:
    """Per-segment sums of ``terms`` and a bound on the error of any summation order."""
    total = np.add.reduceat(terms, starts)
    magnitude = np.add.reduceat(np.abs(terms), starts)
    bound = magnitude * (counts + 8) * 4.0 * _EPS + UNDERFLOW_SLACK * counts
    return total, bound


def _xy_is_working_plane(p: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Per ring: ``rings.working_axes`` surely picks XY for it (Newell normal mostly z)."""
    nxt = np.arange(len(p)) + 1
    last = starts + counts - 1
    nxt[last] = starts
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    xn, yn, zn = x[nxt], y[nxt], z[nxt]
    flat = np.logical_and.reduceat(z == 0, starts)
    if flat.all():
        return flat
    nx, bx = _sum_with_bound((y - yn) * (z + zn), starts, counts)
    ny, by = _sum_with_bound((z - zn) * (x + xn), starts, counts)
    nz, bz = _sum_with_bound((x - xn) * (y + yn), starts, counts)
    # the engine compares its own rounded sums: leave room for both errors
    clear = (np.abs(nz) - 2 * bz) * WALL_RATIO > np.maximum(
        np.abs(nx) + 2 * bx, np.abs(ny) + 2 * by
    )
    return flat | (clear & np.isfinite(nz))


def flatten_rings(
    polygons: Sequence[Sequence[object]], max_vertices: int, xy: bool = False
) -> FlatRings:
    """Parse, clean and orient the rings of ``polygons`` (see the module docstring);
    ``xy``: every polygon is worked in XY (no steep face is left to the engine)."""
    arrays, ring_counts, widths, raw_len = _parse_plain(polygons) or _parse(polygons)
    counts = np.array(ring_counts, dtype=np.int64)
    if len(arrays) and (widths == 2).all():
        # x and y straight from the rings; z is 0 (finite, and no plane to check)
        raw, x, y = _with_zero_z(_joined(arrays, 2))
        return _flatten(raw, x, y, True, raw_len, counts, max_vertices, True)
    return flatten_points(stack_rings(arrays, widths), raw_len, counts, max_vertices, True, xy)


def flatten_points(
    raw: np.ndarray,
    raw_len: np.ndarray,
    ring_counts: np.ndarray,
    max_vertices: int,
    owned: bool = False,
    xy: bool = False,
) -> FlatRings:
    """:func:`flatten_rings` of rings given as one (N, 3) array of their points one after
    another, ``raw_len`` points per ring (none empty), ``ring_counts`` rings per polygon
    (-1: the polygon is not handled, and has no rings here). ``owned``: ``raw`` is the
    caller's own scratch array, which may become the result's ``vertices``; ``xy``: see
    :func:`flatten_rings`."""
    x, y = np.ascontiguousarray(raw[:, 0]), np.ascontiguousarray(raw[:, 1])
    return _flatten(raw, x, y, False, raw_len, ring_counts, max_vertices, owned, xy)


def _flatten(
    raw: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    zero_z: bool,
    raw_len: np.ndarray,
    ring_counts: np.ndarray,
    max_vertices: int,
    owned: bool,
    xy: bool = False,
) -> FlatRings:
    """:func:`flatten_points` with ``raw``'s x and y as contiguous arrays; ``zero_z``: every
    z is 0; ``xy``: no plane check (every polygon is worked in XY)."""
    count = len(ring_counts)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        handled = ring_counts > 0
        poly_rings = np.maximum(ring_counts, 0)
        ring_poly = np.repeat(np.arange(count, dtype=np.int64), poly_rings)
        poly_ring0 = np.cumsum(poly_rings) - poly_rings
        raw_start = np.cumsum(raw_len) - raw_len
        if not zero_z:
            _finite_rings(raw, raw_start, ring_poly, handled)
        if not zero_z and not xy and len(raw) and raw[:, 2].any():
            outer_rings = poly_ring0[poly_rings > 0]
            outer_len = raw_len[outer_rings]
            outer_points = raw[ragged_index(raw_start[outer_rings], outer_len)]
            plane = _xy_is_working_plane(outer_points, np.cumsum(outer_len) - outer_len, outer_len)
            handled[ring_poly[outer_rings[~plane]]] = False
        # clean: consecutive duplicates in XY, then a closing point equal to the first
        keep = np.ones(len(raw), dtype=bool)
        keep[1:] = (x[1:] != x[:-1]) | (y[1:] != y[:-1])
        keep[raw_start] = True
        duplicates = len(raw) - np.count_nonzero(keep)
        if duplicates == 0:
            # position of each ring's last point (all kept)
            kept_count = raw_len.astype(np.int64)
            last_raw = raw_start + kept_count - 1
        else:
            kept_count = np.add.reduceat(keep.astype(np.int64), raw_start)
            # position of each ring's last kept point
            last_raw = np.maximum.reduceat(np.where(keep, np.arange(len(raw)), -1), raw_start)
        closing = (kept_count > 1) & (x[last_raw] == x[raw_start]) & (y[last_raw] == y[raw_start])
        if duplicates == 0 and not closing.any():
            points = raw if owned else raw.copy()
            vx, vy = x, y
        else:
            keep[last_raw[closing]] = False
            kept = np.flatnonzero(keep)
            points = raw.take(kept, axis=0)
            vx, vy = x[kept], y[kept]
        ring_len = kept_count - closing
        ring_start = np.cumsum(ring_len) - ring_len
        too_small = ring_len < 3
        outer_small = too_small[poly_ring0[poly_rings > 0]]
        polys_with_rings = np.flatnonzero(poly_rings > 0)
        empty = np.zeros(count, dtype=bool)
        empty[polys_with_rings[outer_small]] = True
        # islands with fewer than 3 points are ignored by the engine: not handled here
        is_island = np.ones(len(ring_len), dtype=bool)
        is_island[poly_ring0[poly_rings > 0]] = False
        handled[ring_poly[too_small & is_island]] = False
        nonempty = ring_len > 0
        if nonempty.all():
            signs, finite = ring_area_signs(vx, vy, ring_start, ring_len)
        else:
            signs, finite = np.zeros(len(ring_len), dtype=np.int64), True
            if nonempty.any():
                signs[nonempty], finite = ring_area_signs(
                    vx, vy, ring_start[nonempty], ring_len[nonempty]
                )
        if zero_z and not finite:
            _finite_rings(raw, raw_start, ring_poly, handled)
        outer_sign = np.zeros(count, dtype=np.int64)
        outer_sign[polys_with_rings] = signs[poly_ring0[polys_with_rings]]
        # an undecided sign: zero area (empty result) or too close to call (engine decides)
        undecided_outer = (outer_sign == 0) & ~empty & (poly_rings > 0)
        handled[undecided_outer] = False
        handled[ring_poly[(signs == 0) & is_island]] = False
        mirrored = outer_sign < 0
        ring_sign = signs * np.where(mirrored[ring_poly], -1, 1)
        ring_reversed = is_island & (ring_sign > 0)
        poly_vcount = np.bincount(ring_poly, weights=ring_len, minlength=count).astype(np.int64)
        poly_vstart = np.cumsum(poly_vcount) - poly_vcount
        handled[poly_vcount > max_vertices] = False
        empty &= handled
    return FlatRings(
        vertices=points,
        vx=vx,
        vy=vy,
        vz=np.zeros(len(points)) if zero_z else np.ascontiguousarray(points[:, 2]),
        ring_start=ring_start,
        ring_len=ring_len,
        ring_poly=ring_poly,
        poly_ring0=poly_ring0,
        poly_rings=poly_rings,
        poly_vstart=poly_vstart,
        poly_vcount=poly_vcount,
        handled=handled,
        empty=empty,
        mirrored=mirrored,
        ring_reversed=ring_reversed,
    )


def _finite_rings(
    raw: np.ndarray, raw_start: np.ndarray, ring_poly: np.ndarray, handled: np.ndarray
) -> None:
    """Marks polygons with a non-finite coordinate in some ring as not handled."""
    if len(raw) and not np.isfinite(raw).all():
        finite = np.isfinite(raw).all(axis=1)
        ring_finite = np.logical_and.reduceat(finite, raw_start)
        handled[ring_poly[~ring_finite]] = False


def _band_pairs(
    coord: np.ndarray,
    poly_of: np.ndarray,
    count: int,
    edges: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(edge, vertex) pairs of one polygon whose ``coord`` lies in [coord[low], coord[high]]
    of the edge (``low``, ``high``: its end points with the lower and the higher coord)."""
    has = np.bincount(poly_of, minlength=count) > 0
    first = np.flatnonzero(np.r_[True, poly_of[1:] != poly_of[:-1]])
    cmin = np.zeros(count)
    cmax = np.zeros(count)
    cmin[has] = np.minimum.reduceat(coord, first)
    cmax[has] = np.maximum.reduceat(coord, first)
    scale = 0.5 / np.where(cmax > cmin, cmax - cmin, 1.0)
    # poly + (value - min) * scale is monotone in value within a polygon (rounding included)
    key = poly_of + (coord - cmin[poly_of]) * scale[poly_of]
    order = np.argsort(key)
    sorted_key = key[order]
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    # runs of equal keys: the band reaches from the first of the low end's run to the last
    # of the high end's run
    same = sorted_key[1:] == sorted_key[:-1]
    index = np.arange(len(sorted_key))
    run_first = np.maximum.accumulate(np.where(np.r_[False, same], 0, index))
    run_last = np.minimum.accumulate(np.where(np.r_[same, False], len(index), index)[::-1])[::-1]
    start = run_first[rank[low]]
    stop = run_last[rank[high]] + 1
    # the band's first and last keys are the edge's own end points': drop them unless another
    # vertex has the same key
    tied = np.zeros(len(sorted_key), dtype=bool)
    tied[1:] |= same
    tied[:-1] |= same
    start += ~tied[start]
    stop -= ~tied[stop - 1]
    counts = np.maximum(stop - start, 0)
    return np.repeat(edges, counts), order[ragged_index(start, counts)]


def touching_polygons(flat: FlatRings, wx: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Per polygon with ``wanted`` set: two of its vertices coincide, or a vertex lies in the
    relative interior of a ring edge (the engine then splits edges or joins rings at that
    point); False for the others."""
    count = len(flat.handled)
    rings = np.flatnonzero(wanted[flat.ring_poly])
    if len(rings) == len(flat.ring_len):
        return _touching(wx, flat.vy, flat.ring_start, flat.ring_len, flat.ring_poly, count)
    ring_len = flat.ring_len[rings]
    points = ragged_index(flat.ring_start[rings], ring_len)
    ring_start = np.cumsum(ring_len) - ring_len
    ring_poly = flat.ring_poly[rings]
    return _touching(wx[points], flat.vy[points], ring_start, ring_len, ring_poly, count)


def _touching(
    wx: np.ndarray,
    wy: np.ndarray,
    ring_start: np.ndarray,
    ring_len: np.ndarray,
    ring_poly: np.ndarray,
    count: int,
) -> np.ndarray:
    """:func:`touching_polygons` of the rings given (vertices contiguous per ring)."""
    nv = len(wx)
    touching = np.zeros(count, dtype=bool)
    if nv == 0:
        return touching
    poly_of = np.repeat(ring_poly, ring_len)
    nxt = np.arange(nv, dtype=np.int64) + 1
    nxt[ring_start + ring_len - 1] = ring_start
    x0, x1 = np.minimum(wx, wx[nxt]), np.maximum(wx, wx[nxt])
    y0, y1 = np.minimum(wy, wy[nxt]), np.maximum(wy, wy[nxt])
    # candidates from the thinner slab of each edge's bounding box, then its other side
    steep = x1 - x0 <= y1 - y0
    groups = []
    for mask, along, across, lo, hi in (
        (steep, wx, wy, y0, y1),
        (~steep, wy, wx, x0, x1),
    ):
        chosen = np.flatnonzero(mask)
        ends = nxt[chosen]
        ascending = along[chosen] <= along[ends]
        low = np.where(ascending, chosen, ends)
        high = np.where(ascending, ends, chosen)
        e, v = _band_pairs(along, poly_of, count, chosen, low, high)
        t = across[v]
        near = (t >= lo[e]) & (t <= hi[e])
        groups.append((e[near], v[near]))
    edge = np.concatenate([g[0] for g in groups])
    vertex = np.concatenate([g[1] for g in groups])
    a, b = edge, nxt[edge]
    px, py = wx[vertex], wy[vertex]
    in_box = (px >= x0[edge]) & (px <= x1[edge]) & (py >= y0[edge]) & (py <= y1[edge])
    in_box &= (vertex != a) & (vertex != b)
    edge, vertex, px, py, a, b = (
        edge[in_box],
        vertex[in_box],
        px[in_box],
        py[in_box],
        a[in_box],
        b[in_box],
    )
    ax, ay, bx, by = wx[a], wy[a], wx[b], wy[b]
    at_end = ((px == ax) & (py == ay)) | ((px == bx) & (py == by))
    touching[poly_of[vertex[at_end]]] = True
    inner = np.flatnonzero(~at_end)
    if len(inner):
        i = inner
        on_line = orient_many(ax[i], ay[i], bx[i], by[i], px[i], py[i]) == 0
        touching[poly_of[vertex[i[on_line]]]] = True
    return touching


def net_areas(flat: FlatRings, wx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per polygon: twice its net area in the working plane (outer ring less islands, taken
    from its first vertex) and the sum of the shoelace products' magnitudes."""
    count = len(flat.handled)
    nv = len(wx)
    if nv == 0:
        return np.zeros(count), np.zeros(count)
    wy = flat.vy
    has = flat.poly_rings > 0
    first = flat.ring_start[flat.poly_ring0[has]]
    x0 = np.zeros(count)
    y0 = np.zeros(count)
    x0[has], y0[has] = wx[first], wy[first]
    # each polygon's vertices are contiguous, poly_vcount of them
    x = wx - np.repeat(x0, flat.poly_vcount)
    y = wy - np.repeat(y0, flat.poly_vcount)
    start = flat.ring_start
    left, right = shoelace_products(x, y, start, start + flat.ring_len - 1)
    terms = left - right
    # traversal order: reversed islands count with the opposite sign
    if flat.ring_reversed.any():
        terms *= np.repeat(np.where(flat.ring_reversed, -1.0, 1.0), flat.ring_len)
    poly_of = np.repeat(flat.ring_poly, flat.ring_len)
    net = np.bincount(poly_of, weights=terms, minlength=count)
    np.abs(left, out=left)
    np.abs(right, out=right)
    left += right
    magnitude = np.bincount(poly_of, weights=left, minlength=count)
    return net, magnitude


def clear_area(flat: FlatRings, wx: np.ndarray, areas: tuple | None = None) -> np.ndarray:
    """Per polygon: its net area (outer ring less islands) is surely not negligible in the
    engine's sense (``tree.one_polygon.negligible_area``: within 8 eps of the shoelace magnitudes);
    False also where that is too close to call here. ``areas``: :func:`net_areas`, if
    known."""
    if len(wx) == 0:
        return np.zeros(len(flat.handled), dtype=bool)
    net, magnitude = net_areas(flat, wx) if areas is None else areas
    return area_surely_clear(net, magnitude, flat.poly_vcount)
