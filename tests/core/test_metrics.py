"""Per-triangle metrics on hand-checkable triangles and on a planar DEM-like surface."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from bsp_triangulate.metrics import (
    area_2d,
    area_3d,
    aspect,
    centroid,
    min_angle,
    slope,
    triangle_metrics,
    triangulation_quality,
)


def _plane_triangle(gx: float, gy: float) -> tuple[np.ndarray, np.ndarray]:
    """A right triangle on the plane z = gx * x + gy * y (gradient (gx, gy))."""
    xy = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]])
    z = gx * xy[:, 0] + gy * xy[:, 1]
    return np.column_stack([xy, z]), np.array([[0, 1, 2]])


@pytest.mark.parametrize(
    ("gx", "gy", "downslope_azimuth"),
    [(0.0, 1.0, 180.0), (0.0, -1.0, 0.0), (1.0, 0.0, 270.0), (-1.0, 0.0, 90.0), (-1, -1, 45.0)],
)
def test_aspect_points_downhill_clockwise_from_north(gx, gy, downslope_azimuth):
    vertices, triangles = _plane_triangle(gx, gy)
    assert aspect(vertices, triangles)[0] == pytest.approx(downslope_azimuth)
    # The vertex order (clockwise instead of counter-clockwise) must not change it.
    assert aspect(vertices, triangles[:, ::-1])[0] == pytest.approx(downslope_azimuth)


def test_slope_of_planes_and_flat_and_vertical_triangles():
    vertices, triangles = _plane_triangle(1.0, 0.0)
    assert slope(vertices, triangles)[0] == pytest.approx(45.0)
    vertices, triangles = _plane_triangle(np.sqrt(3.0), 0.0)
    assert slope(vertices, triangles)[0] == pytest.approx(60.0)
    flat, triangles = _plane_triangle(0.0, 0.0)
    assert slope(flat, triangles)[0] == 0.0
    assert np.isnan(aspect(flat, triangles)[0])
    wall = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert slope(wall, triangles)[0] == pytest.approx(90.0)
    assert area_2d(wall, triangles)[0] == 0.0
    assert area_3d(wall, triangles)[0] == pytest.approx(0.5)


def test_areas_angles_and_centroid_of_a_tilted_right_triangle():
    vertices, triangles = _plane_triangle(1.0, 0.0)
    assert area_2d(vertices, triangles)[0] == pytest.approx(2.0)
    assert area_3d(vertices, triangles)[0] == pytest.approx(2.0 * np.sqrt(2.0))
    # Legs: (2, 0, 2) of length 2*sqrt(2) and (0, 2, 0) of length 2 at a right angle.
    assert min_angle(vertices, triangles)[0] == pytest.approx(np.degrees(np.arctan(1 / np.sqrt(2))))
    np.testing.assert_allclose(centroid(vertices, triangles)[0], [2 / 3, 2 / 3, 2 / 3])


def test_degenerate_triangle_has_zero_angle_and_nan_slope():
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]])
    triangles = np.array([[0, 1, 2]])
    assert min_angle(vertices, triangles)[0] == 0.0
    assert np.isnan(slope(vertices, triangles)[0])
    assert triangulation_quality(vertices, triangles)["degenerate"] == 1


def test_metrics_on_a_random_mesh_agree_with_shapely_and_angle_sum():
    rng = np.random.default_rng(11)
    vertices = rng.uniform(0, 100, size=(300, 3))
    triangles = rng.choice(300, size=(500, 3), replace=True)
    triangles = triangles[(np.diff(np.sort(triangles, axis=1), axis=1) > 0).all(axis=1)]
    polygons = shapely.polygons(vertices[np.c_[triangles, triangles[:, :1]]][:, :, :2])
    np.testing.assert_allclose(area_2d(vertices, triangles), shapely.area(polygons), rtol=1e-9)
    metrics = triangle_metrics(vertices, triangles)
    assert (metrics["area_3d"] >= metrics["area_2d"] * (1 - 1e-12)).all()
    # Smallest angle from the law of cosines, corner by corner.
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    sides = [np.linalg.norm(q - p, axis=1) for p, q in ((b, c), (c, a), (a, b))]
    cosines = [
        (sides[(i + 1) % 3] ** 2 + sides[(i + 2) % 3] ** 2 - sides[i] ** 2)
        / (2 * sides[(i + 1) % 3] * sides[(i + 2) % 3])
        for i in range(3)
    ]
    expected = np.degrees(np.arccos(np.clip(np.max(cosines, axis=0), -1, 1)))
    np.testing.assert_allclose(metrics["min_angle"], expected, atol=1e-6)
    np.testing.assert_allclose(metrics["centroid"], (a + b + c) / 3)
    # Slope from areas: cos(slope) = projected area / true area.
    np.testing.assert_allclose(
        np.cos(np.radians(metrics["slope"])), metrics["area_2d"] / metrics["area_3d"], atol=1e-9
    )
    quality = triangulation_quality(vertices, triangles)
    assert quality["triangles"] == len(triangles)
    assert quality["area_2d"] == pytest.approx(metrics["area_2d"].sum())
    assert quality["slivers"] == int((metrics["min_angle"] < 5.0).sum())


def test_two_dimensional_vertices_are_flat():
    vertices = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]])
    triangles = np.array([[0, 1, 2]])
    assert area_3d(vertices, triangles)[0] == pytest.approx(6.0)
    assert slope(vertices, triangles)[0] == 0.0
