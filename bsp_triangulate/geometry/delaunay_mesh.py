"""A constrained Delaunay triangulation that takes points one at a time (Lawson flips).

Pure Python on flat lists, so that one insertion costs a few dozen microseconds; numpy is used
only to import and export whole tables. Triangle ``t`` owns the slots ``3t``, ``3t + 1`` and
``3t + 2``: slot ``3t + k`` holds its vertex ``k`` and stands for the edge opposite that
vertex, from vertex ``k + 1`` to vertex ``k + 2`` (mod 3, counter-clockwise). Across that edge
lies the slot ``_across[3t + k]`` of the neighbour (its edge is the same, reversed), or -1 on
the region's boundary, and ``_fixed[3t + k]`` tells whether the edge is constrained. Slots
rather than triangle ids for neighbours make every back-link a single lookup.

Edges on the boundary and constrained edges are never flipped; every other edge is made
locally Delaunay with :func:`predicates.incircle_sos`, whose symbolic tie rule makes the
result unique whatever the insertion order, even with exactly cocircular points.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from .predicates import (
    CCW_ERRBOUND,
    ICC_ERRBOUND,
    UNDERFLOW_SLACK,
    incircle_sos,
    incircle_sos_many,
    orient,
    orient_many,
)
from .rings_batch import ragged_index

# ICC_ERRBOUND with a margin for the few roundings by which the float value of the simpler
# bound of DelaunayMesh._restore may fall below the float permanent
_ICC_SAFE = 1.25 * ICC_ERRBOUND
# a larger bound may come with an overflowed determinant: left to predicates.incircle_sos
_HUGE = 1e290
# the edges of a triangle from edge ``first`` on, each with its two ends' local indices
_WALK_ORDER = tuple(
    tuple((k % 3, (k + 1) % 3, (k + 2) % 3) for k in range(first, first + 3)) for first in range(3)
)


class DelaunayMesh:
    """A constrained Delaunay triangulation that takes points one at a time.

    Vertex ids are positions in the coordinate lists ``x`` and ``y``; triangle ids are
    stable: a split keeps the old id for one piece and appends the others, a flip reuses the
    two ids, so an old id still names a triangle near where it was.
    """

    def __init__(
        self,
        x: Sequence[float],
        y: Sequence[float],
        triangles: object,
        constrained: Iterable[tuple[int, int]] = (),
    ) -> None:
        """``triangles``: (t, 3) vertex ids, each counter-clockwise; ``constrained``: vertex
        pairs (either order) of edges that are never flipped. Edges with a triangle on one side
        only (the region's boundary) are never flipped either."""
        self.x: list[float] = [float(v) for v in x]
        self.y: list[float] = [float(v) for v in y]
        if len(self.x) != len(self.y):
            raise ValueError("x and y differ in length")
        n = len(self.x)
        tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if len(tri) and (tri.min() < 0 or tri.max() >= n):
            raise ValueError("a triangle names a vertex that does not exist")
        xs, ys = np.asarray(self.x), np.asarray(self.y)
        if len(tri):
            signs = orient_many(*(c[tri[:, k]] for k in range(3) for c in (xs, ys)))
            if (signs <= 0).any():
                raise ValueError(f"triangle {int(np.argmax(signs <= 0))} is not counter-clockwise")
        flat = tri.ravel()
        across, repeated = edge_links(tri, n)
        if repeated.any():
            raise ValueError("an edge is used twice in the same direction (overlapping triangles)")
        start = tri[:, [1, 2, 0]].ravel()
        end = tri[:, [2, 0, 1]].ravel()
        fixed = np.zeros(len(across), dtype=bool)
        pairs = np.asarray(list(constrained), dtype=np.int64).reshape(-1, 2)
        if len(pairs):
            low, high = pairs.min(axis=1), pairs.max(axis=1)
            wanted = np.unique(low * n + high)
            slot_keys = np.minimum(start, end) * n + np.maximum(start, end)
            fixed = np.isin(slot_keys, wanted)
            missing = np.setdiff1d(wanted, slot_keys[fixed])
            if len(missing):
                i, j = divmod(int(missing[0]), n)
                raise ValueError(f"constrained pair ({i}, {j}) is not an edge of the triangulation")
        owner = np.full(n, -1, dtype=np.int64)
        owner[flat] = np.arange(len(flat)) // 3
        self._vertex: list[int] = flat.tolist()
        self._across: list[int] = across.tolist()
        self._fixed: list[bool] = fixed.tolist()
        # one triangle holding each vertex (-1: a vertex of no triangle)
        self._owner: list[int] = owner.tolist()

    @classmethod
    def of_triangulation(
        cls, vertices: object, triangles: object, constrained: Iterable[tuple[int, int]] = ()
    ) -> DelaunayMesh:
        """A mesh of an (n, >= 2) vertex array (x, y first) and its (t, 3) triangles."""
        v = np.asarray(vertices, dtype=np.float64)
        return cls(v[:, 0], v[:, 1], triangles, constrained)

    @property
    def vertex_count(self) -> int:
        return len(self.x)

    @property
    def triangle_count(self) -> int:
        return len(self._vertex) // 3

    def triangles(self) -> np.ndarray:
        """(t, 3) int64 vertex ids, counter-clockwise."""
        return np.array(self._vertex, dtype=np.int64).reshape(-1, 3)

    def neighbours(self) -> np.ndarray:
        """(t, 3) int64: the triangle across the edge opposite each vertex, -1 on the boundary."""
        across = np.array(self._across, dtype=np.int64)
        return np.where(across >= 0, across // 3, -1).reshape(-1, 3)

    def constrained_edges(self) -> np.ndarray:
        """(e, 2) int64 constrained edges, each as (smaller id, larger id), sorted."""
        vertex = self._vertex
        pairs = set()
        for s, flag in enumerate(self._fixed):
            if flag:
                base = s - s % 3
                i, j = vertex[base + (s + 1) % 3], vertex[base + (s + 2) % 3]
                pairs.add((i, j) if i < j else (j, i))
        return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)

    def has_edge(self, i: int, j: int) -> bool:
        """Whether an edge joins vertices i and j (a turn around vertex i)."""
        if not (0 <= i < len(self.x)) or self._owner[i] < 0:
            return False
        vertex, across = self._vertex, self._across
        first = self._owner[i]
        # counter-clockwise around i, then clockwise from the first triangle if a boundary stops it
        for step in (1, 2):
            t = first
            for _ in range(len(vertex) // 3 + 1):
                base = 3 * t
                k = vertex.index(i, base, base + 3) - base
                if vertex[base + (k + 1) % 3] == j or vertex[base + (k + 2) % 3] == j:
                    return True
                s = across[base + (k + step) % 3]
                if s < 0:
                    break
                t = s // 3
                if t == first:
                    return False
        return False

    def locate(self, px: float, py: float, start: int = 0) -> tuple[int, int]:
        """The triangle holding (px, py) (closed) and -1 if the point is strictly inside it,
        else the local index of the edge it lies on (one of two on a vertex).

        A visibility walk from triangle ``start`` (0 if there is no such triangle); where the
        region's boundary blocks it or it runs long, every triangle is scanned. ValueError if
        no triangle holds the point.
        """
        px, py = float(px), float(py)
        count = len(self._vertex) // 3
        if count == 0 or not (math.isfinite(px) and math.isfinite(py)):
            raise ValueError(f"point ({px}, {py}) is outside the triangulated region")
        found = self._walk(px, py, start if 0 <= start < count else 0)
        return found if found is not None else self._scan(px, py)

    def _walk(self, px: float, py: float, t: int) -> tuple[int, int] | None:
        """The visibility walk of :meth:`locate`; None where it is blocked or too long."""
        vertex, across, x, y = self._vertex, self._across, self.x, self.y
        entry = -1  # the local edge we came in through: the point is strictly left of it
        limit = 64 + 8 * math.isqrt(len(vertex))
        toggle = 0
        ccw_bound, slack = CCW_ERRBOUND, UNDERFLOW_SLACK
        for _ in range(limit):
            base = 3 * t
            blocked = False
            zero = -1
            # start at either edge after the entry so that no walk keeps circling one way
            toggle ^= 1
            first = (entry + 1 + toggle) % 3 if entry >= 0 else toggle
            for k, k1, k2 in _WALK_ORDER[first]:
                if k == entry:
                    continue
                a = vertex[base + k1]
                b = vertex[base + k2]
                # the float filter of predicates.orient, inlined
                ax, ay, bx, by = x[a], y[a], x[b], y[b]
                left = (ax - px) * (by - py)
                right = (ay - py) * (bx - px)
                det = left - right
                bound = ccw_bound * (abs(left) + abs(right)) + slack
                if det > bound:
                    side = 1
                elif -det > bound:
                    side = -1
                else:
                    side = orient(ax, ay, bx, by, px, py)
                if side < 0:
                    s = across[base + k]
                    if s >= 0:
                        t, entry = s // 3, s % 3
                        break
                    blocked = True
                elif side == 0:
                    zero = k
            else:
                if blocked:
                    return None
                return t, zero
        return None

    def _scan(self, px: float, py: float) -> tuple[int, int]:
        """The triangle holding the point, found among all whose bounding box holds it."""
        tri = np.array(self._vertex, dtype=np.int64).reshape(-1, 3)
        xs, ys = np.array(self.x)[tri], np.array(self.y)[tri]
        boxed = np.flatnonzero(
            (xs.min(axis=1) <= px)
            & (xs.max(axis=1) >= px)
            & (ys.min(axis=1) <= py)
            & (ys.max(axis=1) >= py)
        )
        x, y = self.x, self.y
        for t in boxed.tolist():
            a, b, c = tri[t].tolist()
            sides = (
                orient(x[b], y[b], x[c], y[c], px, py),
                orient(x[c], y[c], x[a], y[a], px, py),
                orient(x[a], y[a], x[b], y[b], px, py),
            )
            if min(sides) >= 0:
                return t, (sides.index(0) if 0 in sides else -1)
        raise ValueError(f"point ({px}, {py}) is outside the triangulated region")

    def insert(self, px: float, py: float, start: int = 0) -> int:
        """Add the vertex (px, py) inside the region or on an edge and restore the Delaunay
        property; returns its id. ValueError (mesh unchanged) for a point outside the region
        or equal to a vertex.

        Inside a triangle it splits 1 -> 3, on an interior edge 2 -> 4, on a boundary edge
        1 -> 2; the halves of a split constrained or boundary edge stay so.
        """
        px, py = float(px), float(py)
        return self._insert_at(px, py, *self.locate(px, py, start))

    def _insert_at(self, px: float, py: float, t: int, edge: int) -> int:
        """:meth:`insert` of a point located in triangle t, on its edge ``edge`` (-1: inside)."""
        x, y = self.x, self.y
        base = 3 * t
        for v in self._vertex[base : base + 3]:
            if x[v] == px and y[v] == py:
                raise ValueError(f"point ({px}, {py}) is vertex {v}")
        p = len(x)
        x.append(px)
        y.append(py)
        self._owner.append(t)
        stack = self._split_triangle(t, p) if edge < 0 else self._split_edge(t, edge, p)
        self._restore(p, stack)
        return p

    def insert_many(self, x: Sequence[float], y: Sequence[float]) -> np.ndarray:
        """:meth:`insert` every point, in the order of a Hilbert curve so that each walk starts
        next to the point before; returns each point's vertex id, or -1 for a point outside
        the region or equal to a vertex (skipped)."""
        xs = np.asarray(x, dtype=np.float64).ravel()
        ys = np.asarray(y, dtype=np.float64).ravel()
        if len(xs) != len(ys):
            raise ValueError("x and y differ in length")
        ids = np.full(len(xs), -1, dtype=np.int64)
        # the triangle holding each point now: points outside are skipped without a scan, and
        # where a walk from the point before is blocked, one from there is not (usually)
        holder = self._containing(xs, ys)
        order = hilbert_order(xs, ys)
        order = order[holder[order] >= 0]
        previous = 0
        walk, insert_at, owner = self._walk, self._insert_at, self._owner
        found_ids = ids.tolist()
        for i, px, py, t in zip(
            order.tolist(), xs[order].tolist(), ys[order].tolist(), holder[order].tolist()
        ):
            try:
                v = insert_at(
                    px, py, *(walk(px, py, previous) or walk(px, py, t) or self._scan(px, py))
                )
            except ValueError:
                continue  # outside after all, or a vertex
            found_ids[i] = v
            previous = owner[v]
        return np.array(found_ids, dtype=np.int64)

    def _containing(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """A triangle holding each point (closed), or -1 (:func:`containing_triangles`)."""
        return containing_triangles(np.array(self.x), np.array(self.y), self.triangles(), px, py)

    def _split_triangle(self, t: int, p: int) -> list[int]:
        """1 -> 3: (p, b, c) keeps id t, (p, c, a) and (p, a, b) are appended."""
        vertex, across, fixed, owner = self._vertex, self._across, self._fixed, self._owner
        base = 3 * t
        a, b, c = vertex[base], vertex[base + 1], vertex[base + 2]
        t1 = len(vertex) // 3
        t2 = t1 + 1
        s1, s2 = 3 * t1, 3 * t2
        n1, n2 = across[base + 1], across[base + 2]
        vertex[base] = p
        vertex.extend((p, c, a, p, a, b))
        across[base + 1 : base + 3] = [s1 + 2, s2 + 1]
        across.extend((n1, s2 + 2, base + 1, n2, base + 2, s1 + 1))
        fixed.extend((fixed[base + 1], False, False, fixed[base + 2], False, False))
        fixed[base + 1] = fixed[base + 2] = False
        if n1 >= 0:
            across[n1] = s1
        if n2 >= 0:
            across[n2] = s2
        owner[a] = t1
        owner[b] = t
        owner[c] = t
        return [t, t1, t2]

    def _split_edge(self, t: int, k: int, p: int) -> list[int]:
        """p on edge k = (u, v) of t = (w, u, v): 2 -> 4, or 1 -> 2 on the boundary."""
        vertex, across, fixed, owner = self._vertex, self._across, self._fixed, self._owner
        base = 3 * t
        w = vertex[base + k]
        u = vertex[base + (k + 1) % 3]
        v = vertex[base + (k + 2) % 3]
        out_vw = across[base + (k + 1) % 3]  # edge (v, w), opposite u
        fix_vw = fixed[base + (k + 1) % 3]
        out_wu = across[base + (k + 2) % 3]  # edge (w, u), opposite v
        fix_wu = fixed[base + (k + 2) % 3]
        split = fixed[base + k]
        other = across[base + k]
        t2 = len(vertex) // 3
        s1, s2 = base, 3 * t2
        # t -> (p, v, w); t2 = (p, w, u)
        vertex[s1 : s1 + 3] = [p, v, w]
        vertex.extend((p, w, u))
        if other < 0:
            across[s1 : s1 + 3] = [out_vw, s2 + 2, -1]
            fixed[s1 : s1 + 3] = [fix_vw, False, split]
            across.extend((out_wu, -1, s1 + 1))
            fixed.extend((fix_wu, split, False))
            stack = [t, t2]
        else:
            t3 = other // 3
            j = other % 3
            s3, s4 = 3 * t3, s2 + 3
            z = vertex[other]
            out_uz = across[s3 + (j + 1) % 3]  # edge (u, z), opposite v
            fix_uz = fixed[s3 + (j + 1) % 3]
            out_zv = across[s3 + (j + 2) % 3]  # edge (z, v), opposite u
            fix_zv = fixed[s3 + (j + 2) % 3]
            # t3 -> (p, u, z); t4 = (p, z, v)
            vertex[s3 : s3 + 3] = [p, u, z]
            vertex.extend((p, z, v))
            across[s1 : s1 + 3] = [out_vw, s2 + 2, s4 + 1]
            fixed[s1 : s1 + 3] = [fix_vw, False, split]
            across[s3 : s3 + 3] = [out_uz, s4 + 2, s2 + 1]
            fixed[s3 : s3 + 3] = [fix_uz, False, split]
            across.extend((out_wu, s3 + 2, s1 + 1, out_zv, s1 + 2, s3 + 1))
            fixed.extend((fix_wu, split, False, fix_zv, split, False))
            if out_uz >= 0:
                across[out_uz] = s3
            if out_zv >= 0:
                across[out_zv] = s4
            owner[z] = t3
            stack = [t, t2, t3, t2 + 1]
        if out_vw >= 0:
            across[out_vw] = s1
        if out_wu >= 0:
            across[out_wu] = s2
        owner[u] = t2
        owner[v] = t
        owner[w] = t
        return stack

    def _restore(self, p: int, stack: list[int]) -> None:
        """Lawson flips around the new vertex p; ``stack``: triangles with p at slot 0."""
        vertex, across, fixed, owner = self._vertex, self._across, self._fixed, self._owner
        x, y = self.x, self.y
        px, py = x[p], y[p]
        pop, push = stack.pop, stack.append
        bound_factor = _ICC_SAFE
        slack = UNDERFLOW_SLACK
        while stack:
            t = pop()
            s = 3 * t
            n = across[s]
            if n < 0 or fixed[s]:
                continue
            b, c, d = vertex[s + 1], vertex[s + 2], vertex[n]
            # a float filter as in predicates.incircle_one, inlined (the loop is the whole cost),
            # with a bound without abs(): |bdx cdy| + |cdx bdy| <= (blift + clift) / 2 and so on,
            # so the permanent is at most the sum of the lifts' pairwise products
            dx, dy = x[d], y[d]
            adx, ady = px - dx, py - dy
            bdx, bdy = x[b] - dx, y[b] - dy
            cdx, cdy = x[c] - dx, y[c] - dy
            alift = adx * adx + ady * ady
            blift = bdx * bdx + bdy * bdy
            clift = cdx * cdx + cdy * cdy
            det = (
                alift * (bdx * cdy - cdx * bdy)
                + blift * (cdx * ady - adx * cdy)
                + clift * (adx * bdy - bdx * ady)
            )
            bound = bound_factor * (alift * blift + blift * clift + clift * alift) + slack
            if bound < _HUGE:
                if -det > bound:
                    continue
                if det <= bound and incircle_sos(px, py, x[b], y[b], x[c], y[c], dx, dy) <= 0:
                    continue
            elif incircle_sos(px, py, x[b], y[b], x[c], y[c], dx, dy) <= 0:
                continue
            t2 = n // 3
            q = 3 * t2
            j = n - q
            nc = q + (j + 1) % 3  # slot of c in t2: edge (b, d)
            nb = q + (j + 2) % 3  # slot of b in t2: edge (d, c)
            out_bd, fix_bd = across[nc], fixed[nc]
            out_dc, fix_dc = across[nb], fixed[nb]
            out_cp, fix_cp = across[s + 1], fixed[s + 1]
            # t -> (p, b, d); t2 -> (p, d, c)
            vertex[s + 2] = d
            across[s] = out_bd
            fixed[s] = fix_bd
            across[s + 1] = q + 2
            fixed[s + 1] = False
            vertex[q] = p
            vertex[q + 1] = d
            vertex[q + 2] = c
            across[q] = out_dc
            across[q + 1] = out_cp
            across[q + 2] = s + 1
            fixed[q] = fix_dc
            fixed[q + 1] = fix_cp
            fixed[q + 2] = False
            if out_bd >= 0:
                across[out_bd] = s
            if out_dc >= 0:
                across[out_dc] = q
            if out_cp >= 0:
                across[out_cp] = q + 1
            owner[b] = t
            owner[c] = t2
            push(t)
            push(t2)

    def make_delaunay(self) -> int:
        """Flip every unconstrained interior edge that is not locally Delaunay until none is
        left; returns the number of flips."""
        vertex, across, fixed = self._vertex, self._across, self._fixed
        x, y = self.x, self.y
        stack = list(range(len(vertex)))
        flips = 0
        while stack:
            s = stack.pop()
            n = across[s]
            if n < 0 or fixed[s]:
                continue
            base = s - s % 3
            a = vertex[s]
            b = vertex[base + (s + 1) % 3]
            c = vertex[base + (s + 2) % 3]
            d = vertex[n]
            if incircle_sos(x[a], y[a], x[b], y[b], x[c], y[c], x[d], y[d]) <= 0:
                continue
            t, t2 = self._flip(s)
            flips += 1
            stack.extend((3 * t, 3 * t + 2, 3 * t2, 3 * t2 + 1))
        return flips

    def _flip(self, s: int) -> tuple[int, int]:
        """Flip the edge (b, c) of slot s in t = (a, b, c), d across it: t becomes (a, b, d)
        and the neighbour (a, d, c), both with a at slot 0."""
        vertex, across, fixed, owner = self._vertex, self._across, self._fixed, self._owner
        k = s % 3
        base = s - k
        n = across[s]
        t, t2 = base // 3, n // 3
        q = 3 * t2
        j = n % 3
        a, b, c, d = vertex[s], vertex[base + (k + 1) % 3], vertex[base + (k + 2) % 3], vertex[n]
        nc, nb = q + (j + 1) % 3, q + (j + 2) % 3  # edges (b, d) and (d, c)
        out_bd, fix_bd = across[nc], fixed[nc]
        out_dc, fix_dc = across[nb], fixed[nb]
        out_ca, fix_ca = across[base + (k + 1) % 3], fixed[base + (k + 1) % 3]
        out_ab, fix_ab = across[base + (k + 2) % 3], fixed[base + (k + 2) % 3]
        vertex[base : base + 3] = [a, b, d]
        across[base : base + 3] = [out_bd, q + 2, out_ab]
        fixed[base : base + 3] = [fix_bd, False, fix_ab]
        vertex[q : q + 3] = [a, d, c]
        across[q : q + 3] = [out_dc, out_ca, base + 1]
        fixed[q : q + 3] = [fix_dc, fix_ca, False]
        for slot, out in ((base, out_bd), (base + 2, out_ab), (q, out_dc), (q + 1, out_ca)):
            if out >= 0:
                across[out] = slot
        owner[a] = owner[b] = owner[d] = t
        owner[c] = t2
        return t, t2


def slot_keys(tri: np.ndarray, n: int) -> np.ndarray:
    """Per slot of the (t, 3) triangles over n vertices (slot 3t + k: the directed edge from
    vertex k + 1 to vertex k + 2), its edge as the integer start * n + end."""
    return (tri[:, [1, 2, 0]] * n + tri[:, [2, 0, 1]]).ravel()


def edge_links(tri: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per slot of the (t, 3) counter-clockwise triangles over n vertices (slot 3t + k: the
    directed edge from vertex k + 1 to vertex k + 2): the slot across its edge, or -1; and
    whether an earlier slot already has that directed edge (overlapping triangles)."""
    start = tri[:, [1, 2, 0]].ravel()
    end = tri[:, [2, 0, 1]].ravel()
    keys = slot_keys(tri, n)
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    repeated = np.zeros(len(keys), dtype=bool)
    repeated[order[1:][sorted_keys[1:] == sorted_keys[:-1]]] = True
    across = np.full(len(keys), -1, dtype=np.int64)
    if len(keys):
        twin = np.minimum(np.searchsorted(sorted_keys, end * n + start), len(keys) - 1)
        found = sorted_keys[twin] == end * n + start
        across[found] = order[twin[found]]
    return across, repeated


def delaunay_faults(x: np.ndarray, y: np.ndarray, tri: np.ndarray, ties: bool) -> np.ndarray:
    """Per triangle of the (t, 3) vertex ids: it is not strictly counter-clockwise, it uses
    a directed edge another triangle uses too, or across one of its edges lies a vertex
    strictly inside its circle under the tie rule (exact, :func:`predicates.incircle_sos`);
    ``ties``: a vertex at a corner's point (the tie rule's 0) counts as a fault too."""
    bad = orient_many(*(c[tri[:, k]] for k in range(3) for c in (x, y))) <= 0
    across, repeated = edge_links(tri, len(x))
    bad[np.flatnonzero(repeated) // 3] = True
    # each shared edge once, from its lower slot (the test is the same from either side)
    s = np.flatnonzero(across > np.arange(len(across)))
    k = s % 3
    base = s - k
    v = tri.ravel()
    a, b, c, d = v[s], v[base + (k + 1) % 3], v[base + (k + 2) % 3], v[across[s]]
    sign = incircle_sos_many(x[a], y[a], x[b], y[b], x[c], y[c], x[d], y[d])
    fault = s[(sign >= 0) if ties else (sign > 0)]
    bad[fault // 3] = True
    bad[across[fault] // 3] = True
    return bad


def hilbert_order(x: np.ndarray, y: np.ndarray, bits: int = 16) -> np.ndarray:
    """Indices that sort the points along a Hilbert curve over their bounding box."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if len(x) == 0:
        return np.zeros(0, dtype=np.int64)
    side = 1 << bits
    low_x, low_y = x.min(), y.min()
    span = max(x.max() - low_x, y.max() - low_y)
    scale = (side - 1) / span if span > 0 else 0.0
    qx = np.clip((x - low_x) * scale, 0, side - 1).astype(np.int64)
    qy = np.clip((y - low_y) * scale, 0, side - 1).astype(np.int64)
    key = np.zeros(len(x), dtype=np.int64)
    s = side >> 1
    while s > 0:
        rx = (qx & s) > 0
        ry = (qy & s) > 0
        key += s * s * ((3 * rx) ^ ry)
        # rotate the quadrant so that the curve inside it runs the standard way
        turn = ~ry
        mirror = turn & rx
        qx = np.where(mirror, s - 1 - qx, qx)
        qy = np.where(mirror, s - 1 - qy, qy)
        qx, qy = np.where(turn, qy, qx), np.where(turn, qx, qy)
        s >>= 1
    return np.argsort(key, kind="stable")


def containing_triangles(
    x: np.ndarray,
    y: np.ndarray,
    tri: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    tri_region: np.ndarray | None = None,
    point_region: np.ndarray | None = None,
) -> np.ndarray:
    """A triangle of ``tri`` (rows of vertex ids into ``x``, ``y``, counter-clockwise)
    holding each point (closed), or -1: a grid over the triangles' boxes. With regions (one
    per triangle and one per point), only the triangles of the point's own region."""
    found = np.full(len(px), -1, dtype=np.int64)
    count = len(tri)
    if count == 0 or len(px) == 0:
        return found
    tx, ty = x[tri], y[tri]
    x0, x1, y0, y1 = tx.min(axis=1), tx.max(axis=1), ty.min(axis=1), ty.max(axis=1)
    # contiguous columns: gathers of whole rows of three are several times slower
    corners = [np.ascontiguousarray(tri[:, k]) for k in range(3)]
    left, bottom = float(x0.min()), float(y0.min())
    span = max(float(x1.max()) - left, float(y1.max()) - bottom)
    side = max(1, math.isqrt(count))
    while True:
        size = span / side if span > 0 else 1.0
        cx0, cx1 = _cells(x0, left, size, side), _cells(x1, left, size, side)
        cy0, cy1 = _cells(y0, bottom, size, side), _cells(y1, bottom, size, side)
        cover = (cx1 - cx0 + 1) * (cy1 - cy0 + 1)
        # long thin triangles cover many cells: coarser cells keep the pairs few
        if side == 1 or cover.sum() <= 8 * count + 4096:
            break
        side //= 2
    # one (cell, triangle) pair per cell of each triangle's box, sorted by cell
    owner = np.repeat(np.arange(count), cover)
    local = ragged_index(np.zeros(count, dtype=np.int64), cover)
    width = (cx1 - cx0 + 1)[owner]
    cells = (cy0[owner] + local // width) * side + cx0[owner] + local % width
    if tri_region is not None:
        cells += tri_region[owner] * (side * side)  # cells of one region only
    order = np.argsort(cells, kind="stable")
    cells, owner = cells[order], owner[order]
    # the boxes' own extremes: left + span may round below them
    right, top = float(x1.max()), float(y1.max())
    inside = (px >= left) & (px <= right) & (py >= bottom) & (py <= top)
    where = np.flatnonzero(inside)
    point_cells = _cells(px[where], left, size, side)
    point_cells += _cells(py[where], bottom, size, side) * side
    if point_region is not None:
        point_cells += point_region[where] * (side * side)
    lo = np.searchsorted(cells, point_cells, side="left")
    counts = np.searchsorted(cells, point_cells, side="right") - lo
    # (point, candidate triangle) pairs in chunks of about a million
    ends = np.cumsum(counts)
    first = 0
    while first < len(where):
        last = int(np.searchsorted(ends, ends[first] - counts[first] + 1_000_000, "right"))
        last = max(last, first + 1)
        part = slice(first, last)
        point = np.repeat(where[part], counts[part])
        candidate = owner[ragged_index(lo[part], counts[part])]
        # a closed triangle's points are in its closed box (exact comparisons)
        qx, qy = px[point], py[point]
        boxed = (x0[candidate] <= qx) & (qx <= x1[candidate])
        boxed &= (y0[candidate] <= qy) & (qy <= y1[candidate])
        point, candidate = point[boxed], candidate[boxed]
        # edge by edge, each test on the pairs left (most fail the first)
        for k in range(3):
            a, b = corners[(k + 1) % 3][candidate], corners[(k + 2) % 3][candidate]
            held = orient_many(x[a], y[a], x[b], y[b], px[point], py[point]) >= 0
            point, candidate = point[held], candidate[held]
        found[point] = candidate
        first = last
    return found


def _cells(v: np.ndarray, low: float, size: float, side: int) -> np.ndarray:
    """Grid column (or row) of each coordinate; monotone, so a box holding a point holds
    its cell."""
    return np.clip(np.floor((v - low) / size), 0, side - 1).astype(np.int64)
