"""Reference BSP triangulation: a slow, literal reading of docs/algorithm.md.

Written independently from the engine (it imports nothing from it) so that the engine can be
compared with it triangle by triangle. Every predicate is exact: coordinates are turned into
Python integers by one common power-of-two scale, which changes no sign of any determinant.
The cost is O(n^3) per polygon, fine for the small polygons the tests feed it.

Scope: an outer ring whose working plane is XY (a ring with Z whose Newell normal is dominated
by x or y raises ``NotImplementedError``), planar tolerance 0. Touching rings, shared-edge
spikes and the apex-angle condition follow docs/algorithm.md sections 2 and 4.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from fractions import Fraction

Point = tuple[int, int]


class NoCorrectTriangle(Exception):  # noqa: N818 - named after the paper's notion
    """A sub-polygon has no candidate forming a correct triangle."""


@dataclass
class ReferenceResult:
    """Triangles in pre-order, with the same meaning as the engine's ``Triangulation``."""

    vertices: list[tuple[float, float, float]] = field(default_factory=list)
    triangles: list[tuple[int, int, int]] = field(default_factory=list)
    parent: list[int] = field(default_factory=list)
    depth: list[int] = field(default_factory=list)
    side: list[int] = field(default_factory=list)


# --- exact predicates on integer points ---------------------------------------------------------


def orient(a: Point, b: Point, c: Point) -> int:
    """Twice the signed area of (a, b, c): > 0 when c is left of a -> b."""
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def sign(value: int) -> int:
    return (value > 0) - (value < 0)


def on_open_segment(p: Point, a: Point, b: Point) -> bool:
    """True when p lies in the relative interior of segment ab (a != b)."""
    if orient(a, b, p) != 0 or p in (a, b):
        return False
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


def segment_meets_open_segment(a: Point, b: Point, p: Point, q: Point) -> bool:
    """True when closed segment ab has a point in the open segment pq (p != q)."""
    o1, o2 = sign(orient(p, q, a)), sign(orient(p, q, b))
    o3, o4 = sign(orient(a, b, p)), sign(orient(a, b, q))
    if o1 == 0 and o2 == 0:  # all four collinear: compare projections on pq's main axis
        axis = 0 if p[0] != q[0] else 1
        lo, hi = sorted((p[axis], q[axis]))
        s_lo, s_hi = sorted((a[axis], b[axis]))
        return s_hi > lo and s_lo < hi
    if o1 * o2 > 0 or o3 * o4 > 0:
        return False
    if a == b:  # a degenerate segment not on line pq cannot meet it
        return False
    # The closed segments meet in exactly one point; it is p or q iff p or q lies on line ab.
    return o3 != 0 and o4 != 0


def segment_meets_open_triangle(a: Point, b: Point, tri: tuple[Point, Point, Point]) -> bool:
    """True when closed segment ab has a point in the open interior of CCW triangle ``tri``.

    Each side of the triangle keeps an open interval of the parameter t of a + t (b - a);
    the segment meets the interior iff [0, 1] and all three intervals share a point.
    """
    lower: Fraction | int = 0
    upper: Fraction | int = 1
    for i in range(3):
        e0, e1 = tri[i], tri[(i + 1) % 3]
        f0, f1 = orient(e0, e1, a), orient(e0, e1, b)
        if f0 <= 0 and f1 <= 0:
            return False
        d = f1 - f0
        if d > 0:
            lower = max(lower, Fraction(-f0, d))
        elif d < 0:
            upper = min(upper, Fraction(f0, -d))
    return lower < upper


def inside_interior_angle(prev: Point, at: Point, nxt: Point, target: Point) -> bool:
    """True when the direction at -> target points strictly into the interior angle at ``at``.

    The polygon is counter-clockwise: the interior angle sweeps from (nxt - at) counter-
    clockwise to (prev - at).
    """
    u = (nxt[0] - at[0], nxt[1] - at[1])
    w = (prev[0] - at[0], prev[1] - at[1])
    d = (target[0] - at[0], target[1] - at[1])

    def cross(x: tuple[int, int], y: tuple[int, int]) -> int:
        return x[0] * y[1] - x[1] * y[0]

    turn = cross((at[0] - prev[0], at[1] - prev[1]), u)
    straight = turn == 0 and (u[0] * w[0] + u[1] * w[1]) < 0
    if turn > 0 or straight:  # convex or straight: inside the cone from u to w
        return cross(u, d) > 0 and cross(d, w) > 0
    # reflex: anywhere outside the closed exterior cone from w to u
    return not (cross(w, d) >= 0 and cross(d, u) >= 0)


