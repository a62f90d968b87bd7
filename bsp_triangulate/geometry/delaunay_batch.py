"""Many constrained Delaunay triangulations in flat numpy arrays, points inserted in batches.

The layout of :class:`.delaunay_mesh.DelaunayMesh` (slot ``3t + k``: vertex k of triangle t and
the edge opposite it; ``across`` the neighbour's slot or -1 on the boundary; ``fixed``: never
flipped) for many regions at once: vertex and triangle ids are global, regions share none.
Points go in levels, coarse to fine (every 2^k-th point of the order given first), so that only
a level's points are looked for; a batch inserts at most one point per triangle at a time (1 ->
3 inside, 2 -> 4 on an interior edge, 1 -> 2 on a boundary edge), all together, then flips
every edge that is not locally Delaunay (:func:`.predicates.incircle_sos_many`) in passes of
flips that share no triangle, until none is left. The symbolic tie rule makes the constrained
Delaunay triangulation unique, so the triangles are those that ``DelaunayMesh`` makes one point
at a time; only their ids differ.
"""

from __future__ import annotations

import numpy as np

from .delaunay_mesh import edge_links
from .points import first_occurrences
from .predicates import incircle_sos_many, orient_many

# slots (k + 1) % 3 and (k + 2) % 3 of local slot k
_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


