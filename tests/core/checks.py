"""Exact checks of a triangulation against the polygon it came from.

Used by every core test. Sign decisions are exact: orientations are computed in float64 in
bulk and recomputed with ``fractions.Fraction`` wherever the float result is within its error
bound (Shewchuk's orient2d bound), areas are summed as exact rationals.

No-overlap is proven through the boundary chain: when every triangle is counter-clockwise and
the sum of the triangles' directed edges equals the polygon's directed boundary (outer ring
counter-clockwise, islands clockwise), every point off the edges is covered by exactly as many
triangles as the boundary winds around it, i.e. once inside and never outside. Where the chain
does not cancel symbolically (collinear vertices splitting a side), the unmatched segments are
split at the vertices lying on them and matched again; only if that fails too are triangle
pairs searched for an actual overlap, to name it in the message.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

Ring = Sequence[Sequence[float]]
XY = tuple[float, float]

_ORIENT_ERR = 3.3306690738754716e-16  # (3 + 16 eps) eps, Shewchuk's ccwerrboundA


# --- rings ---------------------------------------------------------------------------------------


def clean_ring(ring: Ring) -> list[tuple[float, ...]]:
    """Consecutive XY duplicates merged (first kept) and the closing point dropped."""
    out: list[tuple[float, ...]] = []
    for point in ring:
        p = tuple(float(c) for c in point)
        if out and out[-1][:2] == p[:2]:
            continue
        out.append(p)
    while len(out) > 1 and out[-1][:2] == out[0][:2]:
        out.pop()
    return out


def exact_area2(ring: Sequence[Sequence[float]]) -> Fraction:
    """Twice the signed area of a ring, exact."""
    if len(ring) < 3:
        return Fraction(0)
    ix, scale_x = _exact_integers([p[0] for p in ring])
    iy, scale_y = _exact_integers([p[1] for p in ring])
    return Fraction(_area2_int(ix, iy), scale_x * scale_y)


def _exact_integers(values: Sequence[float]) -> tuple[list[int], int]:
    """The values times one common power of two, as exact integers, and that power."""
    ratios = [float(v).as_integer_ratio() for v in values]
    scale = max((d for _, d in ratios), default=1)
    return [n * (scale // d) for n, d in ratios], scale


def _area2_int(xs: Sequence[int], ys: Sequence[int]) -> int:
    n = len(xs)
    return sum(xs[i] * ys[(i + 1) % n] - xs[(i + 1) % n] * ys[i] for i in range(n))


def used_rings(rings: Sequence[Ring]) -> list[list[tuple[float, ...]]]:
    """The rings the triangulation must honour: a non-degenerate outer ring and islands.

    Empty when the outer ring has fewer than 3 distinct points or zero area; islands with fewer
    than 3 distinct points or zero area are left out.
    """
    cleaned = [clean_ring(r) for r in rings]
    if not cleaned or len(cleaned[0]) < 3 or exact_area2(cleaned[0]) == 0:
        return []
    return [cleaned[0]] + [r for r in cleaned[1:] if len(r) >= 3 and exact_area2(r) != 0]


# --- exact orientation in bulk -------------------------------------------------------------------


def orient_signs(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Exact sign of orient(a, b, c) for rows of (k, 2) arrays: +1 when c is left of a -> b."""
    acx, acy = a[:, 0] - c[:, 0], a[:, 1] - c[:, 1]
    bcx, bcy = b[:, 0] - c[:, 0], b[:, 1] - c[:, 1]
    left, right = acx * bcy, acy * bcx
    det = left - right
    signs = np.sign(det).astype(np.int8)
    unsure = np.abs(det) <= _ORIENT_ERR * (np.abs(left) + np.abs(right))
    unsure &= (left != 0) | (right != 0)
    for i in np.flatnonzero(unsure):
        ax, ay, bx, by, cx, cy = (
            Fraction(float(v)) for v in (a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1])
        )
        exact = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)
        signs[i] = (exact > 0) - (exact < 0)
    return signs


