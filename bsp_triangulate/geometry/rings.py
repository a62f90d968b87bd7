"""Input normalisation: rings to clean vertex arrays, the working plane and the orientation."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..triangulation import TriangulationError
from .predicates import ring_area_sign, ring_area_signs


def ring_label(ring_number: int) -> str:
    """Human name of input ring ``ring_number`` (0-based): 'ring 1 (outer)', 'ring 3 (island 2)';
    a negative number -k names the given interior point k ('point 4')."""
    if ring_number < 0:
        return f"point {-ring_number}"
    if ring_number == 0:
        return "ring 1 (outer)"
    return f"ring {ring_number + 1} (island {ring_number})"


@dataclass
class PreparedRings:
    """Normalised rings in the working plane, ready for bridging.

    - ``vertices``: (N, 3) output coordinates, the concatenation of all normalised rings.
    - ``x``, ``y``: (N,) working-plane coordinates (mirrored so that the outer ring is CCW).
    - ``rings``: vertex ids of each usable ring, the outer ring counter-clockwise first, then
      the islands clockwise (traversal order), in input order.
    - ``ring_numbers``: the input ring index of each entry of ``rings``.
    - ``ring_of``: (N,) input ring index of every vertex.
    - ``mirrored``: the first working coordinate was negated (the outer ring was clockwise).
    """

    vertices: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rings: list[np.ndarray]
    ring_numbers: list[int]
    ring_of: np.ndarray
    mirrored: bool = False

    @property
    def is_degenerate(self) -> bool:
        return not self.rings

    def with_points(
        self, points: np.ndarray, px: np.ndarray, py: np.ndarray, numbers: np.ndarray
    ) -> PreparedRings:
        """These rings with interior points appended to the vertices: ``points`` (k, 3) output
        coordinates, ``px``, ``py`` their working coordinates (mirrored as ``x``), ``numbers``
        their 0-based positions among the given points (``ring_of`` holds -1 - number)."""
        return PreparedRings(
            np.concatenate([self.vertices, points]),
            np.concatenate([self.x, px]),
            np.concatenate([self.y, py]),
            self.rings,
            self.ring_numbers,
            np.concatenate([self.ring_of, -1 - np.asarray(numbers, dtype=np.int64)]),
            self.mirrored,
        )


def _as_points(ring: object, ring_number: int) -> np.ndarray:
    """One input ring as an (n, 3) float64 array (z = 0 where absent)."""
    try:
        points = np.asarray(ring, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TriangulationError(
            f"{ring_label(ring_number)}: not a sequence of numeric points ({exc})"
        ) from None
    if points.size == 0:
        return np.zeros((0, 3))
    if points.ndim != 2 or points.shape[1] not in (2, 3, 4):
        raise TriangulationError(
            f"{ring_label(ring_number)}: expected points of 2 or 3 coordinates, "
            f"got an array of shape {points.shape}"
        )
    if not np.isfinite(points[:, :3]).all():
        raise TriangulationError(f"{ring_label(ring_number)}: coordinates are not finite")
    if points.shape[1] == 2:
        return np.column_stack([points, np.zeros(len(points))])
    return np.ascontiguousarray(points[:, :3])


# A ring is a wall when the Newell normal's horizontal part exceeds this multiple of its z.
WALL_RATIO = 10.0
# Working planes: "auto" is XY unless the outer ring is a steep face (x, y and z in the same
# unit); "xy" is always XY (footprints draped on terrain, or z in another unit than x and y).
PLANES = ("auto", "xy")


def working_axes(outer: np.ndarray) -> tuple[int, int]:
    """The two coordinates the engine works on: XY unless the outer ring is a steep face."""
    if len(outer) < 3:
        return 0, 1
    largest = float(np.abs(outer).max())
    if largest > 0:
        outer = outer / largest  # only a decision: rounding is harmless, overflow is not
    nxt = np.roll(outer, -1, axis=0)
    normal = np.array(
        [
            np.sum((outer[:, 1] - nxt[:, 1]) * (outer[:, 2] + nxt[:, 2])),
            np.sum((outer[:, 2] - nxt[:, 2]) * (outer[:, 0] + nxt[:, 0])),
            np.sum((outer[:, 0] - nxt[:, 0]) * (outer[:, 1] + nxt[:, 1])),
        ]
    )
    magnitude = np.abs(normal)
    # Any face that is not close to vertical projects to XY as an affine image of itself, so XY
    # gives the same triangles; only near-vertical faces (steeper than about 84 degrees, whose
    # XY shadow degenerates) are worked on the plane of their dominant normal components.
    if magnitude[2] * WALL_RATIO >= max(magnitude[0], magnitude[1]):
        return 0, 1
    if magnitude[0] >= magnitude[1]:
        return 1, 2
    return 0, 2


def xy_mirror(rings: Sequence[object]) -> float:
    """-1.0 where the outer ring of ``rings`` is clockwise in XY (the working plane then
    mirrors x, as :func:`prepare` does), else 1.0."""
    outer = np.asarray(rings[0], dtype=np.float64)
    return -1.0 if ring_area_sign(outer[:, 0], outer[:, 1]) < 0 else 1.0


def _clean(points: np.ndarray, axes: tuple[int, int]) -> np.ndarray:
    """Drop consecutive duplicates (equal in the working plane) and the closing point."""
    if len(points) == 0:
        return points
    plane = points[:, axes]
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = np.any(plane[1:] != plane[:-1], axis=1)
    points = points[keep]
    plane = plane[keep]
    while len(points) > 1 and np.array_equal(plane[-1], plane[0]):
        points = points[:-1]
        plane = plane[:-1]
    return points


def normalise_rings(
    rings: Sequence[object], plane: str = "auto"
) -> tuple[list[np.ndarray], tuple[int, int]]:
    """Parse, validate and clean the input rings; returns the rings and the working axes
    (``plane``: one of :data:`PLANES`)."""
    if isinstance(rings, np.ndarray) and rings.ndim == 2:
        rings = [rings]
    if not isinstance(rings, (Sequence, np.ndarray)):
        rings = list(rings)  # an iterator of rings
    if len(rings) > _MANY_RINGS:
        many = _many_rings(rings, plane)
        if many is not None:
            return many
    raw = [_as_points(ring, number) for number, ring in enumerate(rings)]
    if not raw:
        return [], (0, 1)
    axes = (0, 1) if plane == "xy" else working_axes(raw[0])
    return [_clean(points, axes) for points in raw], axes


# more rings than this are parsed and cleaned all at once (:func:`_many_rings`)
_MANY_RINGS = 16


def _many_rings(
    rings: Sequence[object], plane: str
) -> tuple[list[np.ndarray], tuple[int, int]] | None:
    """:func:`normalise_rings` of many rings in one pass over their concatenation, where every
    ring is a non-empty array of points with the same number of coordinates (None otherwise,
    and where a ring has a coordinate that is not finite: the ring by ring path says which).
    A ring cleaned loses its consecutive duplicates, then its last point where that equals
    its first: the point before it differs from it, so one such point at most."""
    raw = []
    try:
        for ring in rings:
            raw.append(np.asarray(ring, dtype=np.float64))
    except (TypeError, ValueError):
        return None
    width = raw[0].shape[1] if raw[0].ndim == 2 else 0
    if width not in (2, 3, 4) or any(p.ndim != 2 or p.shape[1] != width or not len(p) for p in raw):
        return None
    every = np.concatenate(raw)
    if width == 2:
        every = np.column_stack([every, np.zeros(len(every))])
    elif width == 4:
        every = np.ascontiguousarray(every[:, :3])
    if not np.isfinite(every).all():
        return None
    sizes = np.array([len(points) for points in raw], dtype=np.int64)
    axes = (0, 1) if plane == "xy" else working_axes(every[: sizes[0]])
    starts = np.cumsum(sizes) - sizes
    u, v = every[:, axes[0]], every[:, axes[1]]
    keep = np.ones(len(every), dtype=bool)
    keep[1:] = (u[1:] != u[:-1]) | (v[1:] != v[:-1])
    keep[starts] = True
    # each ring's last kept point, dropped where it equals the ring's first (not alone)
    kept = np.flatnonzero(keep)
    counts = np.add.reduceat(keep, starts)
    last = kept[np.cumsum(counts) - 1]
    closing = (counts > 1) & (u[last] == u[starts]) & (v[last] == v[starts])
    keep[last[closing]] = False
    counts -= closing
    every = every[keep]
    return np.split(every, np.cumsum(counts)[:-1]), axes


def _ranks(counts: np.ndarray) -> np.ndarray:
    """0 .. counts[i] - 1 for each i, concatenated."""
    return np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(
        np.cumsum(counts) - counts, counts
    )


def prepare(clean_rings: list[np.ndarray], axes: tuple[int, int]) -> PreparedRings:
    """Working-plane coordinates, orientation and the usable rings of normalised input."""
    sizes = [len(r) for r in clean_rings]
    vertices = np.concatenate(clean_rings) if clean_rings else np.zeros((0, 3))
    vertices = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    ring_of = np.repeat(np.arange(len(sizes), dtype=np.int64), sizes)
    x = vertices[:, axes[0]].copy()
    y = vertices[:, axes[1]].copy()
    empty = PreparedRings(vertices, x, y, [], [], ring_of)
    if not clean_rings or sizes[0] < 3:
        return empty
    outer_ids = np.arange(starts[0], starts[1])
    outer_sign = ring_area_sign(x[outer_ids], y[outer_ids])
    if outer_sign == 0:
        return empty
    if outer_sign < 0:
        x = -x  # mirror: exact, keeps the vertex order
    rings = [outer_ids]
    numbers = [0]
    # the islands' signs in float at once where sure, exactly one by one where not
    counts = np.array(sizes[1:], dtype=np.int64)
    signs = np.zeros(len(counts), dtype=np.int64)
    usable = np.flatnonzero(counts >= 3)
    if len(usable):
        kept = counts[usable]
        laid = np.repeat(starts[1:-1][usable], kept) + _ranks(kept)  # one ring after another
        signs[usable], _ = ring_area_signs(x[laid], y[laid], np.cumsum(kept) - kept, kept)
    for index in range(len(counts)):
        number = index + 1
        if counts[index] < 3:
            continue
        ids = np.arange(starts[number], starts[number + 1])
        sign = int(signs[index]) or ring_area_sign(x[ids], y[ids])
        if sign == 0:
            continue
        rings.append(ids[::-1].copy() if sign > 0 else ids)
        numbers.append(number)
    return PreparedRings(vertices, x, y, rings, numbers, ring_of, outer_sign < 0)