# --- normalisation -------------------------------------------------------------------------------


def normalise_ring(ring: Sequence[Sequence[float]]) -> list[tuple[float, float, float]]:
    """Points as (x, y, z); consecutive XY duplicates merged (first kept); closing point dropped."""
    out: list[tuple[float, float, float]] = []
    for point in ring:
        x, y = float(point[0]), float(point[1])
        z = float(point[2]) if len(point) > 2 else 0.0
        if out and (out[-1][0], out[-1][1]) == (x, y):
            continue
        out.append((x, y, z))
    while len(out) > 1 and (out[-1][0], out[-1][1]) == (out[0][0], out[0][1]):
        out.pop()
    return out


def _area2(points: Sequence[Point]) -> int:
    n = len(points)
    return sum(
        points[i][0] * points[(i + 1) % n][1] - points[(i + 1) % n][0] * points[i][1]
        for i in range(n)
    )


def xy_is_working_plane(ring: Sequence[tuple[float, float, float]]) -> bool:
    """True when the ring's Newell normal is not dominated by its x or y component."""
    nx = ny = nz = Fraction(0)
    n = len(ring)
    for i in range(n):
        x0, y0, z0 = (Fraction(c) for c in ring[i])
        x1, y1, z1 = (Fraction(c) for c in ring[(i + 1) % n])
        nx += (y0 - y1) * (z0 + z1)
        ny += (z0 - z1) * (x0 + x1)
        nz += (x0 - x1) * (y0 + y1)
    return abs(nx) <= abs(nz) and abs(ny) <= abs(nz)


def _integer_scale(values: Sequence[float]) -> int:
    """A power of two that turns every value into an integer."""
    scale = 1
    for value in values:
        scale = max(scale, value.as_integer_ratio()[1])
    return scale


# --- bridges -------------------------------------------------------------------------------------


def split_touching(rings: list[list[int]], pts: list[Point]) -> list[list[int]]:
    """Split every ring edge at the vertices (of any ring) lying in its relative interior.

    One vertex per distinct point is inserted (the lowest index), ordered from the edge's start.
    """
    first_index: dict[Point, int] = {}
    for ring in rings:
        for v in ring:
            first_index.setdefault(pts[v], v)
    out = []
    for ring in rings:
        split: list[int] = []
        for i, v in enumerate(ring):
            a, b = pts[v], pts[ring[(i + 1) % len(ring)]]
            split.append(v)
            inside = [p for p in first_index if on_open_segment(p, a, b)]
            inside.sort(key=lambda p: (p[0] - a[0]) ** 2 + (p[1] - a[1]) ** 2)
            split.extend(first_index[p] for p in inside)
        out.append(split)
    return out


def cancel_spikes(seq: list[int], pts: list[Point]) -> list[int]:
    """Cancel every edge walked straight back (p, s, p -> p), repeatedly and cyclically."""
    seq = list(seq)
    changed = True
    while changed and len(seq) >= 2:
        changed = False
        n = len(seq)
        for i in range(n):
            if pts[seq[i - 1]] == pts[seq[(i + 1) % n]]:
                drop = {i, (i + 1) % n}
                seq = [v for k, v in enumerate(seq) if k not in drop]
                changed = True
                break
    return seq


def _bridge_is_valid(
    seq: list[int],
    k: int,
    h: int,
    edges: list[tuple[int, int]],
    points: list[int],
    pts: list[Point],
) -> bool:
    p, q = pts[seq[k]], pts[h]
    for a, b in edges:
        if segment_meets_open_segment(pts[a], pts[b], p, q):
            return False
    if any(on_open_segment(pts[v], p, q) for v in points):
        return False
    prev, nxt = pts[seq[k - 1]], pts[seq[(k + 1) % len(seq)]]
    return inside_interior_angle(prev, p, nxt, q)


def _ring_edges(ring: list[int]) -> list[tuple[int, int]]:
    return [(ring[i], ring[(i + 1) % len(ring)]) for i in range(len(ring))]


def _splice(seq: list[int], k: int, loop: list[int]) -> list[int]:
    """Insert the island ``loop`` (h ... h) after occurrence k; at the end when k == 0."""
    if k == 0:  # keeps S starting with the outer ring's first two vertices
        return [*seq, seq[0], *loop]
    return [*seq[: k + 1], *loop, seq[k], *seq[k + 1 :]]


