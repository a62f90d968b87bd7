"""Many polygons and their triangulations as flat arrays, with no Python object per polygon.

``PackedPolygons`` is the input of ``api.triangulate_packed`` and ``PackedTriangulations``
its output: the same polygons and results as lists of rings and of :class:`Triangulation`,
laid out one after another, so that a whole layer goes in and out with a few numpy arrays.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .geometry.rings_batch import ragged_index, stack_rings
from .triangulation import Triangulation, TriangulationError


@dataclass
class PackedPolygons:
    """Polygons as flat arrays.

    - ``points``: (N, 2, 3 or 4) float64, x, y[, z[, m]] of every ring, one ring after
      another (a closing point is optional, as in lists of rings);
    - ``ring_len``: (R,) points of each ring;
    - ``ring_count``: (P,) rings of each polygon, its outer ring first.
    """

    points: np.ndarray
    ring_len: np.ndarray
    ring_count: np.ndarray

    def __post_init__(self) -> None:
        self.points = np.asarray(self.points, dtype=np.float64)
        self.ring_len = np.asarray(self.ring_len, dtype=np.int64).reshape(-1)
        self.ring_count = np.asarray(self.ring_count, dtype=np.int64).reshape(-1)
        if self.points.ndim != 2 or self.points.shape[1] not in (2, 3, 4):
            raise ValueError("points must be an (N, 2), (N, 3) or (N, 4) array")
        if (self.ring_len < 0).any() or int(self.ring_len.sum()) != len(self.points):
            raise ValueError("ring_len must be non-negative and add up to the points")
        if (self.ring_count < 0).any() or int(self.ring_count.sum()) != len(self.ring_len):
            raise ValueError("ring_count must be non-negative and add up to the rings")
        self._ring_start = np.cumsum(self.ring_len) - self.ring_len
        self._first_ring = np.cumsum(self.ring_count) - self.ring_count

    @classmethod
    def of(cls, polygons: Sequence[Sequence[np.ndarray]]) -> PackedPolygons:
        """Pack lists of rings ((n, 2) to (n, 4) arrays or point lists, empty rings too) as
        (N, 3) points: missing z becomes 0, m is dropped."""
        rings = [np.asarray(ring, dtype=np.float64) for rings in polygons for ring in rings]
        rings = [ring.reshape(0, 2) if ring.size == 0 else ring for ring in rings]
        widths = np.array([ring.shape[1] for ring in rings], dtype=np.int64)
        ring_len = np.array([len(ring) for ring in rings], dtype=np.int64)
        ring_count = np.array([len(rings) for rings in polygons], dtype=np.int64)
        return cls(stack_rings(rings, widths), ring_len, ring_count)

    def __len__(self) -> int:
        return len(self.ring_count)

    @property
    def ring_start(self) -> np.ndarray:
        """(R,) the first point of each ring."""
        return self._ring_start

    @property
    def first_ring(self) -> np.ndarray:
        """(P,) the first ring of each polygon."""
        return self._first_ring

    def take(self, polygons: np.ndarray) -> PackedPolygons:
        """The polygons ``polygons`` (indices), in that order."""
        polygons = np.asarray(polygons, dtype=np.int64)
        rings = ragged_index(self._first_ring[polygons], self.ring_count[polygons])
        rows = ragged_index(self._ring_start[rings], self.ring_len[rings])
        return PackedPolygons(self.points[rows], self.ring_len[rings], self.ring_count[polygons])

    def rings(self, index: int) -> list[np.ndarray]:
        """The rings of polygon ``index`` (views of ``points``)."""
        first = int(self._first_ring[index])
        rings = range(first, first + int(self.ring_count[index]))
        starts, lengths = self._ring_start, self.ring_len
        return [self.points[starts[r] : starts[r] + lengths[r]] for r in rings]


@dataclass
class PackedTriangulations:
    """Triangulations of many polygons, one after another in polygon order.

    Polygon i has the vertices ``vertices[vertex_start[i]:][:vertex_count[i]]`` and the
    triangles ``triangles[triangle_start[i]:][:triangle_count[i]]`` (indices into its own
    vertices), with their ``parent``, ``depth`` and ``side``, all as in
    :class:`Triangulation`. A polygon that failed has no vertices and no triangles and its
    error in ``errors``. Interior points: polygon i was given ``point_count[i]`` of them,
    whose ``point_ids`` (rows of its own vertices, -1 where unused or where the polygon
    failed) are ``point_ids[point_start[i]:][:point_count[i]]``; without points
    ``point_ids`` is empty and ``point_count`` all zero.
    """

    vertices: np.ndarray
    vertex_count: np.ndarray
    triangles: np.ndarray
    triangle_count: np.ndarray
    parent: np.ndarray
    depth: np.ndarray
    side: np.ndarray
    errors: dict[int, TriangulationError] = field(default_factory=dict)
    point_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    point_count: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        if len(self.point_count) != len(self.vertex_count):
            self.point_count = np.zeros(len(self.vertex_count), dtype=np.int64)

    @classmethod
    def without_triangles(
        cls,
        vertices: np.ndarray,
        vertex_count: np.ndarray,
        errors: dict[int, TriangulationError] | None = None,
    ) -> PackedTriangulations:
        """Polygons with ``vertex_count`` of ``vertices`` each and no triangle (empty or
        failed results)."""
        none = np.zeros(0, dtype=np.int64)
        return cls(
            vertices, vertex_count, np.zeros((0, 3), np.int64),
            np.zeros(len(vertex_count), np.int64), none, none, np.zeros(0, np.int8),
            errors or {},
        )  # fmt: skip

    def __len__(self) -> int:
        return len(self.vertex_count)

    # computed once: ``self[i]`` on every polygon in turn stays linear
    @functools.cached_property
    def vertex_start(self) -> np.ndarray:
        return np.cumsum(self.vertex_count) - self.vertex_count

    @functools.cached_property
    def triangle_start(self) -> np.ndarray:
        return np.cumsum(self.triangle_count) - self.triangle_count

    @functools.cached_property
    def point_start(self) -> np.ndarray:
        return np.cumsum(self.point_count) - self.point_count

    def __getitem__(self, index: int) -> Triangulation | TriangulationError:
        if index in self.errors:
            return self.errors[index]
        result = self._slice(
            int(self.vertex_start[index]), int(self.vertex_count[index]),
            int(self.triangle_start[index]), int(self.triangle_count[index]),
        )  # fmt: skip
        if len(self.point_ids):
            start = int(self.point_start[index])
            result.point_ids = self.point_ids[start : start + int(self.point_count[index])]
        return result

    def _slice(self, v: int, n: int, t: int, m: int) -> Triangulation:
        """The polygon of ``n`` vertices from row ``v`` and ``m`` triangles from row ``t``."""
        return Triangulation(
            vertices=self.vertices[v : v + n],
            triangles=self.triangles[t : t + m],
            parent=self.parent[t : t + m],
            depth=self.depth[t : t + m],
            side=self.side[t : t + m],
        )

    def take(self, polygons: np.ndarray) -> PackedTriangulations:
        """The results of ``polygons`` (indices), in that order, without the errors."""
        vertex_rows = ragged_index(self.vertex_start[polygons], self.vertex_count[polygons])
        rows = ragged_index(self.triangle_start[polygons], self.triangle_count[polygons])
        taken = PackedTriangulations(
            self.vertices[vertex_rows], self.vertex_count[polygons], self.triangles[rows],
            self.triangle_count[polygons], self.parent[rows], self.depth[rows], self.side[rows],
        )  # fmt: skip
        if len(self.point_ids):
            point_rows = ragged_index(self.point_start[polygons], self.point_count[polygons])
            taken.point_ids = self.point_ids[point_rows]
            taken.point_count = self.point_count[polygons]
        return taken

    def tree(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(parent, depth, side) of every triangle."""
        return self.parent, self.depth, self.side

    def to_list(self) -> list[Triangulation | TriangulationError]:
        """One :class:`Triangulation` (slices of these arrays) or error per polygon."""
        v0, t0 = self.vertex_start, self.triangle_start
        rows = zip(
            v0.tolist(), (v0 + self.vertex_count).tolist(),
            t0.tolist(), (t0 + self.triangle_count).tolist(),
        )  # fmt: skip
        vertices, triangles, parent, depth, side = (
            self.vertices, self.triangles, self.parent, self.depth, self.side
        )  # fmt: skip
        # one empty view for every result without points (it has no element to change)
        none = self.point_ids[:0]
        out: list[Triangulation | TriangulationError] = [
            Triangulation(vertices[a:b], triangles[c:d], parent[c:d], depth[c:d], side[c:d], none)
            for a, b, c, d in rows
        ]
        if len(self.point_ids):
            p0 = self.point_start.tolist()
            p1 = (self.point_start + self.point_count).tolist()
            for result, a, b in zip(out, p0, p1):
                result.point_ids = self.point_ids[a:b]
        for index, error in self.errors.items():
            out[index] = error
        return out


