"""Polygon WKBs for the validity proof's tests: stars, grid polygons full of exact touches and
collinear points, near-degenerate rings, multipolygons (shared by the core and QGIS tests)."""

from __future__ import annotations

import struct

import numpy as np


def ring_wkb(points: np.ndarray, close: bool = True) -> bytes:
    points = np.asarray(points, dtype=np.float64)
    if close and len(points):
        points = np.vstack([points, points[:1]])
    return struct.pack("<I", len(points)) + points.astype("<f8").tobytes()


def polygon_wkb(rings: list[np.ndarray], close: bool = True) -> bytes:
    return struct.pack("<BII", 1, 3, len(rings)) + b"".join(ring_wkb(r, close) for r in rings)


def multipolygon_wkb(polygons: list[list[np.ndarray]]) -> bytes:
    return struct.pack("<BII", 1, 6, len(polygons)) + b"".join(
        polygon_wkb(rings) for rings in polygons
    )


def star(rng: np.random.Generator, centre, count: int, outer: float, inner: float, jitter=0.1):
    angles = rng.uniform(0, np.pi) + 2 * np.pi * np.arange(count) / count
    radii = np.where(np.arange(count) % 2 == 0, outer, inner)
    radii = radii * (1 + rng.uniform(-jitter, jitter, count))
    return np.column_stack([centre[0] + radii * np.cos(angles), centre[1] + radii * np.sin(angles)])


def star_cases(seed: int = 1, count: int = 400) -> list[bytes]:
    """Stars with islands: inside, crossing, touching, outside, nested; some deep spikes."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(count):
        centre = rng.uniform(-1e3, 1e3, 2)
        outer = star(rng, centre, int(rng.integers(3, 40)), 45, rng.uniform(5, 44))
        rings = [outer if rng.random() < 0.7 else outer[::-1]]
        for _island in range(int(rng.integers(0, 4))):
            offset = rng.normal(0, 12, 2)
            size = rng.uniform(2, 20)
            island = star(rng, centre + offset, int(rng.integers(3, 12)), size, size * 0.6)
            rings.append(island[::-1] if rng.random() < 0.7 else island)
        cases.append(polygon_wkb(rings))
    return cases


def grid_cases(seed: int = 2, count: int = 3000) -> list[bytes]:
    """Small rings on a 6 x 6 integer grid: exact touches, collinear and repeated points."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(count):

        def ring(low: int, high: int) -> np.ndarray:
            n = int(rng.integers(3, 8))
            return rng.integers(low, high, (n, 2)).astype(np.float64)

        polygons = []
        for _part in range(1 if rng.random() < 0.7 else int(rng.integers(2, 4))):
            shift = rng.integers(0, 8, 2) if rng.random() < 0.5 else np.zeros(2)
            rings = [ring(0, 6) + shift]
            rings += [ring(1, 5) + shift for _ in range(int(rng.integers(0, 3)))]
            polygons.append(rings)
        if len(polygons) == 1 and rng.random() < 0.5:
            cases.append(polygon_wkb(polygons[0]))
        else:
            cases.append(multipolygon_wkb(polygons))
    return cases


