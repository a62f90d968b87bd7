"""Random simple polygons with islands for the oracle and property tests.

Every builder takes a ``random.Random`` and returns rings as lists of tuples, or None when the
attempt did not give a valid polygon (shapely decides validity; callers draw again). Integer
coordinates on small grids give collinear runs on purpose.
"""

from __future__ import annotations

import math
import random

import shapely
from shapely.geometry import LinearRing, Polygon

Rings = list[list[tuple]]


def star_ring(
    rnd: random.Random,
    n: int,
    center: tuple[float, float] = (0.0, 0.0),
    radius: float = 50.0,
    integer: bool = True,
) -> list[tuple[float, float]]:
    """A star-shaped ring around ``center``: sorted random angles, random radii."""
    angles = sorted(rnd.uniform(0.0, 2.0 * math.pi) for _ in range(n))
    ring = []
    for angle in angles:
        r = rnd.uniform(0.25, 1.0) * radius
        x, y = center[0] + r * math.cos(angle), center[1] + r * math.sin(angle)
        ring.append((float(round(x)), float(round(y))) if integer else (x, y))
    return ring


def grid_ring(rnd: random.Random, cells: int, size: int = 8) -> list[tuple[float, float]] | None:
    """Boundary of a random polyomino with every unit grid point on it (long collinear runs)."""
    x, y = size // 2, size // 2
    squares = {(x, y)}
    while len(squares) < cells:
        dx, dy = rnd.choice(((1, 0), (-1, 0), (0, 1), (0, -1)))
        x, y = min(max(x + dx, 0), size - 1), min(max(y + dy, 0), size - 1)
        squares.add((x, y))
    union = shapely.union_all([shapely.box(i, j, i + 1, j + 1) for i, j in squares])
    if union.geom_type != "Polygon" or len(union.interiors) > 0:
        return None
    dense = shapely.segmentize(union.exterior, 1.0)
    ring = [(float(px), float(py)) for px, py in dense.coords[:-1]]
    return _without_repeats(ring)


def _without_repeats(ring: list) -> list:
    out: list = []
    for p in ring:
        if not out or out[-1] != p:
            out.append(p)
    return out


def rotate_start(rnd: random.Random, ring: list) -> list:
    """The same ring starting at a random vertex."""
    k = rnd.randrange(len(ring))
    return ring[k:] + ring[:k]


def is_valid(rings: Rings) -> bool:
    """Valid OGC polygon (shapely) with distinct vertices in each ring."""
    if any(len({p[:2] for p in r}) != len(r) for r in rings):
        return False
    try:
        return Polygon(rings[0], rings[1:]).is_valid
    except (ValueError, shapely.errors.GEOSException):
        return False


def rings_are_disjoint(rings: Rings) -> bool:
    """No two rings share a point (islands strictly inside, apart from each other)."""
    lines = [LinearRing(r) for r in rings]
    return all(
        lines[i].disjoint(lines[j]) for i in range(len(lines)) for j in range(i + 1, len(lines))
    )


def add_islands(
    rnd: random.Random, outer: list, count: int, size: float, integer: bool = True
) -> Rings | None:
    """``outer`` with ``count`` small star islands strictly inside it and apart from each other."""
    shell = Polygon(outer)
    minx, miny, maxx, maxy = shell.bounds
    islands: list = []
    for _ in range(40 * count):
        if len(islands) == count:
            break
        center = (rnd.uniform(minx, maxx), rnd.uniform(miny, maxy))
        island = star_ring(rnd, rnd.randint(3, 6), center, size, integer)
        candidate = [outer, *islands, island]
        if is_valid(candidate) and rings_are_disjoint(candidate):
            islands.append(island)
    if len(islands) < count:
        return None
    return [outer, *islands]


def touching_island(rnd: random.Random, rings: Rings, target: int) -> list | None:
    """A small triangle island with one corner on a vertex of ring ``target``, or None."""
    for _ in range(40):
        p = rnd.choice(rings[target])
        a = (p[0] + rnd.randint(-4, 4), p[1] + rnd.randint(-4, 4))
        b = (p[0] + rnd.randint(-4, 4), p[1] + rnd.randint(-4, 4))
        island = [p, a, b]
        candidate = [*rings, island]
        if is_valid(candidate) and not LinearRing(island).disjoint(LinearRing(rings[target])):
            return island
    return None


def with_random_orientation(rnd: random.Random, rings: Rings) -> Rings:
    """Each ring reversed or not at random, and started at a random vertex."""
    out = []
    for ring in rings:
        r = ring[::-1] if rnd.random() < 0.4 else list(ring)
        out.append(rotate_start(rnd, r))
    return out


def with_z(rnd: random.Random, rings: Rings, low: int = 0, high: int = 9) -> Rings:
    """Integer z values, kept small so that the XY plane stays the working plane."""
    return [[(p[0], p[1], float(rnd.randint(low, high))) for p in ring] for ring in rings]


def random_polygon(
    rnd: random.Random,
    islands: int = 0,
    integer: bool = True,
    grid: bool = False,
    touching: int = 0,
) -> Rings:
    """A valid random polygon; ``islands`` apart from everything, ``touching`` more islands
    each touching the outer ring or an earlier island at a vertex."""
    while True:
        if grid:
            outer = grid_ring(rnd, rnd.randint(3, 14))
            size = 0.3
        else:
            outer = star_ring(
                rnd, rnd.randint(3, 16), radius=rnd.choice((10, 25, 60)), integer=integer
            )
            size = 6.0
        if outer is None or not is_valid([outer]):
            continue
        rings = add_islands(rnd, outer, islands, size, integer=integer and not grid)
        for _ in range(touching if rings is not None else 0):
            island = touching_island(rnd, rings, rnd.randrange(len(rings)))
            if island is not None:
                rings.append(island)
        if rings is not None:
            return with_random_orientation(rnd, rings)