@dataclass
class Piece:
    """The results of some polygons of a call: their indices (increasing) and their
    triangulations, packed in that order."""

    index: np.ndarray
    results: PackedTriangulations

    @classmethod
    def of(cls, index: int, result: Triangulation) -> Piece:
        return cls(
            np.array([index], dtype=np.int64),
            PackedTriangulations(
                np.asarray(result.vertices, dtype=np.float64).reshape(-1, 3),
                np.array([len(result.vertices)], dtype=np.int64),
                np.asarray(result.triangles, dtype=np.int64).reshape(-1, 3),
                np.array([len(result.triangles)], dtype=np.int64),
                np.asarray(result.parent, dtype=np.int64),
                np.asarray(result.depth, dtype=np.int64),
                np.asarray(result.side, dtype=np.int8),
                point_ids=np.asarray(result.point_ids, dtype=np.int64),
                point_count=np.array([len(result.point_ids)], dtype=np.int64),
            ),
        )


def assemble(
    count: int,
    pieces: list[Piece],
    errors: dict[int, TriangulationError],
    point_count: np.ndarray | None = None,
) -> PackedTriangulations:
    """The pieces (each polygon in one of them, or failed in ``errors``) in polygon order.

    ``point_count``: the interior points given per polygon (None: none); those of a polygon
    that failed get the point id -1.
    """
    pieces = [piece for piece in pieces if len(piece.index)]
    result = _assemble_triangles(count, pieces, errors)
    if point_count is None and not any(p.results.point_count.any() for p in pieces):
        return result
    counts = np.zeros(count, dtype=np.int64)
    for piece in pieces:
        counts[piece.index] = piece.results.point_count
    if point_count is not None:
        counts = np.asarray(point_count, dtype=np.int64)
    point_ids = np.full(int(counts.sum()), -1, dtype=np.int64)
    if pieces:
        index = np.concatenate([piece.index for piece in pieces])
        rows = ragged_index(
            (np.cumsum(counts) - counts)[index],
            np.concatenate([piece.results.point_count for piece in pieces]),
        )
        point_ids[rows] = np.concatenate([piece.results.point_ids for piece in pieces])
    result.point_ids, result.point_count = point_ids, counts
    return result