def _points_strictly_inside(p: XY, q: XY, points: np.ndarray) -> list[XY]:
    """Points (rows of ``points``) in the relative interior of segment pq, ordered from p."""
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    box = np.all((points >= lo) & (points <= hi), axis=1)
    cand = points[box]
    cand = cand[~(np.all(cand == p, axis=1) | np.all(cand == q, axis=1))]
    if len(cand) == 0:
        return []
    pa = np.broadcast_to(np.asarray(p, dtype=float), cand.shape)
    qa = np.broadcast_to(np.asarray(q, dtype=float), cand.shape)
    on = cand[orient_signs(pa, qa, cand) == 0]
    axis = 0 if p[0] != q[0] else 1
    ordered = sorted(on.tolist(), key=lambda r: r[axis], reverse=p[axis] > q[axis])
    return [(r[0], r[1]) for r in ordered]


# --- counts --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PolygonCounts:
    """V distinct vertices, B boundary segments after splitting, h islands, expected triangles."""

    vertices: int
    segments: int
    islands: int

    @property
    def triangles(self) -> int:
        return 2 * self.vertices - self.segments - 2 + 2 * self.islands


def polygon_counts(rings: Sequence[Ring]) -> PolygonCounts:
    """V, B and h of docs/algorithm.md section 2 for the rings the engine keeps."""
    kept = used_rings(rings)
    if not kept:
        return PolygonCounts(0, 0, 0)
    points = np.unique(np.array([p[:2] for r in kept for p in r], dtype=float), axis=0)
    by_x = points[np.argsort(points[:, 0], kind="stable")]
    starts = np.array([p[:2] for r in kept for p in r], dtype=float)
    ends = np.array([p[:2] for r in kept for p in r[1:] + r[:1]], dtype=float)
    # candidate (edge, point) pairs: the point's x within the edge's x range
    lo = np.searchsorted(by_x[:, 0], np.minimum(starts[:, 0], ends[:, 0]), side="left")
    hi = np.searchsorted(by_x[:, 0], np.maximum(starts[:, 0], ends[:, 0]), side="right")
    counts = hi - lo
    edge = np.repeat(np.arange(len(starts)), counts)
    point = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    point = by_x[np.repeat(lo, counts) + point]
    a, b = starts[edge], ends[edge]
    inside = (point[:, 1] >= np.minimum(a[:, 1], b[:, 1])) & (
        point[:, 1] <= np.maximum(a[:, 1], b[:, 1])
    )
    inside &= ~(np.all(point == a, axis=1) | np.all(point == b, axis=1))
    on_edge = orient_signs(a[inside], b[inside], point[inside]) == 0
    return PolygonCounts(len(points), len(starts) + int(on_edge.sum()), len(kept) - 1)


# --- deviation -----------------------------------------------------------------------------------


def deviation(rings: Sequence[Ring], vertices: np.ndarray, triangles: np.ndarray) -> float:
    """earcut's deviation, computed exactly: |triangle area - polygon area| / polygon area.

    The polygon area is |outer| minus the |islands| of the rings as given (earcut's definition).
    All coordinates are scaled by one power of two into integers, which keeps the ratio exact.
    """
    sizes = [len(r) for r in rings]
    xs, _ = _exact_integers([p[0] for r in rings for p in r] + vertices[:, 0].tolist())
    ys, _ = _exact_integers([p[1] for r in rings for p in r] + vertices[:, 1].tolist())
    polygon = 0
    offset = 0
    for number, size in enumerate(sizes):
        area = abs(_area2_int(xs[offset : offset + size], ys[offset : offset + size]))
        polygon += area if number == 0 else -area
        offset += size
    vx, vy = xs[offset:], ys[offset:]
    total = 0
    for a, b, c in np.asarray(triangles).tolist():
        total += abs((vx[b] - vx[a]) * (vy[c] - vy[a]) - (vy[b] - vy[a]) * (vx[c] - vx[a]))
    if polygon == 0 and total == 0:
        return 0.0
    if polygon == 0:
        return float("inf")
    return float(abs(Fraction(total - polygon, polygon)))


# --- individual checks ---------------------------------------------------------------------------


