"""Fast checks of the engine's contract: tree order, orientation, errors, exactness, batches."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from bsp_triangulate import Triangulation, TriangulationError, triangulate, triangulate_many


def exact_area2(points: np.ndarray) -> Fraction:
    """Twice the signed area of a ring, exactly."""
    xs = [Fraction(float(v)) for v in points[:, 0]]
    ys = [Fraction(float(v)) for v in points[:, 1]]
    n = len(xs)
    return sum(xs[i] * ys[(i + 1) % n] - xs[(i + 1) % n] * ys[i] for i in range(n))


def triangle_areas2(result: Triangulation) -> list[Fraction]:
    return [exact_area2(result.vertices[tri]) for tri in result.triangles]


HEXAGON = [(2.0, 0.0), (4.0, 1.0), (4.0, 3.0), (2.0, 4.0), (0.0, 3.0), (0.0, 1.0)]


def test_convex_hexagon_gives_the_papers_fan_order() -> None:
    result = triangulate([HEXAGON])
    # root P0 P1 P5, then right children fanning from P1 as in the paper's example
    assert result.triangles[:, 2].tolist() == [5, 4, 3, 2]
    assert result.parent.tolist() == [-1, 0, 1, 2]
    assert result.depth.tolist() == [0, 1, 2, 3]
    assert result.side.tolist() == [0, 2, 1, 1]
    assert all(area > 0 for area in triangle_areas2(result))


def test_square_with_island_has_n_plus_2h_minus_2_triangles_covering_the_area() -> None:
    outer = [(0, 0), (10, 0), (10, 10), (0, 10)]
    island = [(3, 3), (3, 6), (6, 6), (6, 3)]
    result = triangulate([outer, island])
    assert len(result) == 8 + 2 - 2
    areas = triangle_areas2(result)
    assert all(area > 0 for area in areas)
    assert sum(areas) == 2 * (100 - 9)
    for tri, parent in zip(result.triangles[1:], result.parent[1:]):
        # the first two vertices are the base edge shared with the parent
        assert set(tri[:2].tolist()) <= set(result.triangles[parent].tolist())


def test_clockwise_outer_ring_gives_counter_clockwise_triangles_on_input_vertices() -> None:
    ring = np.array(HEXAGON[::-1])
    result = triangulate([ring])
    np.testing.assert_array_equal(result.vertices[:, :2], ring)
    assert len(result) == 4
    assert all(area > 0 for area in triangle_areas2(result))


def test_closing_point_and_repeated_points_are_dropped() -> None:
    ring = [(0, 0), (0, 0), (4, 0), (4, 4), (4, 4), (0, 4), (0, 0)]
    result = triangulate([ring])
    assert len(result.vertices) == 4
    assert len(result) == 2


def test_island_with_non_finite_coordinate_names_its_ring() -> None:
    outer = [(0, 0), (10, 0), (10, 10), (0, 10)]
    island = [(3, 3), (3, float("nan")), (6, 6)]
    with pytest.raises(TriangulationError, match=r"ring 2 \(island 1\).*not finite"):
        triangulate([outer, island])


@pytest.mark.parametrize(
    "ring",
    [[(0, 0), (1, 1), (2, 2)], [(0, 0), (1, 0)], [], [(5, 5), (5, 5), (5, 5)]],
    ids=["collinear", "two-points", "no-points", "one-point"],
)
def test_degenerate_outer_ring_gives_an_empty_result(ring: list) -> None:
    result = triangulate([ring])
    assert result.is_empty


def test_unknown_rule_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="unknown apex rule"):
        triangulate([HEXAGON], rule="nearest")


@pytest.mark.parametrize(
    ("offset", "scale"),
    [(1e15, 1.0), (0.0, 1e-9), (-1e8, 1e-6), (0.0, 1e300), (0.0, 1e-300)],
    ids=["1e15", "1e-9", "mixed", "huge", "subnormal-range"],
)
@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
def test_far_or_tiny_comb_polygon_is_tiled_exactly(offset: float, scale: float, rule: str) -> None:
    # a comb: deep notches with nearly collinear teeth tips
    teeth = 12
    ring = [(0.0, 0.0), (2.0 * teeth, 0.0)]
    for k in range(teeth, 0, -1):
        ring += [(2.0 * k, 5.0 + k * 1e-7), (2.0 * k - 1, 1.0)]
    ring.append((0.0, 5.0))
    points = np.array(ring) * scale + offset
    result = triangulate([points], rule=rule)
    assert len(result) == len(points) - 2
    areas = triangle_areas2(result)
    assert all(area > 0 for area in areas)
    assert sum(areas) == exact_area2(points)


@pytest.mark.parametrize("scale", [1.0, 1e153, 1e155, 1e300])
def test_long_star_with_overflowing_products_is_tiled_exactly(scale: float) -> None:
    # 160 vertices: the one-polygon path decides runs of ears (fans) in batches; with
    # coordinates past 1e153 the float triangle holding a batch overflowed (nan), which the
    # reach's max() passed over, and a batch of ears crossing the boundary was taken
    rng = np.random.default_rng(14)
    n = 160
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(0, 0.3 * 2 * np.pi / n, n)
    radius = np.where(np.arange(n) % 2 == 0, 1000.0, rng.uniform(300, 900, n))
    ring = np.round(np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])) * scale
    with np.errstate(all="ignore"):
        result = triangulate([ring], rule="first", invalid="fail")
    assert len(result) == n - 2
    areas = triangle_areas2(result)
    assert all(area > 0 for area in areas)
    assert sum(areas) == exact_area2(ring)


def test_vertical_wall_is_triangulated_in_its_own_plane() -> None:
    wall = [(0, 0, 0), (5, 0, 0), (5, 0, 3), (2, 0, 4), (0, 0, 3)]
    result = triangulate([wall])
    assert len(result) == 3
    np.testing.assert_array_equal(result.vertices, np.array(wall, dtype=float))


def test_elevation_rule_takes_the_apex_closest_to_the_base_mean() -> None:
    # a gently undulating surface: the XY plane stays the working plane
    heights = [10.0, 10.0, 0.0, 10.0, 0.0, 30.0]
    ring = [(100 * x, 100 * y, z) for (x, y), z in zip(HEXAGON, heights)]
    first = triangulate([ring], rule="first")
    elevation = triangulate([ring], rule="elevation")
    assert first.triangles[0, 2] == 5  # the paper's first correct candidate
    assert elevation.triangles[0, 2] == 3  # z 10 equals the base mean


def test_many_polygons_keep_their_order_and_return_errors_in_place() -> None:
    good = [HEXAGON]
    bad = [[(0, 0), (float("inf"), 0), (1, 1)]]
    results = triangulate_many([good, bad, good], on_error="return")
    assert isinstance(results[1], TriangulationError)
    assert len(results[0]) == len(results[2]) == 4
    with pytest.raises(TriangulationError, match="ring 1 \\(outer\\)"):
        triangulate_many([good, bad])