def _assemble_triangles(
    count: int, pieces: list[Piece], errors: dict[int, TriangulationError]
) -> PackedTriangulations:
    """:func:`assemble` without the interior points."""
    if not pieces:
        return PackedTriangulations.without_triangles(
            np.zeros((0, 3)), np.zeros(count, dtype=np.int64), errors
        )
    index = np.concatenate([piece.index for piece in pieces])
    vcount = np.concatenate([piece.results.vertex_count for piece in pieces])
    tcount = np.concatenate([piece.results.triangle_count for piece in pieces])
    vertex_count = np.zeros(count, dtype=np.int64)
    triangle_count = np.zeros(count, dtype=np.int64)
    vertex_count[index] = vcount
    triangle_count[index] = tcount
    fields = [
        np.concatenate([getattr(piece.results, name) for piece in pieces]) if len(pieces) > 1
        else getattr(pieces[0].results, name)
        for name in ("vertices", "triangles", "parent", "depth", "side")
    ]  # fmt: skip
    vertices, triangles, parent, depth, side = fields
    if len(index) > 1 and (np.diff(index) < 0).any():
        # pieces out of polygon order: one gather per field
        joined = PackedTriangulations(vertices, vcount, triangles, tcount, parent, depth, side)
        ordered = joined.take(np.argsort(index, kind="stable"))
        vertices, triangles = ordered.vertices, ordered.triangles
        parent, depth, side = ordered.parent, ordered.depth, ordered.side
    return PackedTriangulations(
        vertices, vertex_count, triangles, triangle_count, parent, depth, side, errors
    )
