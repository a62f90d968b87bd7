"""The working plane and the area guard: draped footprints stay in XY, and a triangulation
whose triangles do not cover the polygon exactly is never returned."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate import (
    PackedPolygons,
    Triangulation,
    TriangulationError,
    triangulate,
    triangulate_many,
    triangulate_packed,
)
from bsp_triangulate.geometry.rings import normalise_rings, prepare
from bsp_triangulate.tree import batch, one_polygon

# a concave footprint near Swellendam in degrees, z from a DEM in metres: a few metres of
# relief over 1e-4 degrees make its Newell normal nearly horizontal
DEGREES = [
    (20.43000, -34.03000, 99.0),
    (20.43012, -34.03000, 101.0),
    (20.43012, -34.02990, 103.5),
    (20.43006, -34.02995, 100.0),
    (20.43000, -34.02990, 102.0),
]


def xy_area2(points: list[tuple[float, float, float]]) -> float:
    xy = np.array(points)[:, :2]
    x, y = xy[:, 0] - xy[0, 0], xy[:, 1] - xy[0, 1]
    return float(abs(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def triangle_area2_sum(result: Triangulation) -> float:
    v = result.vertices
    a, b, c = (v[result.triangles[:, k]] for k in range(3))
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    return float(np.abs(cross).sum())


def test_degree_footprint_with_metre_z_is_a_wall_in_auto_and_draped_in_xy() -> None:
    _, axes = normalise_rings([DEGREES])
    assert axes != (0, 1)  # x, y, z taken as one unit: a near-vertical face
    result = triangulate([DEGREES], plane="xy")
    assert len(result) == 3
    assert triangle_area2_sum(result) == pytest.approx(xy_area2(DEGREES), rel=1e-12)
    np.testing.assert_array_equal(result.vertices, np.array(DEGREES))


@pytest.mark.parametrize("call", ["many", "packed"])
def test_many_draped_footprints_in_xy_give_the_single_polygon_results(call: str) -> None:
    rng = np.random.default_rng(5)
    polygons = []
    for k in range(300):
        shift = np.array([1e-3 * (k % 20), 1e-3 * (k // 20), 0.0])
        z = rng.uniform(95, 105, size=(len(DEGREES), 1))
        polygons.append([np.array(DEGREES)[:, :2] + shift[:2]])
        polygons[-1] = [np.column_stack([polygons[-1][0], z])]
    if call == "many":
        results = triangulate_many(polygons, plane="xy")
    else:
        results = triangulate_packed(PackedPolygons.of(polygons), plane="xy").to_list()
    for rings, result in zip(polygons, results):
        single = triangulate(rings, plane="xy")
        np.testing.assert_array_equal(result.triangles, single.triangles)
        assert triangle_area2_sum(result) == pytest.approx(xy_area2(list(rings[0])), rel=1e-12)


def test_unknown_plane_is_refused() -> None:
    with pytest.raises(ValueError, match="plane"):
        triangulate([DEGREES], plane="yz")
    with pytest.raises(ValueError, match="plane"):
        triangulate_many([[DEGREES]], plane="")


def test_area_guard_rejects_overlapping_triangles() -> None:
    square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
    clean, axes = normalise_rings([square])
    prepared = prepare(clean, axes)
    good = triangulate([square])
    one_polygon.check_area(prepared, good, axes)
    # two triangles over the same half: the signed areas still add up to 16, the absolute ones
    # to 24
    bad = Triangulation(
        vertices=good.vertices,
        triangles=np.array([[0, 1, 2], [0, 2, 3], [2, 0, 1]]),
        parent=np.array([-1, 0, 0]),
        depth=np.array([0, 1, 1]),
        side=np.array([0, 1, 2], dtype=np.int8),
    )
    with pytest.raises(TriangulationError, match=r"areas add up to 1\.5 times"):
        one_polygon.check_area(prepared, bad, axes)


def test_area_guard_holds_on_far_tiny_and_huge_coordinates() -> None:
    for offset, scale in ((1e7, 1.0), (0.0, 1e-200), (0.0, 1e300)):
        ring = np.array([(0, 0), (3, 0), (3, 1e-9), (1, 2), (0, 2)], dtype=float) * scale + offset
        assert len(triangulate([ring])) == 3


def test_batch_tree_that_does_not_cover_its_polygon_is_left_to_the_engine(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
    polygons = [[[(x + 10 * k, y) for x, y in square]] for k in range(50)]
    build = batch.build_trees

    def first_triangle_collapsed(*args, **kwargs):
        trees = build(*args, **kwargs)
        first = trees.start[0]
        trees.triangles[first, 2] = trees.triangles[first, 0]  # half the square uncovered
        return trees

    monkeypatch.setattr(batch, "build_trees", first_triangle_collapsed)
    results = batch.triangulate_batch(polygons)
    assert results[0] is None  # the engine decides it
    assert all(result is not None for result in results[1:])
    # through the public call the engine's own triangles come back, and they are right
    listed = triangulate_many(polygons)
    assert triangle_area2_sum(listed[0]) == pytest.approx(32.0)


@pytest.mark.parametrize("tilt", [0.05, -0.05])
@pytest.mark.parametrize("order", [1, -1], ids=["as drawn", "reversed"])
def test_valid_steep_face_as_given_gives_the_triangles_of_the_strict_mode(
    tilt: float, order: int
) -> None:
    """A concave face tilted about 87 degrees is worked in its dominant plane. As given, a
    valid one gets the strict mode's tree: each triangle counter-clockwise in that plane,
    whatever its turn in XY (none is a fallback, so none is turned or counted as lost)."""
    outline = np.array([[0, 0], [10, 0], [10, 6], [6, 6], [6, 3], [4, 3], [4, 6], [0, 6]], float)
    ring = np.column_stack([outline[:, 0], tilt * outline[:, 1], outline[:, 1]])[::order]
    strict = triangulate([ring], invalid="fail")
    given = triangulate([ring], invalid="as_given")
    for field in ("triangles", "parent", "depth", "side"):
        assert np.array_equal(getattr(strict, field), getattr(given, field)), field