def check_vertices(
    rings: Sequence[Ring], vertices: np.ndarray, triangles: np.ndarray, crossings: bool = False
) -> None:
    """Every triangle corner is an input vertex (x, y, and z, 0 where the input has none).

    With ``crossings`` (invalid input that was repaired) a corner may also be a point where
    two input edges cross: it must lie on at least two of them (to 1e-9 of their length).
    """
    allowed = set()
    for ring in rings:
        for point in ring:
            p = tuple(float(c) for c in point)
            allowed.add((p[0], p[1], p[2] if len(p) > 2 else 0.0))
    assert vertices.ndim == 2 and vertices.shape[1] == 3, f"vertices shape {vertices.shape}"
    if len(triangles) == 0:
        return
    assert triangles.min() >= 0 and triangles.max() < len(vertices), "index out of range"
    used = np.unique(triangles.ravel())
    bad = [tuple(vertices[i]) for i in used if tuple(float(c) for c in vertices[i]) not in allowed]
    if crossings and bad:
        edges = _edges(rings)
        bad = [p for p in bad if _edges_through(edges, p[:2]) < 2]
    assert not bad, f"{len(bad)} triangle corners are not input vertices, e.g. {bad[:3]}"


def _edges(rings: Sequence[Ring]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every edge of the rings of 2 points or more, built once for all the points tested: starts
    (k, 2), vectors to the next point (k, 2) and squared lengths (k,)."""
    starts, vectors = [np.zeros((0, 2))], [np.zeros((0, 2))]
    for ring in rings:
        pts = np.asarray([(float(q[0]), float(q[1])) for q in ring])
        if len(pts) < 2:
            continue
        starts.append(pts)
        vectors.append(np.roll(pts, -1, axis=0) - pts)
    a, ab = np.concatenate(starts), np.concatenate(vectors)
    return a, ab, (ab**2).sum(axis=1)


def _edges_through(edges: tuple[np.ndarray, np.ndarray, np.ndarray], point: XY) -> int:
    """How many of ``edges`` (from ``_edges``) pass within 1e-9 of their length of ``point``."""
    a, ab, length2 = edges
    px, py = point
    ok = length2 > 0
    safe = np.where(ok, length2, 1)
    t = np.clip(((px - a[:, 0]) * ab[:, 0] + (py - a[:, 1]) * ab[:, 1]) / safe, 0, 1)
    dist = np.hypot(a[:, 0] + t * ab[:, 0] - px, a[:, 1] + t * ab[:, 1] - py)
    return int(np.sum(ok & (dist <= 1e-9 * np.sqrt(safe))))


def check_ccw(vertices: np.ndarray, triangles: np.ndarray, allow_zero_area: bool = False) -> None:
    """Every triangle is counter-clockwise in XY (exact), with non-zero area unless allowed.

    Zero-area triangles are allowed for invalid input triangulated as given, where they drop
    zero-width spikes and pinches; a clockwise triangle is never allowed.
    """
    if len(triangles) == 0:
        return
    xy = vertices[:, :2]
    signs = orient_signs(xy[triangles[:, 0]], xy[triangles[:, 1]], xy[triangles[:, 2]])
    bad = np.flatnonzero(signs < 0 if allow_zero_area else signs <= 0)
    assert len(bad) == 0, (
        f"{len(bad)} triangles degenerate or clockwise, e.g. #{bad[:5].tolist()}: "
        f"{[vertices[triangles[i]][:, :2].tolist() for i in bad[:2]]}"
    )


def _chain_residual(edges: Counter) -> Counter:
    return Counter({k: v for k, v in edges.items() if v != 0})


def _add_edge(chain: Counter, p: XY, q: XY, weight: int) -> None:
    if p == q:
        return
    if p < q:
        chain[(p, q)] += weight
    else:
        chain[(q, p)] -= weight


def boundary_mismatch(rings: Sequence[Ring], vertices: np.ndarray, triangles: np.ndarray) -> list:
    """Directed segments where the triangles' edges and the polygon boundary disagree.

    Empty means the triangles tile the polygon exactly (given they are all counter-clockwise).
    """
    kept = used_rings(rings)
    chain: Counter = Counter()
    xy = [(float(x), float(y)) for x, y in vertices[:, :2]]
    for a, b, c in np.asarray(triangles).tolist():
        _add_edge(chain, xy[a], xy[b], 1)
        _add_edge(chain, xy[b], xy[c], 1)
        _add_edge(chain, xy[c], xy[a], 1)
    for number, ring in enumerate(kept):
        positive = exact_area2(ring) > 0
        ccw_wanted = number == 0
        pts = [(p[0], p[1]) for p in ring]
        if positive != ccw_wanted:
            pts = pts[::-1]
        for i in range(len(pts)):
            _add_edge(chain, pts[i], pts[(i + 1) % len(pts)], -1)
    residual = _chain_residual(chain)
    if not residual:
        return []
    all_points = np.unique(
        np.array([p[:2] for r in kept for p in r] + xy, dtype=float).reshape(-1, 2), axis=0
    )
    split: Counter = Counter()
    for (p, q), weight in residual.items():
        path = [p, *_points_strictly_inside(p, q, all_points), q]
        for s, t in zip(path, path[1:]):
            _add_edge(split, s, t, weight)
    return sorted(_chain_residual(split).items())


def overlapping_pairs(
    vertices: np.ndarray, triangles: np.ndarray, suspects: np.ndarray | None = None, limit: int = 10
) -> list[tuple[int, int]]:
    """Pairs of CCW triangles whose interiors intersect (exact separating-axis test).

    Each of ``suspects`` (default: all triangles) is tested against every triangle whose
    bounding box meets its own; at most ``limit`` pairs are returned.
    """
    corners = vertices[:, :2][np.asarray(triangles)]  # (M, 3, 2)
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    found: set[tuple[int, int]] = set()
    for i in range(len(corners)) if suspects is None else np.asarray(suspects).tolist():
        near = np.all((lo <= hi[i]) & (hi >= lo[i]), axis=1)
        near[i] = False
        others = np.flatnonzero(near)
        for j in others[_interiors_intersect(corners[i], corners[others])].tolist():
            found.add((min(i, j), max(i, j)))
        if len(found) >= limit:
            break
    return sorted(found)[:limit]


def _interiors_intersect(tri: np.ndarray, others: np.ndarray) -> np.ndarray:
    """For CCW ``tri`` (3, 2) and CCW ``others`` (K, 3, 2): do the interiors intersect?

    Two convex polygons have disjoint interiors iff a side of one has the other on its outer
    closed side.
    """
    k = len(others)
    separated = np.zeros(k, dtype=bool)
    for e in range(3):
        a = np.broadcast_to(tri[e], (k, 2))
        b = np.broadcast_to(tri[(e + 1) % 3], (k, 2))
        outside = np.ones(k, dtype=bool)
        for c in range(3):
            outside &= orient_signs(a, b, others[:, c]) <= 0
        separated |= outside
    for e in range(3):
        a, b = others[:, e], others[:, (e + 1) % 3]
        outside = np.ones(k, dtype=bool)
        for c in range(3):
            outside &= orient_signs(a, b, np.broadcast_to(tri[c], (k, 2))) <= 0
        separated |= outside
    return ~separated


def check_tiling(rings: Sequence[Ring], vertices: np.ndarray, triangles: np.ndarray) -> None:
    """The triangles cover the polygon exactly once: no overlap, no gap (needs CCW triangles)."""
    residual = boundary_mismatch(rings, vertices, triangles)
    if not residual:
        return
    # an overlap or a gap leaves unmatched segments along its border: search next to them
    ends = {p for (a, b), _ in residual for p in (a, b)}
    xy = [tuple(p) for p in vertices[:, :2].tolist()]
    suspects = [
        t for t, tri in enumerate(np.asarray(triangles).tolist()) if any(xy[v] in ends for v in tri)
    ]
    pairs = overlapping_pairs(vertices, triangles, suspects)
    assert not pairs, f"overlapping triangles {pairs}: {[triangles[i].tolist() for i in pairs[0]]}"
    raise AssertionError(f"triangles do not tile the polygon; unmatched segments {residual[:6]}")


def check_forest(
    triangles: np.ndarray, parent: np.ndarray, depth: np.ndarray, side: np.ndarray
) -> None:
    """Several BSP trees one after another (the parts of a repaired polygon), each consistent
    and in pre-order; the base convention at the root is not checked (parts come re-ordered).
    """
    roots = [*np.flatnonzero(np.asarray(parent) < 0).tolist(), len(triangles)]
    assert len(triangles) == 0 or roots[0] == 0, "first triangle is not a root"
    for start, stop in zip(roots[:-1], roots[1:]):
        sub = slice(start, stop)
        rebased = np.where(parent[sub] < 0, -1, parent[sub] - start)
        check_tree(triangles[sub], rebased, depth[sub], side[sub], check_bases=False)


def check_tree(
    triangles: np.ndarray,
    parent: np.ndarray,
    depth: np.ndarray,
    side: np.ndarray,
    check_bases: bool = True,
) -> None:
    """The BSP tree is consistent and listed in pre-order.

    Parent earlier and on the current root path, left subtree before the right one, at most one
    child per side, depth = parent's depth + 1, and the bases: tracking each node's (V1, V2)
    from the root's, a left child has base (V1, apex) and a right child (V2, apex) of its
    parent. The root's V1 is s0, normally vertex 0; for inputs where S does not start at
    vertex 0 (the engine may drop zero-width spikes of invalid rings) the other order is tried.
    """
    m = len(triangles)
    for name, arr in (("parent", parent), ("depth", depth), ("side", side)):
        assert len(arr) == m, f"{name} has {len(arr)} entries for {m} triangles"
    if m == 0:
        return
    tris = np.asarray(triangles).tolist()
    assert parent[0] == -1 and depth[0] == 0 and side[0] == 0, "first triangle is not the root"
    children: dict[int, dict[int, int]] = {0: {}}
    path = [0]  # the root-to-current chain; in pre-order a parent is on it
    for i in range(1, m):
        p, s = int(parent[i]), int(side[i])
        assert 0 <= p < i, f"triangle {i}: parent {p} not earlier"
        assert s in (1, 2), f"triangle {i}: side {s}"
        assert depth[i] == depth[p] + 1, f"triangle {i}: depth {depth[i]} vs parent {depth[p]}"
        while path and path[-1] != p:
            path.pop()
        assert path, f"triangle {i}: parent {p} is not an ancestor chain node (not pre-order)"
        assert s not in children[p], f"triangle {i}: parent {p} has two children on side {s}"
        assert not (s == 1 and 2 in children[p]), f"triangle {i}: left child after right sibling"
        children[p][s] = i
        children[i] = {}
        path.append(i)
    if not check_bases:
        return
    a, b = tris[0][:2]
    first = _base_mismatch(tris, parent, side, (b, a) if b == 0 else (a, b))
    if first is not None and 0 not in (a, b) and _base_mismatch(tris, parent, side, (b, a)) is None:
        return
    assert first is None, first


def _base_mismatch(
    tris: list, parent: np.ndarray, side: np.ndarray, root: tuple[int, int]
) -> str | None:
    """The first child whose base is not (V1, apex) or (V2, apex) of its parent, or None."""
    bases: list[tuple[int, int]] = [root]
    for i in range(1, len(tris)):
        p, s = int(parent[i]), int(side[i])
        v1, v2 = bases[p]
        apex = tris[p][2]
        base = (v1, apex) if s == 1 else (v2, apex)
        if set(tris[i][:2]) != set(base):
            return f"triangle {i} {tris[i]}: base is not {base} from parent {p} {tris[p]}, side {s}"
        bases.append(base)
    return None


# --- everything at once --------------------------------------------------------------------------


def check_triangulation(
    rings: Sequence[Ring], result, *, valid: bool = True, expect_count: bool = True
) -> PolygonCounts | None:
    """All checks on ``result`` (a Triangulation) for ``rings``; returns the counts it used.

    ``valid``: the input is a valid polygon, so the triangles must tile it exactly, have zero
    deviation and (with ``expect_count``) number 2V - B - 2 + 2h.
    """
    vertices = np.asarray(result.vertices, dtype=float)
    triangles = np.asarray(result.triangles, dtype=np.int64).reshape(-1, 3)
    check_vertices(rings, vertices, triangles, crossings=not valid)
    check_ccw(vertices, triangles, allow_zero_area=not valid)
    tree = (np.asarray(result.parent), np.asarray(result.depth), np.asarray(result.side))
    if valid:
        check_tree(triangles, *tree)
    else:
        check_forest(triangles, *tree)
    if not valid:
        return None
    check_tiling(rings, vertices, triangles)
    dev = deviation([clean_ring(r) for r in rings], vertices, triangles)
    assert dev == 0, f"deviation {dev}"
    counts = polygon_counts(rings)
    if expect_count:
        assert len(triangles) == counts.triangles, (
            f"{len(triangles)} triangles, expected 2V-B-2+2h = {counts.triangles} ({counts})"
        )
    return counts
