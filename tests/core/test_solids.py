"""Building solids: closed and outward oriented (every edge twice, once each way; trimesh
agrees), volume = footprint area x height for flat roofs and floors, walls following a
per-vertex ground, courtyards and multi-part footprints, failures named per footprint."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from bsp_triangulate.formats.gltf import write_glb
from bsp_triangulate.formats.obj import write_obj
from bsp_triangulate.packed import PackedPolygons
from bsp_triangulate.solids import (
    SURFACE_FLOOR,
    SURFACE_ROOF,
    SURFACE_WALL,
    build_solids,
    is_closed,
)
from tests import model_checks
from tests.model_checks import (
    assert_valid_gltf,
    closed_and_oriented,
    signed_volume,
    trimesh_read,
)

gltf_validator = model_checks.gltf_validator  # the session fixture, used by name

X0, Y0 = 500_000.0, 6_000_000.0
SHAPES = (
    [(0, 0), (1, 0), (1, 1), (0, 1)],
    [(0, 0), (1, 0), (1, 0.45), (0.5, 0.45), (0.5, 1), (0, 1)],
    [(0.3, 0), (0.7, 0), (0.7, 0.6), (1, 0.6), (1, 1), (0, 1), (0, 0.6), (0.3, 0.6)],
    [(0, 0), (1, 0), (1, 1), (0.7, 1), (0.7, 0.4), (0.3, 0.4), (0.3, 1), (0, 1)],
)
COURTYARD = [(0.3, 0.3), (0.3, 0.7), (0.7, 0.7), (0.7, 0.3)]


def ring_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0] - ring[:, 0].mean(), ring[:, 1] - ring[:, 1].mean()
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def footprints(count: int, seed: int = 5) -> list[list[np.ndarray]]:
    """Rectangles, L, T and U shapes, rotated, 8-30 m, some rectangles with a courtyard; far
    from the CRS origin."""
    rng = np.random.default_rng(seed)
    polygons = []
    for index in range(count):
        shape = np.asarray(SHAPES[index % len(SHAPES)], dtype=float)
        size = rng.uniform(8.0, 30.0, 2)
        angle = rng.uniform(0.0, np.pi)
        rotation = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        centre = np.array([X0 + 40.0 * index, Y0 + 17.0 * (index % 7)])
        rings = [(shape - 0.5) * size @ rotation + centre]
        if len(shape) == 4 and index % 8 == 0:
            rings.append((np.asarray(COURTYARD) - 0.5) * size @ rotation + centre)
        polygons.append(rings)
    return polygons


def at_height(polygons: list[list[np.ndarray]], heights) -> PackedPolygons:
    heights = np.broadcast_to(np.asarray(heights, dtype=float), (len(polygons),))
    return PackedPolygons.of(
        [
            [np.column_stack([ring, np.full(len(ring), h)]) for ring in rings]
            for rings, h in zip(polygons, heights)
        ]
    )


def footprint_area(rings: list[np.ndarray]) -> float:
    return abs(ring_area(rings[0])) - sum(abs(ring_area(ring)) for ring in rings[1:])


@pytest.fixture(scope="module")
def flat_solids():
    polygons = footprints(40)
    heights = 3.0 + np.arange(len(polygons)) % 5 * 2.5
    ground = 100.0 + np.arange(len(polygons)) * 0.25
    solids = build_solids(at_height(polygons, ground + heights), ground)
    return polygons, heights, ground, solids


def test_every_solid_is_closed_and_outward(flat_solids) -> None:
    polygons, _heights, _ground, solids = flat_solids
    assert solids.errors == {}
    for index in range(len(polygons)):
        triangles = solids.triangles_of(index)
        assert closed_and_oriented(triangles), index
        assert is_closed(triangles)
        assert signed_volume(solids.vertices, triangles) > 0


def test_trimesh_agrees_the_solids_are_watertight(flat_solids) -> None:
    import trimesh

    polygons, _heights, _ground, solids = flat_solids
    for index in range(len(polygons)):
        mesh = trimesh.Trimesh(solids.vertices, solids.triangles_of(index), process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent, index
        assert mesh.volume > 0


def test_volume_is_footprint_area_times_height(flat_solids) -> None:
    polygons, heights, _ground, solids = flat_solids
    for index, rings in enumerate(polygons):
        volume = signed_volume(solids.vertices, solids.triangles_of(index))
        expected = footprint_area(rings) * heights[index]
        assert volume == pytest.approx(expected, rel=1e-9, abs=0), index


def test_surfaces_roof_walls_floor(flat_solids) -> None:
    polygons, heights, ground, solids = flat_solids
    for index, rings in enumerate(polygons):
        rows = slice(
            solids.triangle_start[index],
            solids.triangle_start[index] + solids.triangle_count[index],
        )
        surface = solids.surface[rows]
        roof = np.count_nonzero(surface == SURFACE_ROOF)
        # walls: two per ring edge, every ring (the courtyards too)
        assert np.count_nonzero(surface == SURFACE_WALL) == 2 * sum(len(r) for r in rings)
        assert np.count_nonzero(surface == SURFACE_FLOOR) == roof
        # sorted roof, walls, floor
        assert (np.diff(surface.astype(int)) >= 0).all()
        z = solids.vertices[solids.triangles[rows]][..., 2]
        np.testing.assert_array_equal(z[surface == SURFACE_ROOF], ground[index] + heights[index])
        np.testing.assert_array_equal(z[surface == SURFACE_FLOOR], ground[index])
        assert (solids.depth[rows][surface == SURFACE_WALL] == -1).all()
        assert (solids.depth[rows][surface != SURFACE_WALL] >= 0).all()


def test_courtyard_walls_face_into_the_courtyard() -> None:
    square = np.array([(0, 0), (10, 0), (10, 10), (0, 10)], dtype=float)
    court = np.array([(3, 3), (3, 7), (7, 7), (7, 3)], dtype=float)
    solids = build_solids(at_height([[square, court]], 5.0), 0.0)
    rows = solids.triangles_of(0)[solids.surface == SURFACE_WALL]
    corners = solids.vertices[rows]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    centre = corners.mean(axis=1)
    inner = (np.abs(centre[:, 0] - 5) < 2.5) & (np.abs(centre[:, 1] - 5) < 2.5)
    towards_middle = np.einsum("ij,ij->i", normal[:, :2], np.array([5, 5]) - centre[:, :2])
    assert inner.sum() == 8 and (towards_middle[inner] > 0).all()
    assert (towards_middle[~inner] < 0).all()
    assert signed_volume(solids.vertices, solids.triangles_of(0)) == pytest.approx(
        (100 - 16) * 5, rel=1e-12
    )


def test_ground_per_vertex_makes_walls_follow_the_slope() -> None:
    polygons = footprints(12, seed=9)
    packed = at_height(polygons, 150.0)
    # a tilted plane: z = 0.01 x + 0.02 y - const, well below the roof
    ground_points = 0.01 * (packed.points[:, 0] - X0) + 0.02 * (packed.points[:, 1] - Y0) + 90.0
    solids = build_solids(packed, ground_points=ground_points)
    assert solids.errors == {}
    for index in range(len(polygons)):
        triangles = solids.triangles_of(index)
        assert closed_and_oriented(triangles)
        floor = solids.vertices[triangles[solids.surface[solids.solid == index] == SURFACE_FLOOR]]
        expected = 0.01 * (floor[..., 0] - X0) + 0.02 * (floor[..., 1] - Y0) + 90.0
        np.testing.assert_allclose(floor[..., 2], expected, rtol=0, atol=1e-9)
        # a flat roof over a planar floor: volume = area x (roof z - ground z at the centroid)
        shape = shapely.Polygon(polygons[index][0], polygons[index][1:])
        centre = shape.centroid
        height = 150.0 - (0.01 * (centre.x - X0) + 0.02 * (centre.y - Y0) + 90.0)
        volume = signed_volume(solids.vertices, triangles)
        assert volume == pytest.approx(shape.area * height, rel=1e-9)


def test_collinear_and_repeated_points_still_close_the_solid() -> None:
    ring = np.array([(0, 0), (5, 0), (10, 0), (10, 0), (10, 10), (0, 10), (0, 5)], dtype=float)
    solids = build_solids(at_height([[ring]], 4.0), 1.0)
    assert closed_and_oriented(solids.triangles_of(0))
    assert signed_volume(solids.vertices, solids.triangles_of(0)) == pytest.approx(300.0)


def test_failures_are_named_per_footprint_and_others_kept() -> None:
    square = np.array([(0, 0), (10, 0), (10, 10), (0, 10)], dtype=float)
    bow_tie = np.array([(20, 0), (30, 10), (30, 0), (20, 10)], dtype=float)
    line = np.array([(40, 0), (41, 1), (42, 2)], dtype=float)
    packed = at_height([[square], [bow_tie], [line], [square + 50]], [5.0, 5.0, 5.0, 0.5])
    solids = build_solids(packed, ground=np.array([0.0, 0.0, 0.0, 1.0]))
    assert sorted(solids.errors) == [1, 3]
    assert "above the ground" in solids.errors[3]
    assert solids.triangle_count.tolist()[1:] == [0, 0, 0]
    assert closed_and_oriented(solids.triangles_of(0))
    assert solids.triangles.max() < len(solids.vertices)


def test_missing_ground_fails_the_footprint() -> None:
    square = np.array([(0, 0), (10, 0), (10, 10), (0, 10)], dtype=float)
    packed = at_height([[square], [square + 20]], 5.0)
    ground_points = np.zeros(len(packed.points))
    ground_points[4] = np.nan
    solids = build_solids(packed, ground_points=ground_points)
    assert list(solids.errors) == [1] and "ground" in solids.errors[1]


def test_sloped_roof_snapped_by_planar_tolerance_stays_closed() -> None:
    ring = np.array([(0, 0, 10), (10, 0, 10), (10, 10, 15.0004), (0, 10, 15)], dtype=float)
    solids = build_solids(PackedPolygons.of([[ring]]), 0.0, planar_tolerance=0.01)
    triangles = solids.triangles_of(0)
    assert closed_and_oriented(triangles)
    assert signed_volume(solids.vertices, triangles) == pytest.approx(1250.0, rel=1e-4)


def test_solids_as_glb_and_obj_pass_the_validator_and_read_back(
    tmp_path, flat_solids, gltf_validator
) -> None:
    _polygons, _heights, _ground, solids = flat_solids
    values = {"building_id": solids.solid, "surface": solids.surface}
    glb = write_glb(tmp_path / "b.glb", solids.vertices, solids.triangles, values)[0]
    assert_valid_gltf(gltf_validator, glb)
    read = trimesh_read(glb)
    assert len(read.faces) == len(solids.triangles)
    obj = write_obj(tmp_path / "b.obj", solids.vertices, solids.triangles, values)[0]
    read = trimesh_read(obj)
    assert (len(read.vertices), len(read.faces)) == (len(solids.vertices), len(solids.triangles))
    assert math.isclose(read.volume, sum(
        signed_volume(solids.vertices, solids.triangles_of(i)) for i in range(len(solids))
    ), rel_tol=1e-6)  # fmt: skip
