"""Long sub-polygons: candidates proven to fail, skipped without the exact test.

Seen from the base (A, B) of a sub-polygon, a point ``q`` strictly left of the chord A -> B has
two angles in (0, pi): ``alpha`` at A from A -> B counter-clockwise to A -> q, and ``beta`` at
B from B -> q counter-clockwise to B -> A. A vertex ``p`` lies strictly inside the triangle on
the base with apex ``c`` exactly when ``alpha(p) < alpha(c)`` and ``beta(p) < beta(c)``: ``c``
lies in the *shadow* of ``p``, and fails condition 2 of the correct triangle
(docs/algorithm.md, section 4). Candidates not strictly left of the chord fail condition 1.

:class:`Shadows` keeps the staircase of the vertices met so far that no other one shadows,
first those the caller adds (the vertices next to the base's ends), then while it walks the
boxes from the last candidate back. It yields, in that order, only the candidates that no
box or point test rules out; the caller tests those exactly, so the first correct candidate
is the one the full scan finds (rule "first"). Rule "elevation" asks only whether a
candidate lies in a shadow (:meth:`Shadows.shadowed`, :meth:`Shadows.shadowed_many`).
Angles are compared with a margin far above their rounding: a doubtful case is tested, never
skipped.

The base's own corners cast wider shadows. The edge from B to the next vertex leaves B at the
angle ``beta`` of that vertex: every candidate with a larger ``beta`` has that direction strictly
inside its triangle's angle at B, so the edge meets the triangle's open interior (condition 2),
whatever the candidate's ``alpha``. Likewise the edge into A for ``alpha``. These half-planes of
the (alpha, beta) plane also rule out boxes that straddle the chord's line beyond B or beyond A,
whose points near the line have an angle near 0 that no vertex's shadow covers.

An edge whose ends lie at the angles a < b seen from A (less than a half-turn apart) crosses
every ray from A at an angle strictly between a and b, within the distance r of its farther
end: every candidate at such an angle farther from A than r has the edge across its side from
A (condition 2); an edge that crosses the chord's line beyond A covers every angle from a on.
Likewise from B with ``beta``. Such *rays* come from the edges that blocked candidates and
from the edges the walk meets (two positions in a row) that cross the chord's line, kept as the
least r per angle (:class:`Horizon`); they rule out the slivers along the chord's line, which a
vertex's shadow covers only near the line's crossing, and along a long straight river the thin
triangles reaching far downstream.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Iterator

import numpy as np

from ..geometry.spatial_index import ChainBoxes, box_distance2

# Angles (radians) closer than this are not trusted to compare.
_MARGIN = 1e-9
# Points along an edge that casts its shadow (its ends' shadows do not cover each other).
_EDGE_SAMPLES = 7
_TWO_PI = 2.0 * math.pi
# Rays added per base at most (from A and B together), and the relative slack on their
# squared distances (far above the rounding of a distance beyond the trusted one).
_RAYS = 256
# the upper end of an occluder across the chord's line (beyond every angle left of it)
_BEYOND = 4.0
# cuts a range query of a Horizon walks at most (a longer one rules nothing out)
_WALK = 32
_REACH_SLACK = 1.0 + 1e-6
# radians added to a staircase step's angles for its corner Q (region_box), far above the
# margin and the rounding of the angles
_WIDEN = 1e-7
# a step whose angles leave less than this to a half-turn leaves the region unbounded
_OPEN = 1e-3
# positions walked from a reflex base corner for the edge that crosses back (region_box)
_CROSSING_WALK = 32
# share of near2 within which a vertex's angles at a base corner are not trusted
_TRUSTED_VERTEX = 2.0**-80


def _square(dx: float, dy: float) -> float:
    """dx * dx + dy * dy (inf on overflow, where ``**`` would raise)."""
    return dx * dx + dy * dy


class Horizon:
    """Occluders seen from one corner of the base: an edge whose ends lie at the angles l < h
    (less than a half-turn apart) and within the distance r of the corner crosses every ray
    from it at an angle strictly between l and h, within r; a point at such an angle and
    farther than r has the edge across its side from the corner (condition 2). Kept as the
    least squared reach per angle: sorted ``cuts`` (ends of occluders, shrunk by the
    margin), the reach over each open interval between two cuts (``between``) and at each
    cut (``at``); inf where no occluder covers."""

    def __init__(self) -> None:
        self.cuts: list[float] = []
        self.between: list[float] = []  # between cuts[i] and cuts[i + 1]
        self.at: list[float] = []

    def __bool__(self) -> bool:
        return bool(self.cuts)

    def _cut(self, angle: float) -> int:
        """Index of the cut at ``angle``, made where there is none."""
        cuts = self.cuts
        i = bisect_left(cuts, angle)
        if i < len(cuts) and cuts[i] == angle:
            return i
        # the new cut lies inside the interval i - 1 (or outside every one): its reach
        inside = self.between[i - 1] if 0 < i < len(cuts) else math.inf
        cuts.insert(i, angle)
        self.at.insert(i, inside)
        if 0 < i < len(cuts) - 1:
            self.between.insert(i, inside)
        elif i == 0 and len(cuts) > 1:
            self.between.insert(0, math.inf)
        elif i == len(cuts) - 1 and len(cuts) > 1:
            self.between.append(math.inf)
        return i

    def add(self, low: float, high: float, reach2: float) -> None:
        """An occluder over the open angles (low, high) (margins already applied)."""
        if not low < high:
            return
        first = self._cut(low)
        last = self._cut(high)
        between, at = self.between, self.at
        for i in range(first, last):
            if reach2 < between[i]:
                between[i] = reach2
        for i in range(first + 1, last):
            if reach2 < at[i]:
                at[i] = reach2

    def reach2(self, angle: float) -> float:
        """The least squared reach of an occluder covering ``angle`` (inf: none)."""
        cuts = self.cuts
        i = bisect_left(cuts, angle)
        if i < len(cuts) and cuts[i] == angle:
            return self.at[i]
        if 0 < i < len(cuts):
            return self.between[i - 1]
        return math.inf

    def reach2_over(self, low: float, high: float) -> float:
        """The largest of the least squared reaches over the angles [low, high] (inf where
        some angle there has no occluder, or where the range holds more than ``_WALK``
        cuts)."""
        cuts = self.cuts
        if not (cuts and cuts[0] < low <= high < cuts[-1]):
            return math.inf  # (also for nan angles)
        between, at = self.between, self.at
        i = bisect_right(cuts, low) - 1
        most = at[i] if cuts[i] == low else 0.0
        for _ in range(_WALK):
            most = max(most, between[i])
            i += 1
            if cuts[i] >= high:
                return most if cuts[i] > high else max(most, at[i])
            most = max(most, at[i])
            if most == math.inf:
                break
        return math.inf  # a gap, or too many cuts to walk: not ruled out


class Shadows:
    """The staircase of shadows on the base (positions ``hi`` -> ``lo``) of a sub-polygon."""

    def __init__(
        self,
        xs: list[float],
        ys: list[float],
        boxes: ChainBoxes,
        lo: int,
        hi: int,
        rays: bool = True,
    ) -> None:
        self.xs, self.ys, self.boxes, self.lo, self.hi = xs, ys, boxes, lo, hi
        ax, ay, bx, by = xs[hi], ys[hi], xs[lo], ys[lo]
        self.ax, self.ay, self.bx, self.by = ax, ay, bx, by
        self.to_b = math.atan2(by - ay, bx - ax)
        self.to_a = math.atan2(ay - by, ax - bx)
        # staircase: alphas increasing, betas decreasing
        self.alphas: list[float] = []
        self.betas: list[float] = []
        self.side: tuple[float, float, float, float] | None = None
        # the corner edges' half-plane shadows (beta beyond the edge at B, alpha beyond the
        # edge at A; inf: none), and the chord's direction, length and trusted distance
        self.corner_beta = self.corner_alpha = math.inf
        self.chord: tuple[float, float, float, float] | None = None
        # rays (module docstring): occluders seen from A and from B (``Horizon``), and
        # how many were added (none where the caller never asks, ``rays`` False)
        self.rays_a = Horizon()
        self.rays_b = Horizon()
        self.ray_count = 0 if rays else _RAYS
        # squared distance from a base end within which a computed point's angles are not
        # trusted (the coordinates' rounding, 2**-52 of their scale, over it stays far below
        # the margin)
        self.near2 = _square(boxes.pad * 2.0**12, 0.0)
        nx, ny = ay - by, bx - ax  # left of the chord A -> B
        norm = math.hypot(nx, ny)
        if 0 < norm < math.inf:
            nx, ny = nx / norm, ny / norm
            self.side = (nx, ny, nx * ax + ny * ay + boxes.pad, nx * ax + ny * ay - boxes.pad)
            self.chord = (ny, -nx, norm, math.sqrt(self.near2))
            self._corner_shadows()

    def _corner_shadows(self) -> None:
        """The half-planes ruled out by the edges at the base's corners (module docstring),
        also as the staircase's first and last points (alpha 0, beta 0)."""
        lo, hi, xs, ys = self.lo, self.hi, self.xs, self.ys
        if hi - lo < 3:
            return
        after, before = lo + 1, hi - 1
        if (xs[after], ys[after]) != (self.bx, self.by):
            beta = self.angles(xs[after], ys[after])[1]
            if _MARGIN < beta < math.pi - _MARGIN:
                self.corner_beta = beta
                self.alphas.append(0.0)
                self.betas.append(beta)
        if (xs[before], ys[before]) != (self.ax, self.ay):
            alpha = self.angles(xs[before], ys[before])[0]
            if _MARGIN < alpha < math.pi - _MARGIN:
                self.corner_alpha = alpha
                self.alphas.append(alpha)
                self.betas.append(0.0)

    def angles(self, x: float, y: float) -> tuple[float, float]:
        """(alpha, beta) of the point (x, y), each in [0, 2 pi)."""
        alpha = (math.atan2(y - self.ay, x - self.ax) - self.to_b) % _TWO_PI
        beta = (self.to_a - math.atan2(y - self.by, x - self.bx)) % _TWO_PI
        return alpha, beta

    def add(self, position: int) -> None:
        """Cast the shadow of the vertex at ``position`` if it surely lies strictly left of
        the chord (a vertex of the sub-polygon other than the base's ends)."""
        if self.lo < position < self.hi and self.side is not None:
            self._add(*self.angles(self.xs[position], self.ys[position]))

    def add_edge(self, edge: int) -> None:
        """Cast the shadows of the edge (edge, edge + 1) of the sub-polygon: those of its
        ends and, where neither end's shadow covers the other's, those of points along it (a
        point of an edge strictly inside a triangle breaks condition 2 as a vertex does)."""
        if self.side is None or not self.lo <= edge < self.hi:
            return  # neither end is a vertex strictly between the base's ends
        px, py, qx, qy = self.xs[edge], self.ys[edge], self.xs[edge + 1], self.ys[edge + 1]
        alpha_p, beta_p = self.angles(px, py)
        alpha_q, beta_q = self.angles(qx, qy)
        if edge > self.lo:
            self._add(alpha_p, beta_p)
        if edge + 1 < self.hi:
            self._add(alpha_q, beta_q)
        self._ray(px, py, qx, qy, (alpha_p, beta_p), (alpha_q, beta_q))
        if (alpha_q - alpha_p) * (beta_q - beta_p) >= 0 and max(
            alpha_p, beta_p, alpha_q, beta_q
        ) < math.pi:
            return
        # a point computed along the edge is off it by a rounding: kept only where that
        # moves its angles far less than the margin
        near = self.near2
        for k in range(1, _EDGE_SAMPLES + 1):
            t = k / (_EDGE_SAMPLES + 1)
            x, y = px + t * (qx - px), py + t * (qy - py)
            away = _square(x - self.ax, y - self.ay) > near
            if away and _square(x - self.bx, y - self.by) > near:
                self._add(*self.angles(x, y))

    def _ray(
        self,
        px: float,
        py: float,
        qx: float,
        qy: float,
        angles_p: tuple[float, float],
        angles_q: tuple[float, float],
    ) -> None:
        """Keep the edge p-q as a ray seen from A and from B (module docstring), where its
        angles there are less than a half-turn apart and its ends farther than the trusted
        distance from that corner."""
        if self.ray_count >= _RAYS:
            return
        for which, (cx, cy), rays in (
            (0, (self.ax, self.ay), self.rays_a),
            (1, (self.bx, self.by), self.rays_b),
        ):
            low, high = sorted((angles_p[which], angles_q[which]))
            if not _MARGIN < low < math.pi - _MARGIN:
                continue
            if high - low > math.pi - _MARGIN:
                continue  # it crosses the line between the corners or beyond the other one
            to_p, to_q = _square(px - cx, py - cy), _square(qx - cx, qy - cy)
            reach2, near2 = max(to_p, to_q), min(to_p, to_q)
            if near2 > self.near2:
                # across the chord's line: every angle up to pi (and the line itself)
                top = _BEYOND if high > math.pi + _MARGIN else high - _MARGIN
                if low + _MARGIN < top:
                    rays.add(low + _MARGIN, top, reach2 * _REACH_SLACK)
                    self.ray_count += 1

    def _in_ray(self, alpha: float, beta: float, x: float, y: float) -> bool:
        """The point (x, y) strictly left of the chord, at these angles, lies in a ray."""
        if not (alpha < math.pi - _MARGIN and beta < math.pi - _MARGIN):
            return False
        if self.rays_a.reach2(alpha) < _square(x - self.ax, y - self.ay):
            return True
        return self.rays_b.reach2(beta) < _square(x - self.bx, y - self.by)

    def _box_in_ray(
        self,
        box: tuple[float, ...],
        alpha: float,
        beta: float,
        top_alpha: float = math.pi,
        top_beta: float = math.pi,
    ) -> bool:
        """Every point of the box strictly left of the chord lies in a ray (``alpha``,
        ``beta``: the least angles of those points, ``top_alpha``, ``top_beta`` the largest;
        pi where not known, up to the chord's line)."""
        for rays, low, high, cx, cy in (
            (self.rays_a, alpha, top_alpha, self.ax, self.ay),
            (self.rays_b, beta, top_beta, self.bx, self.by),
        ):
            reach2 = rays.reach2_over(low, high)
            if reach2 < math.inf and box_distance2(box, cx, cy) > reach2:
                return True
        return False

    def add_many(self, sx: np.ndarray, sy: np.ndarray, positions: np.ndarray) -> None:
        """:meth:`add` of the vertices at ``positions`` (coordinates ``sx``, ``sy``), at once."""
        if self.side is None:
            return
        positions = positions[(positions > self.lo) & (positions < self.hi)]
        if not len(positions):
            return
        alpha, beta, keep = self._angles_many(sx, sy, positions)
        alpha = np.concatenate([np.array(self.alphas), alpha[keep]])
        beta = np.concatenate([np.array(self.betas), beta[keep]])
        if not len(alpha):
            return
        order = np.lexsort((beta, alpha))
        alpha, beta = alpha[order], beta[order]
        # the staircase: each point whose beta is below every beta before it
        before = np.minimum.accumulate(np.concatenate([[math.inf], beta[:-1]]))
        low = beta < before
        self.alphas = alpha[low].tolist()
        self.betas = beta[low].tolist()

    def _add(self, alpha: float, beta: float) -> None:
        if not (_MARGIN < alpha < math.pi - _MARGIN and _MARGIN < beta < math.pi - _MARGIN):
            return
        alphas, betas = self.alphas, self.betas
        at = bisect_left(alphas, alpha)
        if at and betas[at - 1] <= beta:
            return
        end = at
        while end < len(alphas) and betas[end] >= beta:
            end += 1
        alphas[at:end] = [alpha]
        betas[at:end] = [beta]

    def shadowed(self, alpha: float, beta: float) -> bool:
        """Some vertex of the staircase surely lies strictly inside the triangle whose apex
        has these angles. A point not surely strictly left of the chord (an angle within the
        margin of 0 or pi, or wrapped past them: a hair left of the chord's line beyond a
        base end may compute as right of it) is never shadowed."""
        if not (_MARGIN < alpha < math.pi - _MARGIN and _MARGIN < beta < math.pi - _MARGIN):
            return False
        at = bisect_left(self.alphas, alpha - _MARGIN)
        return at > 0 and self.betas[at - 1] < beta - _MARGIN

    def shadowed_many(self, sx: np.ndarray, sy: np.ndarray, positions: np.ndarray) -> np.ndarray:
        """:meth:`shadowed` of the points at ``positions`` (coordinates ``sx``, ``sy``)."""
        if not self.alphas:
            return np.zeros(len(positions), dtype=bool)
        alpha, beta, sure = self._angles_many(sx, sy, positions)
        at = np.searchsorted(np.array(self.alphas), alpha - _MARGIN, side="left")
        stair = np.array([math.inf, *self.betas])
        return sure & (stair[at] < beta - _MARGIN)

    def region_box(self) -> tuple[float, float, float, float] | None:
        """An axis-aligned box (xmin, ymin, xmax, ymax) holding every apex of a correct
        triangle on the base, or None where the staircase does not bound one.

        A correct apex has, for some step j, alpha at most ``alphas[j + 1]`` and beta at most
        ``betas[j]`` (no vertex of the staircase strictly inside its triangle): it lies in the
        triangle of the base and the point Q_j where the rays from A and B at those angles
        meet. The corners' half-planes close the staircase at both ends (alpha 0 first, beta
        0 last). Where a corner is reflex, the edge by which the chain comes back across the
        chord's line beyond it closes that end instead (:meth:`_crossing_back`): an apex
        below the staircase's first alpha has beta at most that of the edge's left end, or
        lies within the edge's reach of B (likewise at A). The box holds A, B, every Q_j,
        found with both angles widened far beyond their rounding, and those reaches; None
        where a step's rays meet only far away or not at all, or an end stays open."""
        alphas, betas = self.alphas, self.betas
        if self.side is None or not alphas:
            return None
        ax, ay, bx, by = self.ax, self.ay, self.bx, self.by
        xs, ys = [ax, bx], [ay, by]
        steps = list(zip(alphas[1:], betas[:-1]))
        for at_b, corner in ((True, alphas[0]), (False, betas[-1])):
            if corner == 0.0:
                continue
            crossing = self._crossing_back(at_b)
            if crossing is None:
                return None
            angle, reach = crossing
            steps.append((alphas[0], angle) if at_b else (angle, betas[-1]))
            cx, cy = (bx, by) if at_b else (ax, ay)
            xs += [cx - reach, cx + reach]
            ys += [cy - reach, cy + reach]
        length = math.hypot(bx - ax, by - ay)
        for alpha, beta in steps:
            alpha, beta = alpha + _WIDEN, beta + _WIDEN
            if not alpha + beta < math.pi - _OPEN:
                return None
            # |AQ| = |AB| sin(beta) / sin(alpha + beta) (the angle at Q is pi - alpha - beta)
            reach = length * math.sin(beta) / math.sin(alpha + beta)
            turn = self.to_b + alpha
            xs.append(ax + reach * math.cos(turn))
            ys.append(ay + reach * math.sin(turn))
        pad = self.boxes.pad + 1e-9 * (max(xs) - min(xs) + max(ys) - min(ys))
        return min(xs) - pad, min(ys) - pad, max(xs) + pad, max(ys) + pad

    def _crossing_back(self, at_b: bool) -> tuple[float, float] | None:
        """Where the chain leaves the base's corner B (``at_b``, from lo on) or A (from hi
        back) to the right of the chord's line: the edge by which it comes back to the
        left, if it crosses the line beyond that corner within ``_CROSSING_WALK`` positions.
        Returns its left end's angle at that corner (beta at B, alpha at A) and a distance
        from the corner beyond which every candidate at a larger such angle has the edge
        across its side from the corner (a ray, module docstring); None if none is found."""
        xs, ys, lo, hi = self.xs, self.ys, self.lo, self.hi
        which = 1 if at_b else 0
        step = 1 if at_b else -1
        cx, cy = (self.bx, self.by) if at_b else (self.ax, self.ay)
        first = lo + 1 if at_b else hi - 1
        previous = lo if at_b else hi
        for position in range(first, first + step * _CROSSING_WALK, step):
            if not lo < position < hi:
                return None
            x, y = xs[position], ys[position]
            alpha, beta = self.angles(x, y)
            if not (_MARGIN < alpha < math.pi - _MARGIN and _MARGIN < beta < math.pi - _MARGIN):
                previous = position
                continue
            if previous in (lo, hi):
                return None  # left of the chord at once: no crossing to find
            px, py = xs[previous], ys[previous]
            back = self.angles(px, py)[which]
            angle = (alpha, beta)[which]
            if not (back > math.pi + _MARGIN and back - angle < math.pi - _MARGIN):
                return None  # not across the line beyond this corner
            # both ends are vertices, whose differences from the corner round relatively:
            # their angles are as good as atan2's unless an end (nearly) is the corner (the
            # trusted distance near2 is for points computed along an edge)
            to_p, to_q = _square(px - cx, py - cy), _square(x - cx, y - cy)
            if not min(to_p, to_q) > self.near2 * _TRUSTED_VERTEX:
                return None
            return angle + _MARGIN, math.sqrt(max(to_p, to_q) * _REACH_SLACK)
        return None

    def _angles_many(
        self, sx: np.ndarray, sy: np.ndarray, positions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`angles` of the points at ``positions``, and where both lie in (0, pi) by
        the margin (the point surely strictly left of the chord: only such a point casts
        or falls in a shadow, as :meth:`_add` and :meth:`shadowed` require one by one)."""
        x, y = sx[positions], sy[positions]
        alpha = (np.arctan2(y - self.ay, x - self.ax) - self.to_b) % _TWO_PI
        beta = (self.to_a - np.arctan2(y - self.by, x - self.bx)) % _TWO_PI
        left = (alpha > _MARGIN) & (alpha < math.pi - _MARGIN)
        left &= (beta > _MARGIN) & (beta < math.pi - _MARGIN)
        return alpha, beta, left

    def _box(self, box: tuple[float, ...]) -> tuple[int, float, float, float, float]:
        """(kind, least alpha, least beta, largest alpha, largest beta) of a chain box: kind 1
        if the box lies strictly left of the chord, -1 if strictly right; where it straddles
        the chord's line, kind 2 if it lies beyond B along the chord, 3 if beyond A (least
        angles of its points left of the line; the other angle then 0), else 0 (angles 0).
        The largest angles are pi but for kind 1."""
        nx, ny, above, below = self.side
        ox, oy, ux, uy, hu, hv = box[4:]
        centre = nx * ox + ny * oy
        reach = hu * abs(nx * ux + ny * uy) + hv * abs(ny * ux - nx * uy)
        if centre + reach < below:
            return -1, 0.0, 0.0, math.pi, math.pi
        if centre - reach <= above:
            return self._straddling(ox, oy, ux, uy, hu, hv)
        ax, ay, to_a, to_b = self.ax, self.ay, self.to_a, self.to_b
        bx, by = self.bx, self.by
        alphas, betas = [], []
        for su, sv in ((hu, hv), (hu, -hv), (-hu, hv), (-hu, -hv)):
            x, y = ox + su * ux - sv * uy, oy + su * uy + sv * ux
            alphas.append((math.atan2(y - ay, x - ax) - to_b) % _TWO_PI)
            betas.append((to_a - math.atan2(y - by, x - bx)) % _TWO_PI)
        return 1, min(alphas), min(betas), max(alphas), max(betas)

    def _straddling(
        self, ox: float, oy: float, ux: float, uy: float, hu: float, hv: float
    ) -> tuple[int, float, float, float, float]:
        """:meth:`_box` of a box that straddles the chord's line. Beyond B (every point's
        projection on the chord past B, by more than the trusted distance) each point has
        ``beta`` in (pi/2, 3 pi/2), below pi left of the line: the least ``beta`` of its left
        part is at a corner or on the line (pi); beyond A the same holds for ``alpha``. Only
        a corner's shadow or a ray can rule such a box out."""
        none = self.corner_beta == math.inf and self.corner_alpha == math.inf
        if self.chord is None or (none and not self.rays_a and not self.rays_b):
            return 0, 0.0, 0.0, math.pi, math.pi  # nothing could rule it out
        dx, dy, length, trusted = self.chord
        along = dx * (ox - self.ax) + dy * (oy - self.ay)
        reach = hu * abs(dx * ux + dy * uy) + hv * abs(dy * ux - dx * uy)
        if along - reach > length + trusted:
            kind, which = 2, 1
        elif along + reach < -trusted:
            kind, which = 3, 0
        else:
            return 0, 0.0, 0.0, math.pi, math.pi
        least = math.pi
        for su, sv in ((hu, hv), (hu, -hv), (-hu, hv), (-hu, -hv)):
            least = min(least, self.angles(ox + su * ux - sv * uy, oy + su * uy + sv * ux)[which])
        if kind == 2:
            return kind, 0.0, least, math.pi, math.pi
        return kind, least, 0.0, math.pi, math.pi

    def _ruled_out(self, box: tuple[float, ...]) -> bool:
        """Every point of the chain box fails: strictly right of the chord, or left of it in
        a vertex's shadow, beyond a corner's half-plane or in a ray."""
        kind, alpha, beta, top_alpha, top_beta = self._box(box)
        if kind < 0 or (kind == 1 and self.shadowed(alpha, beta)):
            return True
        if kind == 2 and beta > self.corner_beta + _MARGIN:
            return True
        if kind == 3 and alpha > self.corner_alpha + _MARGIN:
            return True
        return (
            kind > 0
            and bool(self.rays_a or self.rays_b)
            and self._box_in_ray(box, alpha, beta, top_alpha, top_beta)
        )

    def candidates(self, top: int, bottom: int | None = None) -> Iterator[int]:
        """Candidate positions in ``[bottom, top]`` (``bottom`` lo + 1 if not given), from the
        last back, that no box or point test rules out; vertices met (and shadows added by
        the caller) join the staircase."""
        low_end = self.lo + 1 if bottom is None else bottom
        if self.side is None:
            yield from range(top, low_end - 1, -1)
            return
        xs, ys, lo, hi = self.xs, self.ys, self.lo, self.hi
        levels, sizes, m = self.boxes.levels, self.boxes.sizes, self.boxes.m
        top_level = len(levels) - 1
        stack = [(top_level, k) for k in range(len(levels[top_level]))]
        # the position visited last (the next one back is its edge's other end), its angles
        after, after_x, after_y, after_alpha, after_beta = -2, 0.0, 0.0, 0.0, 0.0
        while stack:
            level, k = stack.pop()
            first = k * sizes[level]
            last = min(first + sizes[level], m)
            if first > top or last < low_end:
                continue
            # a box that holds a base end straddles the chord's line between the ends (kind
            # 0, which no test rules out): entered untested
            holds_end = level and (first <= lo <= last or first <= hi <= last)
            if not holds_end and self._ruled_out(levels[level][k]):
                continue
            if level:
                stack.append((level - 1, 2 * k))
                if 2 * k + 1 < len(levels[level - 1]):
                    stack.append((level - 1, 2 * k + 1))
                continue
            # the box's last point opens the next box, which covers it
            high = min(last if last == m else last - 1, top)
            for position in range(high, max(first, low_end) - 1, -1):
                x, y = xs[position], ys[position]
                alpha, beta = self.angles(x, y)
                if (
                    position == after
                    and (alpha < math.pi) != (after_alpha < math.pi)
                    and lo <= position < hi
                ):
                    # the edge to the position met before crosses the chord's line: beyond a
                    # base end it rules out the candidates behind it along the line, which
                    # no vertex shadows
                    self._ray(x, y, after_x, after_y, (alpha, beta), (after_alpha, after_beta))
                after, after_x, after_y = position - 1, x, y
                after_alpha, after_beta = alpha, beta
                if not self.shadowed(alpha, beta):
                    self._add(alpha, beta)
                    if not (self.rays_a or self.rays_b) or not self._in_ray(alpha, beta, x, y):
                        yield position
