"""Property tests: random valid polygons with islands always triangulate exactly.

Polygons are star-shaped or polyomino outlines on an integer grid (collinear runs), with extra
collinear midpoints, islands apart from everything, islands touching the outer ring or another
island at a vertex, duplicated consecutive points and closing points, and exact transforms to
coordinates near 1e15 or of size about 1e-9. Every result must pass checks.py: input vertices
only, counter-clockwise, exact tiling (no overlap, no gap), 2V - B - 2 + 2h triangles, zero
deviation, a consistent pre-order BSP tree.

The default run is deterministic and short; ``HYPOTHESIS_PROFILE=fuzz`` runs many more random
examples.
"""

from __future__ import annotations

import os
import random

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bsp_triangulate import (
    PackedPolygons,
    TriangulationError,
    triangulate,
    triangulate_many,
    triangulate_packed,
)

from .checks import check_triangulation
from .random_polygons import (
    grid_ring,
    is_valid,
    rings_are_disjoint,
    rotate_start,
    star_ring,
    touching_island,
)
from .reference_bsp import xy_is_working_plane

settings.register_profile(
    "fuzz",
    max_examples=3000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
FUZZ = os.environ.get("HYPOTHESIS_PROFILE") == "fuzz"
if FUZZ:
    settings.load_profile("fuzz")


def examples(count: int) -> settings:
    """``count`` deterministic examples, or the fuzz profile's many random ones."""
    if FUZZ:
        return settings(settings.get_profile("fuzz"))
    return settings(
        max_examples=count,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )


# --- building blocks -----------------------------------------------------------------------------


def _outer(rnd: random.Random, kind: str) -> list[tuple[float, float]]:
    while True:
        if kind == "polyomino":
            ring = grid_ring(rnd, rnd.randint(3, 12))
            ring = None if ring is None else [(4 * x, 4 * y) for x, y in ring]
        else:
            ring = star_ring(rnd, rnd.randint(3, 14), radius=rnd.choice((12, 30, 60)))
        if ring is not None and is_valid([ring]):
            return ring


def _free_island(rnd: random.Random, rings: list) -> list | None:
    """A small island touching nothing."""
    minx = min(p[0] for p in rings[0])
    maxx = max(p[0] for p in rings[0])
    miny = min(p[1] for p in rings[0])
    maxy = max(p[1] for p in rings[0])
    for _ in range(30):
        center = (rnd.uniform(minx, maxx), rnd.uniform(miny, maxy))
        island = star_ring(rnd, rnd.randint(3, 6), center, radius=rnd.choice((2, 4, 7)))
        candidate = [*rings, island]
        if is_valid(candidate) and rings_are_disjoint(candidate):
            return island
    return None


def _with_midpoints(rnd: random.Random, ring: list) -> list:
    """Doubled coordinates with the exact midpoint of some edges inserted (collinear runs)."""
    doubled = [(2 * p[0], 2 * p[1]) for p in ring]
    out = []
    for i, p in enumerate(doubled):
        out.append(p)
        if rnd.random() < 0.3:
            q = doubled[(i + 1) % len(doubled)]
            out.append(((p[0] + q[0]) / 2, (p[1] + q[1]) / 2))
    return out


def _with_duplicates(rnd: random.Random, ring: list) -> list:
    out = []
    for p in ring:
        out.append(p)
        if rnd.random() < 0.15:
            out.append(p)
    if rnd.random() < 0.5:
        out.append(out[0])
    return out


@st.composite
def polygons(draw: st.DrawFn, elevation: bool = False) -> list:
    """Rings of a valid polygon (outer ring first) with the features described above."""
    rnd = random.Random(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(("star", "polyomino")))
    free = draw(st.integers(0, 3))
    touch_outer = draw(st.booleans())
    touch_island = draw(st.booleans())
    midpoints = draw(st.booleans())
    duplicates = draw(st.booleans())
    place = draw(st.sampled_from(("plain", "offset-1e15", "size-1e-9")))

    rings = [_outer(rnd, kind)]
    for _ in range(free):
        island = _free_island(rnd, rings)
        if island is not None:
            rings.append(island)
    if touch_outer:
        island = touching_island(rnd, rings, 0)
        if island is not None:
            rings.append(island)
    if touch_island and len(rings) > 1:
        island = touching_island(rnd, rings, rnd.randrange(1, len(rings)))
        if island is not None:
            rings.append(island)
    if midpoints:
        rings = [_with_midpoints(rnd, r) for r in rings]
    assert is_valid(rings)
    rings = [rotate_start(rnd, r[::-1] if rnd.random() < 0.4 else r) for r in rings]
    if duplicates:
        rings = [_with_duplicates(rnd, r) for r in rings]
    if place == "offset-1e15":  # exact: integers below 2**53
        rings = [[(x + 1e15, y + 1e15) for x, y in r] for r in rings]
    elif place == "size-1e-9":  # exact: a power of two
        rings = [[(x * 2.0**-30, y * 2.0**-30) for x, y in r] for r in rings]
    if elevation:  # z scaled with the polygon so that XY stays the working plane
        unit = 2.0**-30 if place == "size-1e-9" else 1.0
        rings = [[(x, y, rnd.randint(0, 3) * unit) for x, y in r] for r in rings]
    return rings


# --- properties ----------------------------------------------------------------------------------


@examples(80)
@given(polygons())
def test_random_polygon_with_islands_is_tiled_exactly(rings: list) -> None:
    result = triangulate(rings)
    check_triangulation(rings, result)


@examples(30)
@given(polygons(elevation=True))
def test_random_polygon_with_z_is_tiled_exactly_with_rule_elevation(rings: list) -> None:
    if not all(xy_is_working_plane(r) for r in rings if len(r) >= 3):
        rings = [[(p[0], p[1], 0.0) for p in r] for r in rings]
    result = triangulate(rings, rule="elevation")
    check_triangulation(rings, result)


@examples(15)
@given(st.lists(polygons(), min_size=1, max_size=3))
def test_triangulate_many_matches_one_by_one_and_returns_errors_in_place(polys: list) -> None:
    outside = [[(0, 0), (10, 0), (10, 10), (0, 10)], [(20, 20), (22, 20), (21, 22)]]
    batch = [*polys, outside]
    results = triangulate_many(batch, on_error="return")
    assert len(results) == len(batch)
    assert isinstance(results[-1], TriangulationError)
    for rings, result in zip(polys, results):
        try:
            single = triangulate(rings)
        except TriangulationError:
            assert isinstance(result, TriangulationError)
            continue
        np.testing.assert_array_equal(result.vertices, single.vertices)
        np.testing.assert_array_equal(result.triangles, single.triangles)
        np.testing.assert_array_equal(result.parent, single.parent)


@st.composite
def points_for(draw: st.DrawFn, rings: list) -> np.ndarray:
    """Points for a polygon: on a grid over its box (inside, outside, on its edges), at its
    vertices and edges' midpoints, some repeated."""
    rnd = random.Random(draw(st.integers(0, 2**32 - 1)))
    xy = np.array([p[:2] for ring in rings for p in ring], dtype=np.float64)
    low, high = xy.min(axis=0), xy.max(axis=0)
    steps = rnd.choice((4, 9, 17))
    grid = [
        (low[0] + (high[0] - low[0]) * i / steps, low[1] + (high[1] - low[1]) * j / steps)
        for i in range(steps + 1)
        for j in range(steps + 1)
    ]
    chosen = rnd.sample(grid, min(len(grid), rnd.randint(1, 40)))
    ring = [tuple(p[:2]) for p in rings[rnd.randrange(len(rings))]]
    chosen += rnd.sample(ring, min(2, len(ring)))
    a, b = ring[0], ring[1]
    chosen.append(((a[0] + b[0]) / 2, (a[1] + b[1]) / 2))
    chosen += rnd.sample(chosen, min(3, len(chosen)))
    rnd.shuffle(chosen)
    return np.array([(x, y, rnd.randint(0, 3)) for x, y in chosen], dtype=np.float64)


@st.composite
def polygons_with_points(draw: st.DrawFn) -> tuple[list, list]:
    polys = draw(st.lists(polygons(), min_size=1, max_size=4))
    return polys, [draw(points_for(rings)) for rings in polys]


@examples(15)
@given(polygons_with_points())
def test_many_with_points_match_one_by_one_under_rule_delaunay(drawn: tuple) -> None:
    # triangulate_many and triangulate_packed insert the points of all polygons at once
    # (tree/points_batch.py); one polygon at a time inserts them one by one
    polys, points = drawn
    many = triangulate_many(polys, points=points, rule="delaunay", on_error="return")
    counts = np.array([len(p) for p in points], dtype=np.int64)
    packed = triangulate_packed(
        PackedPolygons.of(polys), points=(np.concatenate(points), counts), rule="delaunay"
    ).to_list()
    for rings, pts, got, got_packed in zip(polys, points, many, packed):
        single = triangulate(rings, points=pts, rule="delaunay")
        for result in (got, got_packed):
            for name in ("vertices", "triangles", "parent", "depth", "side", "point_ids"):
                np.testing.assert_array_equal(getattr(result, name), getattr(single, name))