class MeshSet:
    """Constrained Delaunay triangulations of many regions, to insert points into in batches.

    ``x``, ``y``: vertex coordinates; ``triangles`` (t, 3) vertex ids, counter-clockwise;
    ``region`` (t,) each triangle's region. Edges with a triangle on one side only are the
    regions' boundaries; ``fixed_pairs`` (e, 2) further edges never flipped. ``changed``
    marks the triangles made or altered since it was last cleared (all, at first)."""

    def __init__(
        self,
        x: np.ndarray,
        y: np.ndarray,
        triangles: np.ndarray,
        region: np.ndarray,
        fixed_pairs: np.ndarray | None = None,
    ) -> None:
        tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        n, t = len(x), len(tri)
        self._nv, self._nt = n, t
        self.x = np.array(x, dtype=np.float64)
        self.y = np.array(y, dtype=np.float64)
        self.vertex = tri.ravel().copy()
        self.across = edge_links(tri, n)[0]
        self.fixed = np.zeros(3 * t, dtype=bool)
        if fixed_pairs is not None and len(fixed_pairs):
            pairs = np.asarray(fixed_pairs, dtype=np.int64).reshape(-1, 2)
            start, end = tri[:, [1, 2, 0]].ravel(), tri[:, [2, 0, 1]].ravel()
            keys = np.minimum(start, end) * n + np.maximum(start, end)
            self.fixed = np.isin(keys, pairs.min(axis=1) * n + pairs.max(axis=1))
        self.region = np.asarray(region, dtype=np.int64).copy()
        self.changed = np.ones(t, dtype=bool)
        # per triangle scratch for claims, kept at _FREE between uses; per slot scratch for
        # where a rewritten slot's edge goes, kept at -1
        self._claim = np.full(t, _FREE, dtype=np.int64)
        self._moved = np.full(3 * t, -1, dtype=np.int64)

    @property
    def vertex_count(self) -> int:
        return self._nv

    @property
    def triangle_count(self) -> int:
        return self._nt

    def triangles(self) -> np.ndarray:
        """(t, 3) vertex ids of every triangle, counter-clockwise."""
        return self.vertex[: 3 * self._nt].reshape(-1, 3)

    def make_delaunay(self, triangles: np.ndarray) -> None:
        """Flip the edges of ``triangles`` (and those beyond, in turn) until every edge is
        locally Delaunay: any triangulation of a region becomes its constrained Delaunay
        one (Lawson), the boundary and fixed edges kept."""
        triangles = np.asarray(triangles, dtype=np.int64)
        if len(triangles):
            self._flip_all((3 * triangles[:, None] + np.arange(3)).ravel())

    def insert(
        self, px: np.ndarray, py: np.ndarray, start: np.ndarray, boundary: bool = True
    ) -> np.ndarray:
        """Add the points (px, py), each found from triangle ``start`` (a triangle of its
        region, best near it), and restore the Delaunay property; returns each point's vertex
        id, or -1 for a point outside its region (walking from ``start``), equal to a vertex,
        or (``boundary`` False) on a boundary edge. Equal points: the first is inserted, the
        others are vertices by then."""
        px = np.asarray(px, dtype=np.float64)
        py = np.asarray(py, dtype=np.float64)
        ids = np.full(len(px), -1, dtype=np.int64)
        origin = np.asarray(start, dtype=np.int64)
        if len(origin) and (origin.min() < 0 or origin.max() >= self._nt):
            raise ValueError("a start triangle does not exist")
        near = origin.copy()
        # a point equal to an earlier one of its region would find it a vertex: not looked for
        region = self.region[near]
        waiting = np.flatnonzero(first_occurrences(px, py, region))
        # levels of every 2^k-th point in the order given, coarse to fine: each level adds
        # about as many points as the mesh has triangles where it goes, so a round inserts
        # most of its level and only that level's points are looked for (a point's search
        # starts from where the point before it in the order went)
        stride = 1 << max(0, int(np.ceil(np.log2(max(1.0, len(waiting) / max(1, self._nt))))))
        ranks = np.arange(len(waiting))
        while stride:
            level = waiting[ranks % stride == 0]
            waiting, ranks = waiting[ranks % stride != 0], ranks[ranks % stride != 0]
            stride //= 2
            if not len(level):
                continue
            self._hint(px, py, level, near, ids, region)
            self._insert_level(px, py, level, near, ids, origin, boundary)
        return ids

    def _hint(
        self,
        px: np.ndarray,
        py: np.ndarray,
        level: np.ndarray,
        near: np.ndarray,
        ids: np.ndarray,
        region: np.ndarray,
    ) -> None:
        """Into ``near``: for each point of ``level``, a triangle at the vertex of the nearer
        of the points inserted before and after it in the order given (of its region)."""
        placed = ids >= 0
        if not placed.any():
            return
        count = len(px)
        before = np.maximum.accumulate(np.where(placed, np.arange(count), -1))[level]
        after = np.minimum.accumulate(np.where(placed, np.arange(count), count)[::-1])[::-1]
        after = after[level]
        has_before = before >= 0
        has_before[has_before] = region[before[has_before]] == region[level[has_before]]
        has_after = after < count
        has_after[has_after] = region[after[has_after]] == region[level[has_after]]
        if not (has_before | has_after).any():
            return
        vertex_before = ids[np.maximum(before, 0)]
        vertex_after = ids[np.minimum(after, count - 1)]
        qx, qy = px[level], py[level]
        far_before = (self.x[vertex_before] - qx) ** 2 + (self.y[vertex_before] - qy) ** 2
        far_after = (self.x[vertex_after] - qx) ** 2 + (self.y[vertex_after] - qy) ** 2
        take_after = has_after & (~has_before | (far_after < far_before))
        chosen = np.where(take_after, vertex_after, vertex_before)
        hinted = has_before | has_after
        # a triangle at each vertex (any one)
        slots = np.arange(3 * self._nt)
        at_vertex = np.empty(self._nv, dtype=np.int64)
        at_vertex[self.vertex[slots]] = slots // 3
        near[level[hinted]] = at_vertex[chosen[hinted]]

    def _insert_level(
        self,
        px: np.ndarray,
        py: np.ndarray,
        pending: np.ndarray,
        near: np.ndarray,
        ids: np.ndarray,
        origin: np.ndarray,
        boundary: bool,
    ) -> None:
        """Insert the points ``pending`` in rounds of at most one per triangle, each looked
        for from its triangle ``near`` (then from ``origin``); their vertex ids into ``ids``."""
        while len(pending):
            tri, edge, found = self._locate(
                px[pending], py[pending], near[pending], origin[pending]
            )
            pending, tri, edge = pending[found], tri[found], edge[found]
            other = np.where(edge >= 0, self.across[3 * tri + np.maximum(edge, 0)], -1)
            if not boundary:
                inner = (edge < 0) | (other >= 0)
                pending, tri, edge, other = pending[inner], tri[inner], edge[inner], other[inner]
            if not len(pending):
                break
            partner = np.where(other >= 0, other // 3, -1)
            # one point per triangle (an edge point holds both of its edge's): the middle one
            # of the triangle's points in the order given wins, so that each split leaves
            # about as many on either side (the first would leave nearly all on one side)
            rank = _middle_first(tri)
            claim = self._claim
            np.minimum.at(claim, tri, rank)
            paired = partner >= 0
            np.minimum.at(claim, partner[paired], rank[paired])
            wins = claim[tri] == rank
            wins[paired] &= claim[partner[paired]] == rank[paired]
            claim[tri] = _FREE
            claim[partner[paired]] = _FREE
            ids[pending[wins]] = self._split(
                px[pending[wins]], py[pending[wins]], tri[wins], edge[wins], other[wins]
            )
            near[pending[~wins]] = tri[~wins]
            pending = pending[~wins]

    def _locate(
        self, px: np.ndarray, py: np.ndarray, start: np.ndarray, again: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per point: the triangle holding it (closed), the local edge it lies on (-1:
        strictly inside) and whether it was found and is no vertex. Visibility walks from
        ``start`` in lock-step; a point whose walk is blocked or long walks again from
        ``again`` where given, and is then looked for among all triangles of its region."""
        if again is not None:
            tri, edge, found, lost = self._walk(px, py, start)
            if len(lost):
                tri[lost], edge[lost], found[lost] = self._locate(px[lost], py[lost], again[lost])
            return tri, edge, found
        tri, edge, found, lost = self._walk(px, py, start)
        if len(lost):
            region = self.region[tri[lost]]
            for r in np.unique(region).tolist():
                among = np.flatnonzero(self.region[: self._nt] == r)
                for i in lost[region == r].tolist():
                    tri[i], edge[i], found[i] = self._scan(px[i], py[i], among)
        return tri, edge, found

    def _walk(
        self, px: np.ndarray, py: np.ndarray, start: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_locate`'s walks; also the points whose walk was blocked or long."""
        count = len(px)
        tri = start.copy()
        edge = np.full(count, -1, dtype=np.int64)
        found = np.zeros(count, dtype=bool)
        todo = np.arange(count)
        stuck: list[np.ndarray] = []  # walks blocked or too long: scanned at the end
        across, x, y = self.across, self.x, self.y
        limit = 64 + 8 * int(np.sqrt(self._nt))
        for step in range(limit):
            if not len(todo):
                break
            t = tri[todo]
            qx, qy = px[todo], py[todo]
            corners, signs = self._sides(t, qx, qy)
            inside = (signs >= 0).all(axis=1)
            done = todo[inside]
            zeros = signs[inside] == 0
            on_vertex = (x[corners[inside]] == qx[inside, None]) & (
                y[corners[inside]] == qy[inside, None]
            )
            found[done] = ~on_vertex.any(axis=1)
            edge[done] = np.where(zeros.any(axis=1), zeros.argmax(axis=1), -1)
            # step across a negative edge with a neighbour; the first one looked at turns
            # with the step, so that no walk keeps circling one way
            out = ~inside
            moving = todo[out]
            neg = signs[out] < 0
            slots = 3 * t[out][:, None] + np.arange(3)
            beyond = across[slots]
            usable = neg & (beyond >= 0)
            turn = (np.arange(3)[None, :] + step + moving[:, None]) % 3
            pick = np.take_along_axis(usable, turn, axis=1).argmax(axis=1)
            k = turn[np.arange(len(moving)), pick]
            can = usable[np.arange(len(moving)), k]
            tri[moving[can]] = beyond[np.arange(len(moving)), k][can] // 3
            stuck.append(moving[~can])
            todo = moving[can]
        stuck.append(todo)
        return tri, edge, found, np.concatenate(stuck)

    def _scan(self, px: float, py: float, among: np.ndarray) -> tuple[int, int, bool]:
        """:meth:`_locate` of one point among the triangles ``among`` (its region's)."""
        x, y = self.x, self.y
        corners, signs = self._sides(among, px, py)
        holding = np.flatnonzero((signs >= 0).all(axis=1))
        if not len(holding):
            return int(among[0]) if len(among) else 0, -1, False
        h = holding[0]
        if ((x[corners[h]] == px) & (y[corners[h]] == py)).any():
            return int(among[h]), -1, False
        zero = np.flatnonzero(signs[h] == 0)
        return int(among[h]), int(zero[0]) if len(zero) else -1, True

    def _sides(
        self, t: np.ndarray, px: np.ndarray | float, py: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The corners (n, 3) of the triangles ``t`` and the exact signs (n, 3) of the points
        against their edges: column k for the edge from corner k + 1 to corner k + 2."""
        corners = self.vertex[(3 * t)[:, None] + np.arange(3)]
        cx, cy = self.x[corners], self.y[corners]
        px = np.asarray(px, dtype=np.float64).reshape(-1, 1)
        py = np.asarray(py, dtype=np.float64).reshape(-1, 1)
        signs = orient_many(cx[:, _NEXT], cy[:, _NEXT], cx[:, _PREV], cy[:, _PREV], px, py)
        return corners, signs

    def _reserve(self, vertices: int, triangles: int) -> None:
        """Room for this many more vertices and triangles."""
        need_v, need_t = self._nv + vertices, self._nt + triangles
        self.x, self.y = grown(self.x, need_v), grown(self.y, need_v)
        if need_t > len(self.region):
            self.region = grown(self.region, need_t)
            size = len(self.region)
            self.vertex = grown(self.vertex, 3 * size)
            self.across = grown(self.across, 3 * size)
            self.fixed = grown(self.fixed, 3 * size)
            self.changed = grown(self.changed, size)
            claim = np.full(size, _FREE, dtype=np.int64)
            claim[: len(self._claim)] = self._claim
            self._claim = claim
            self._moved = np.full(3 * size, -1, dtype=np.int64)

    def _split(
        self, px: np.ndarray, py: np.ndarray, tri: np.ndarray, edge: np.ndarray, other: np.ndarray
    ) -> np.ndarray:
        """Insert one point into each triangle ``tri`` (no two alike, nor neighbours across
        an ``edge`` a point lies on), then flip; returns the new vertex ids."""
        count = len(px)
        inside = edge < 0
        interior = ~inside & (other >= 0)
        new_count = 2 * count - int(np.count_nonzero(~inside & ~interior))
        self._reserve(count, new_count)
        ids = np.arange(self._nv, self._nv + count)
        self.x[ids], self.y[ids] = px, py
        self._nv += count
        first_new = self._nt
        self._nt += new_count
        # new triangle ids: two per point, one per boundary-edge point
        per_point = np.where(inside | interior, 2, 1)
        new_start = first_new + np.cumsum(per_point) - per_point
        dirty = []
        i = np.flatnonzero(inside)
        if len(i):
            dirty.append(self._split_inside(ids[i], tri[i], new_start[i]))
        e = np.flatnonzero(~inside)
        if len(e):
            rows = _Rows()
            self._split_edges(rows, ids[e], tri[e], edge[e], other[e], new_start[e])
            touched = rows.write(self)
            made = rows.new_rows(first_new)
            self.region[made] = self.region[rows.source_of(made)]
            self.changed[touched // 3] = True
            dirty.append(rows.outer_slots())
        # edges opposite the new vertices may not be locally Delaunay
        self._flip_all(np.concatenate(dirty))
        return ids

    def _split_inside(self, p: np.ndarray, t: np.ndarray, new: np.ndarray) -> np.ndarray:
        """1 -> 3, for triangles that no other split of the batch touches: (p, b, c) keeps id
        t, (p, c, a) and (p, a, b) are the new ids. Returns the slots of the outer edges."""
        vertex, across, fixed = self.vertex, self.across, self.fixed
        base, s1, s2 = 3 * t, 3 * new, 3 * (new + 1)
        a, b, c = vertex[base], vertex[base + 1], vertex[base + 2]
        # the edge b c keeps its slot; c a and a b move to the new triangles
        old = np.concatenate([base + 1, base + 2])
        moved_to = np.concatenate([s1, s2])
        fixed[moved_to] = fixed[old]
        self._relink(old, moved_to)
        vertex[base] = p
        vertex[s1], vertex[s1 + 1], vertex[s1 + 2] = p, c, a
        vertex[s2], vertex[s2 + 1], vertex[s2 + 2] = p, a, b
        for slot in (base + 1, base + 2, s1 + 1, s1 + 2, s2 + 1, s2 + 2):
            fixed[slot] = False
        for one, two in ((base + 1, s1 + 2), (base + 2, s2 + 1), (s1 + 1, s2 + 2)):
            across[one] = two
            across[two] = one
        self.region[new] = self.region[t]
        self.region[new + 1] = self.region[t]
        self.changed[t] = True
        self.changed[new] = True
        self.changed[new + 1] = True
        return np.concatenate([base, s1, s2])

    def _split_edges(
        self,
        rows: _Rows,
        p: np.ndarray,
        t: np.ndarray,
        k: np.ndarray,
        other: np.ndarray,
        new: np.ndarray,
    ) -> None:
        """p on edge k = (u, v) of t = (w, u, v): 2 -> 4 with the triangle (z, v, u) across,
        1 -> 2 on the boundary; the halves of a fixed edge stay fixed."""
        v_, f = self.vertex, self.fixed
        base = 3 * t
        s_vw, s_wu = base + _NEXT[k], base + _PREV[k]
        w, u, v = v_[base + k], v_[s_vw], v_[s_wu]
        split = f[base + k]
        s1, s2 = base, 3 * new
        inner = other >= 0
        # the neighbour across: t3 = (z, v, u), slot j holding z; t4 the second new id
        o = np.where(inner, other, 0)
        s3 = o - o % 3
        s_uz, s_zv = s3 + _NEXT[o % 3], s3 + _PREV[o % 3]
        z = v_[o]
        s4 = s2 + 3
        none = np.full(len(t), -1)
        rows.add(
            t,
            t,
            (p, v, w),
            (s_vw, s2 + 2, np.where(inner, s4 + 1, none)),
            (True, False, False),
            (f[s_vw], 0, split),
        )
        rows.add(
            new,
            t,
            (p, w, u),
            (s_wu, np.where(inner, s3 + 2, none), s1 + 1),
            (True, False, False),
            (f[s_wu], split, 0),
        )
        i = np.flatnonzero(inner)
        t3 = s3[i] // 3
        rows.add(
            t3,
            t3,
            (p[i], u[i], z[i]),
            (s_uz[i], s4[i] + 2, s2[i] + 1),
            (True, False, False),
            (f[s_uz[i]], 0, split[i]),
        )
        rows.add(
            new[i] + 1,
            t3,
            (p[i], z[i], v[i]),
            (s_zv[i], s1[i] + 2, s3[i] + 1),
            (True, False, False),
            (f[s_zv[i]], split[i], 0),
        )

    def _flip_all(self, dirty: np.ndarray) -> None:
        """Flip edges that are not locally Delaunay, starting from the ``dirty`` slots, in
        passes of flips that share no triangle, until every edge looked at is."""
        vertex, across, fixed, x, y = self.vertex, self.across, self.fixed, self.x, self.y
        claim = self._claim
        while len(dirty):
            n = across[dirty]
            keep = (n >= 0) & ~fixed[dirty]
            s = self._distinct(np.minimum(dirty[keep], n[keep]))
            n = across[s]
            k = s % 3
            base = s - k
            a, b, c, d = vertex[s], vertex[base + _NEXT[k]], vertex[base + _PREV[k]], vertex[n]
            bad = np.flatnonzero(
                incircle_sos_many(x[a], y[a], x[b], y[b], x[c], y[c], x[d], y[d]) > 0
            )
            if not len(bad):
                break
            s, n = s[bad], n[bad]
            t1, t2 = s // 3, n // 3
            np.minimum.at(claim, t1, s)
            np.minimum.at(claim, t2, s)
            wins = (claim[t1] == s) & (claim[t2] == s)
            claim[t1] = _FREE
            claim[t2] = _FREE
            won = bad[wins]
            outer = self._flip(s[wins], n[wins], a[won], b[won], c[won], d[won])
            self.changed[t1[wins]] = True
            self.changed[t2[wins]] = True
            lost = s[~wins]
            if len(lost):
                # a loser whose triangle a winner flipped is one of the winner's outer edges
                mark = self._claim
                mark[t1[wins]] = 0
                mark[t2[wins]] = 0
                gone = (mark[lost // 3] == 0) | (mark[across[lost] // 3] == 0)
                mark[t1[wins]] = _FREE
                mark[t2[wins]] = _FREE
                lost = lost[~gone]
            dirty = np.concatenate([lost, outer])

    def _distinct(self, slots: np.ndarray) -> np.ndarray:
        """The distinct values of ``slots`` (slot ids), in no particular order (no sort)."""
        stamp = self._moved
        rank = np.arange(len(slots))
        stamp[slots] = rank
        first = stamp[slots] == rank
        stamp[slots] = -1
        return slots[first]

    def _relink(self, old: np.ndarray, new: np.ndarray) -> None:
        """Edges rewritten together (no slot twice) move from the slots ``old`` to ``new``:
        link each to wherever its other side is after all of them move. Reads the links of
        ``old`` first, so call it before any other link of those triangles is written."""
        across, moved = self.across, self._moved
        neighbour = across[old]
        moved[old] = new
        target = np.where(neighbour >= 0, moved[neighbour], -1)
        np.copyto(target, neighbour, where=target < 0)
        moved[old] = -1
        across[new] = target
        linked = target >= 0
        across[target[linked]] = new[linked]

    def _flip(
        self,
        s: np.ndarray,
        n: np.ndarray,
        a: np.ndarray,
        b: np.ndarray,
        c: np.ndarray,
        d: np.ndarray,
    ) -> np.ndarray:
        """Flip the edge (b, c) of slot s in t = (a, b, c), d across it (slot n), for flips
        that share no triangle: t becomes (a, b, d) and the neighbour (a, d, c). Returns the
        slots of the four outer edges (to check next)."""
        vertex, across, fixed = self.vertex, self.across, self.fixed
        k = s % 3
        base = s - k
        j = n % 3
        q = n - j
        # the outer edges' old slots (b d, a b, d c, c a) and the slots they move to
        old = np.concatenate([q + _NEXT[j], base + _PREV[k], q + _PREV[j], base + _NEXT[k]])
        new = np.concatenate([base, base + 2, q, q + 1])
        fixed[new] = fixed[old]
        self._relink(old, new)
        vertex[base], vertex[base + 1], vertex[base + 2] = a, b, d
        vertex[q], vertex[q + 1], vertex[q + 2] = a, d, c
        fixed[base + 1] = False
        fixed[q + 2] = False
        across[base + 1] = q + 2
        across[q + 2] = base + 1
        return new


class _Rows:
    """Triangles to write at once: per triangle id its three vertices, per slot either an
    old slot whose edge it now carries (``outer``, linked to wherever that edge's other side
    is after every rewrite of the batch) or the new slot across (or -1), and its fixed flag."""

    def __init__(self) -> None:
        self.parts: list[tuple[np.ndarray, ...]] = []

    def add(
        self,
        tri: np.ndarray,
        source: np.ndarray,
        vertices: tuple[np.ndarray, ...],
        links: tuple[np.ndarray, ...],
        outer: tuple[bool, bool, bool],
        fixed: tuple[np.ndarray | int, ...],
    ) -> None:
        tri = np.asarray(tri, dtype=np.int64)
        m = len(tri)
        columns = [np.broadcast_to(np.asarray(c), (m,)) for c in (*vertices, *links, *fixed)]
        self.parts.append((tri, np.broadcast_to(source, (m,)), *columns, np.array(outer)))

    def _stack(self) -> tuple[np.ndarray, ...]:
        tri = np.concatenate([p[0] for p in self.parts])
        source = np.concatenate([p[1] for p in self.parts])
        vertices = np.concatenate([np.column_stack(p[2:5]) for p in self.parts])
        links = np.concatenate([np.column_stack(p[5:8]).astype(np.int64) for p in self.parts])
        fixed = np.concatenate([np.column_stack(p[8:11]).astype(bool) for p in self.parts])
        outer = np.concatenate([np.broadcast_to(p[11], (len(p[0]), 3)) for p in self.parts])
        return tri, source, vertices, links, fixed, outer

    def write(self, mesh: MeshSet) -> np.ndarray:
        """Write the triangles into ``mesh``; returns their slots."""
        if not self.parts:
            self._outer = np.zeros(0, dtype=np.int64)
            self._tri = np.zeros(0, dtype=np.int64)
            self._source = np.zeros(0, dtype=np.int64)
            return np.zeros(0, dtype=np.int64)
        tri, source, vertices, links, fixed, outer = self._stack()
        slots = (3 * tri)[:, None] + np.arange(3)
        across = mesh.across
        # where each outer edge's old slot goes: its edge's new slot
        old = links[outer]
        new = slots[outer]
        mesh._relink(old, new)
        mesh.vertex[slots] = vertices
        mesh.fixed[slots] = fixed
        inner = ~outer
        across[slots[inner]] = links[inner]
        self._outer = new
        self._tri, self._source = tri, source
        return slots.ravel()

    def outer_slots(self) -> np.ndarray:
        """The slots of the outer edges written (to check for flips)."""
        return self._outer

    def new_rows(self, first: int) -> np.ndarray:
        """The triangle ids written from ``first`` on (new ones)."""
        return self._tri[self._tri >= first]

    def source_of(self, made: np.ndarray) -> np.ndarray:
        """The triangle each of the ids ``made`` (written here) was made from."""
        order = np.argsort(self._tri, kind="stable")
        at = order[np.searchsorted(self._tri[order], made)]
        return self._source[at]


_FREE = np.iinfo(np.int64).max


def _middle_first(tri: np.ndarray) -> np.ndarray:
    """Per point (in the order given, ``tri`` its triangle) a distinct priority, lower first:
    within each triangle's points, how far it is from their middle one, then its place."""
    count = len(tri)
    order = np.argsort(tri, kind="stable")
    sorted_tri = tri[order]
    start = np.flatnonzero(np.r_[True, sorted_tri[1:] != sorted_tri[:-1]])
    size = np.diff(np.r_[start, count])
    middle = np.repeat(start + size // 2, size)
    priority = np.empty(count, dtype=np.int64)
    priority[order] = np.abs(np.arange(count) - middle) * count + order
    return priority


def grown(array: np.ndarray, size: int) -> np.ndarray:
    """``array`` if it has ``size`` entries, else it with zeros appended to ``size`` entries
    or twice its length, whichever is more (appending then costs amortised constant time)."""
    if len(array) >= size:
        return array
    more = np.zeros(max(size, 2 * len(array)), dtype=array.dtype)
    more[: len(array)] = array
    return more