def _splice_touching(seq: list[int], k: int, loop: list[int]) -> list[int]:
    """Splice the island ``loop`` (h ... h-1) at occurrence k of h's point, no duplication."""
    if k == 0:
        return [*seq, *loop]
    return [*seq[: k + 1], *loop[1:], loop[0], *seq[k + 1 :]]


def bridge(outer: list[int], islands: list[list[int]], pts: list[Point]) -> list[int]:
    """The bridged vertex sequence S (vertex indices) of the outer ring and the islands.

    Order: while some island shares a point with S, the one with the smallest leftmost vertex
    among them is joined at its smallest shared point; otherwise the next island in leftmost
    order is joined from its leftmost vertex. The bridge goes to the nearest valid occurrence
    (a shared point is at distance 0 and valid where the closed interior angle of that
    occurrence holds both island edges at h), ties to the smallest k.
    """
    seq = list(outer)
    rank = sorted(range(len(islands)), key=lambda i: (min(pts[v] for v in islands[i]), i))
    joined: set[int] = set()
    while len(joined) < len(islands):
        in_seq = {pts[v] for v in seq}
        touching = [
            i for i in rank if i not in joined and any(pts[v] in in_seq for v in islands[i])
        ]
        number = touching[0] if touching else next(i for i in rank if i not in joined)
        island = islands[number]
        corners = [pts[v] for v in island if pts[v] in in_seq] if touching else []
        target = min(corners) if corners else min(pts[v] for v in island)
        start = next(i for i, v in enumerate(island) if pts[v] == target)
        loop = [*island[start:], *island[:start]]
        h = loop[0]
        edges = _ring_edges(seq)
        points = list(seq)
        for other in range(len(islands)):
            if other not in joined:
                edges += _ring_edges(islands[other])
                points += islands[other]
        best: tuple[int, int] | None = None
        q = pts[h]
        for k in range(len(seq)):
            p = pts[seq[k]]
            prev, nxt = pts[seq[k - 1]], pts[seq[(k + 1) % len(seq)]]
            if p == q:  # the occurrence must hold the island's corner at h
                valid = all(within_closed_angle(prev, p, nxt, pts[t]) for t in (loop[1], loop[-1]))
            else:
                valid = _bridge_is_valid(seq, k, h, edges, points, pts)
            dist = (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2
            if valid and (best is None or dist < best[0]):
                best = (dist, k)
        if best is None:
            raise NoCorrectTriangle(f"island {number} has no valid bridge")
        if best[0] == 0:
            seq = _splice_touching(seq, best[1], loop)
        else:
            seq = _splice(seq, best[1], [*loop, h])
        joined.add(number)
    return seq


# --- the BSP tree --------------------------------------------------------------------------------


def within_closed_angle(prev: Point, at: Point, nxt: Point, target: Point) -> bool:
    """True when the direction at -> target lies in the closed interior angle at ``at``.

    A spike (prev and nxt in the same direction) counts as a full turn.
    """
    u = (nxt[0] - at[0], nxt[1] - at[1])
    w = (prev[0] - at[0], prev[1] - at[1])
    d = (target[0] - at[0], target[1] - at[1])

    def cross(x: tuple[int, int], y: tuple[int, int]) -> int:
        return x[0] * y[1] - x[1] * y[0]

    turn = cross((at[0] - prev[0], at[1] - prev[1]), u)
    if turn > 0:
        return cross(u, d) >= 0 and cross(d, w) >= 0
    if turn < 0:
        return not (cross(w, d) > 0 and cross(d, u) > 0)
    if u[0] * w[0] + u[1] * w[1] < 0:  # straight
        return cross(u, d) >= 0
    return True


def is_correct_triangle(seq_pts: list[Point], lo: int, hi: int, j: int) -> bool:
    """Section 4 of docs/algorithm.md for candidate s_j of the sub-polygon s_lo ... s_hi.

    Conditions 1-3 as documented, plus: both new sides leave s_j inside the closed interior
    angle of the sequence at position j. For a simple sub-polygon this follows from 1-3; it
    tells duplicate occurrences of one point apart (bridge ends), where 1-3 alone accept an
    occurrence whose chord cuts the island's loop off to the wrong side.
    """
    v_hi, v_lo, c = seq_pts[hi], seq_pts[lo], seq_pts[j]
    if orient(v_hi, v_lo, c) <= 0:
        return False
    prev, nxt = seq_pts[j - 1], seq_pts[j + 1]
    if not (within_closed_angle(prev, c, nxt, v_hi) and within_closed_angle(prev, c, nxt, v_lo)):
        return False
    tri = (v_hi, v_lo, c)
    for i in range(lo, hi):
        if segment_meets_open_triangle(seq_pts[i], seq_pts[i + 1], tri):
            return False
    for i in range(lo, hi + 1):
        if i in (lo, hi, j):
            continue
        p = seq_pts[i]
        if on_open_segment(p, v_lo, c) or on_open_segment(p, v_hi, c):
            return False
    return True


def _choose_apex(
    seq_pts: list[Point], seq_z: list[float], lo: int, hi: int, v1: int, v2: int, rule: str
) -> int:
    candidates = range(hi - 1, lo, -1)
    if rule == "first":
        for j in candidates:
            if is_correct_triangle(seq_pts, lo, hi, j):
                return j
        raise NoCorrectTriangle(f"no correct triangle on sub-polygon [{lo}, {hi}]")
    if rule != "elevation":
        raise ValueError(f"unknown rule {rule!r}")
    target = Fraction(seq_z[v1]) + Fraction(seq_z[v2])
    best: tuple[Fraction, int] | None = None
    for j in candidates:
        if is_correct_triangle(seq_pts, lo, hi, j):
            gap = abs(2 * Fraction(seq_z[j]) - target)
            if best is None or gap < best[0]:
                best = (gap, j)
    if best is None:
        raise NoCorrectTriangle(f"no correct triangle on sub-polygon [{lo}, {hi}]")
    return best[1]


def reference_triangulate(
    rings: Sequence[Sequence[Sequence[float]]], *, rule: str = "first"
) -> ReferenceResult:
    """Triangulate ``rings`` (outer ring first) exactly as docs/algorithm.md prescribes."""
    normalised = [normalise_ring(ring) for ring in rings]
    # every normalised ring is in ``vertices``, also the islands that are ignored
    vertices = [p for ring in normalised for p in ring]
    if not normalised or len(normalised[0]) < 3:
        return ReferenceResult(vertices=vertices)
    if not xy_is_working_plane(normalised[0]):  # the outer ring decides for all rings
        raise NotImplementedError("walls (non-XY working plane) are out of the oracle's scope")
    scale = _integer_scale([c for ring in normalised for p in ring for c in p[:2]])
    pts = [(int(Fraction(p[0]) * scale), int(Fraction(p[1]) * scale)) for p in vertices]
    index_rings: list[list[int]] = []
    offset = 0
    for number, ring in enumerate(normalised):
        indices = list(range(offset, offset + len(ring)))
        offset += len(ring)
        if number == 0 or (len(ring) >= 3 and _area2([pts[v] for v in indices]) != 0):
            index_rings.append(indices)
    area = _area2([pts[v] for v in index_rings[0]])
    if area == 0:
        return ReferenceResult(vertices=vertices)
    mirrored = area < 0
    if mirrored:
        pts = [(-x, y) for x, y in pts]

    oriented = [index_rings[0]]
    for ring in index_rings[1:]:
        oriented.append(ring[::-1] if _area2([pts[v] for v in ring]) > 0 else ring)
    oriented = split_touching(oriented, pts)
    islands = oriented[1:]

    seq = cancel_spikes(bridge(oriented[0], islands, pts), pts)
    if len(seq) < 3:  # everything cancelled: the islands cover the outer ring
        return ReferenceResult(vertices=vertices)
    seq = [*seq, seq[0]]  # s_m = s_0
    seq_pts = [pts[v] for v in seq]
    seq_z = [vertices[v][2] for v in seq]
    m = len(seq) - 1

    result = ReferenceResult(vertices=vertices)
    # Work list of (V1 position, V2 position, parent, depth, side); popped last-in first-out so
    # that pushing right before left yields pre-order.
    stack = [(m, 1, -1, 0, 0)]
    while stack:
        p1, p2, parent, depth, side = stack.pop()
        lo, hi = min(p1, p2), max(p1, p2)
        j = _choose_apex(seq_pts, seq_z, lo, hi, p1, p2, rule)
        first, second = (seq[lo], seq[hi]) if mirrored else (seq[hi], seq[lo])
        node = len(result.triangles)
        result.triangles.append((first, second, seq[j]))
        result.parent.append(parent)
        result.depth.append(depth)
        result.side.append(side)
        if abs(j - p2) > 1:
            stack.append((p2, j, node, depth + 1, 2))
        if abs(j - p1) > 1:
            stack.append((p1, j, node, depth + 1, 1))
    return result