def convex_cases(seed: int = 3, count: int = 1000) -> list[bytes]:
    """Convex polygons and squares with square islands, placed to be valid or barely not."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(count):
        n = int(rng.integers(3, 30))
        angles = np.sort(rng.uniform(0, 2 * np.pi, n))
        scale = 10.0 ** rng.integers(-9, 12)
        shell = (np.column_stack([np.cos(angles), np.sin(angles)]) + rng.normal(0, 3, 2)) * scale
        rings = [shell]
        if rng.random() < 0.5:
            half = rng.choice([0.1, 0.5, 0.7, 1.0, 1.2]) * scale
            centre = shell.mean(axis=0) + rng.choice([0.0, 0.3, 1e-16]) * scale
            square = centre + half * np.array([[-1, -1], [-1, 1], [1, 1], [1, -1]]) / np.sqrt(2)
            rings.append(square)
        if rng.random() < 0.2:
            # a point moved by a hair onto, or just past, an edge or a neighbour
            i = int(rng.integers(0, n))
            j = (i + 1) % n
            rings[0] = shell.copy()
            rings[0][i] = shell[j] + rng.choice([0.0, 1e-16, -1e-16]) * scale
        cases.append(polygon_wkb(rings))
    return cases


# building outlines in a unit square: L, T, U (not star-shaped around their vertex mean)
OUTLINES = (
    [(0, 0), (1, 0), (1, 0.45), (0.5, 0.45), (0.5, 1), (0, 1)],
    [(0.3, 0), (0.7, 0), (0.7, 0.6), (1, 0.6), (1, 1), (0, 1), (0, 0.6), (0.3, 0.6)],
    [(0, 0), (1, 0), (1, 1), (0.7, 1), (0.7, 0.4), (0.3, 0.4), (0.3, 1), (0, 1)],
)


def footprint_cases(seed: int = 4, count: int = 1500) -> tuple[list[bytes], list[bool]]:
    """Rotated L, T and U outlines, some with a courtyard, and broken copies: a vertex moved
    onto another edge, onto another vertex or across an edge. Returns the WKBs and which of
    them are intact (unbroken)."""
    rng = np.random.default_rng(seed)
    cases, intact = [], []
    for _ in range(count):
        shape = np.array(OUTLINES[int(rng.integers(len(OUTLINES)))], dtype=np.float64)
        angle = rng.uniform(0, 2 * np.pi)
        rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        scale = rng.uniform(5, 40) * 10.0 ** rng.integers(-3, 4)
        origin = rng.uniform(-1e6, 1e6, 2)
        outline = shape * scale
        broken = rng.random() < 0.4
        if broken:
            i = int(rng.integers(len(shape)))
            j = int(rng.integers(len(shape)))
            k = (j + 1) % len(shape)
            where = rng.choice(["vertex", "edge", "across"])
            if where == "vertex":
                outline[i] = outline[j]
            elif where == "edge":
                outline[i] = 0.5 * (outline[j] + outline[k])
            else:
                outline[i] = outline[j] + 1.5 * (outline[k] - outline[j])
        rings = [outline @ rotation.T + origin]
        if rng.random() < 0.3:
            # a small square courtyard where all three outlines are solid
            yard = np.array([[0.4, 0.05], [0.4, 0.2], [0.55, 0.2], [0.55, 0.05]]) * scale
            rings.append(yard @ rotation.T + origin)
        cases.append(polygon_wkb(rings if rng.random() < 0.5 else [r[::-1] for r in rings]))
        intact.append(not broken)
    return cases, intact


def special_cases() -> list[bytes]:
    """Hand-made cases: unclosed rings, NaN, huge and tiny coordinates, spikes, bow ties."""
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], dtype=np.float64)
    triangle = np.array([[0, 0], [0, 2], [2, 0]], dtype=np.float64)
    cases = [
        polygon_wkb([square]),
        polygon_wkb([square[::-1]]),
        polygon_wkb([square], close=False),
        polygon_wkb([np.vstack([square, square[:1] + np.array([1e-9, 0])])], close=False),
        polygon_wkb([square * 1e200]),
        polygon_wkb([square * 1e-200]),
        polygon_wkb([square + np.array([1e15, 1e15])]),
        polygon_wkb([np.array([[0, 0], [10, 0], [np.nan, 10], [0, 10]])]),
        polygon_wkb([np.array([[0, 0], [10, 0], [np.inf, 10], [0, 10]])]),
        polygon_wkb([np.array([[0, 0], [10, 0], [10, 0], [10, 10], [0, 10]])]),
        polygon_wkb([np.array([[0, 0], [10, 10], [10, 0], [0, 10]])]),
        polygon_wkb([np.array([[0, 0], [4, 0], [4, 4], [2, 4], [2, 6], [2, 4], [0, 4]])]),
        polygon_wkb([np.array([[0, 0], [5, 0], [10, 0], [5, 5]])]),
        polygon_wkb([np.array([[0, 0], [1, 1], [2, 2], [3, 3]])]),
        polygon_wkb([np.array([[0, 0], [3, 0], [0, 3]]), np.array([[1, 1], [1, 1.5], [1.5, 1]])]),
        polygon_wkb([square, np.array([[0, 0], [3, 1], [1, 3]])]),
        polygon_wkb([square, np.array([[2, 2], [2, 4], [4, 4], [4, 2]])[::-1]] * 1),
        polygon_wkb([square, triangle + 2, np.array([[2, 4], [4, 4], [4, 2]])]),
        polygon_wkb([square, np.array([[1, 1], [1, 9], [9, 9], [9, 1]]), triangle + 3]),
        polygon_wkb([square, square]),
        polygon_wkb([square, np.array([[0, 5], [5, 5], [5, 7]])]),
        polygon_wkb([square, np.array([[-1, 5], [5, 5], [5, 7]])]),
        polygon_wkb([square, np.array([[5, 5], [6, 5], [6, 6]])]),
        polygon_wkb([square, np.array([[5, 5], [6, 5], [6, 6]]) + np.array([20, 0])]),
        polygon_wkb([square, np.array([[1, 1], [1, 9], [9, 9], [9, 1]]) - np.array([1, 0])]),
        polygon_wkb([np.array([[0, 0], [1, 0], [0.5, 1e-17]])]),
        polygon_wkb([np.array([[0, 0], [1, 0], [0.5, 1e-300]])]),
        polygon_wkb([np.array([[0, 0], [1, 0], [0.5, 5e-324]])]),
        multipolygon_wkb([[square], [square + np.array([20, 0])]]),
        multipolygon_wkb([[square], [square + np.array([10, 0])]]),
        multipolygon_wkb([[square], [square + np.array([10, 10])]]),
        multipolygon_wkb([[square], [square * 0.5 + np.array([2, 2])]]),
        multipolygon_wkb([[square * 3, square + 10], [square * 0.2 + 11]]),
        multipolygon_wkb([[square], [square + np.array([5, 5])]]),
        struct.pack("<BII", 1, 3, 2) + ring_wkb(square) + struct.pack("<I", 0),
        struct.pack("<BII", 1, 6, 2) + polygon_wkb([square]) + struct.pack("<BII", 1, 3, 0),
    ]
    return cases


def radial_cases(seed: int = 5, count: int = 300) -> tuple[list[bytes], list[bool]]:
    """Rings of 40 to 400 vertices star-shaped around a point that is often not their vertex
    mean (radii 55-145 %, or a densely digitised side), half of them with one pair of
    neighbouring vertices swapped (a bow tie, or a fold that stays simple); per case whether
    it was left as generated (simple)."""
    rng = np.random.default_rng(seed)
    cases, intact = [], []
    for index in range(count):
        n = int(rng.integers(40, 401))
        if index % 2:
            angles = 2 * np.pi * np.arange(n) / n
        else:  # three quarters of the vertices on one quarter of the ring
            dense = 3 * n // 4
            angles = np.r_[
                np.linspace(0, np.pi / 2, dense, endpoint=False),
                np.linspace(np.pi / 2, 2 * np.pi, n - dense, endpoint=False),
            ]
        radii = 100 * rng.uniform(0.55, 1.45, n)
        centre = rng.uniform(-1e4, 1e4, 2)
        ring = centre + np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
        swapped = index % 4 >= 2
        if swapped:
            k = int(rng.integers(0, n - 1))
            ring[[k, k + 1]] = ring[[k + 1, k]]
        cases.append(polygon_wkb([ring if rng.random() < 0.5 else ring[::-1]]))
        intact.append(not swapped)
    return cases, intact


def all_cases() -> list[bytes]:
    return special_cases() + star_cases() + grid_cases() + convex_cases() + footprint_cases()[0]
