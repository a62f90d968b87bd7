"""``triangulate_packed`` against ``triangulate_many``: the same results, packed.

Every polygon's vertices, triangles, parent, depth and side (dtypes included) and every error
(same polygons, same messages) must be those of the list API, whichever path produced them:
the batch path, the mid-size groups (whose pieces come back out of polygon order) or the
engine (large polygons, touching rings, invalid rings, empty rings).
"""

from __future__ import annotations

import json
import random

import numpy as np
import pytest

from bsp_triangulate import (
    PackedPolygons,
    TriangulationError,
    triangulate_many,
    triangulate_packed,
)
from bsp_triangulate.tree.batch import MID_MIN_COUNT

from ..conftest import SHARED_DATA
from .random_polygons import random_polygon, with_z
from .tree.test_batch import farm_polygons, first_differing_field, mid_size_polygons

EARCUT = SHARED_DATA / "earcut" / "fixtures"


def as_arrays(polygons: list) -> list:
    return [[np.asarray(ring, dtype=np.float64) for ring in rings] for rings in polygons]


def differences(polygons: list, packed=None, **options) -> list[str]:
    """Where the packed results (``packed``, else computed here) differ from the list API's."""
    expected = triangulate_many(polygons, on_error="return", **options)
    if packed is None:
        packed = triangulate_packed(PackedPolygons.of(polygons), on_error="return", **options)
    assert len(packed) == len(polygons)
    problems = []
    for number, (want, got) in enumerate(zip(expected, packed.to_list())):
        if isinstance(want, TriangulationError) or isinstance(got, TriangulationError):
            if type(want) is not type(got) or str(want) != str(got):
                problems.append(f"polygon {number}: {want!r} against {got!r}")
            continue
        differing = first_differing_field(got, want)
        if differing is not None:
            problems.append(f"polygon {number}: {differing} differs")
    return problems


def test_packed_equals_list_on_earcut_fixtures() -> None:
    polygons = as_arrays(json.loads(path.read_text()) for path in sorted(EARCUT.glob("*.json")))
    assert len(polygons) == 59
    packed = triangulate_packed(PackedPolygons.of(polygons), on_error="return")
    # the fixtures include self-intersecting rings on purpose: some fail, most do not
    assert 0 < len(packed.errors) < 20
    assert differences(polygons, packed) == []


def test_packed_equals_list_on_farms_and_random_polygons_with_z() -> None:
    rnd = random.Random(8)
    polygons = farm_polygons(150)
    polygons += [with_z(rnd, random_polygon(rnd, islands=rnd.randint(0, 2))) for _ in range(80)]
    assert differences(polygons) == []
    assert differences(polygons, rule="elevation") == []


def test_mid_size_groups_come_back_in_polygon_order() -> None:
    rnd = random.Random(21)
    small = [random_polygon(rnd, islands=1) for _ in range(30)]
    mid = mid_size_polygons(rnd, MID_MIN_COUNT + 2, integer=False)
    # interleaved, so that the mid-size group's pieces fall between the small ones
    polygons = [p for pair in zip(small, mid) for p in pair] + small[len(mid) :]
    assert differences(polygons) == []


def test_empty_rings_no_rings_and_invalid_rings_go_to_the_engine() -> None:
    rnd = random.Random(3)
    plain = [random_polygon(rnd, islands=0) for _ in range(6)]
    bowtie = [[(0.0, 0.0), (4.0, 4.0), (4.0, 0.0), (0.0, 4.0)]]
    with_empty_island = [plain[0][0], np.zeros((0, 2))]
    island_case = [np.asarray(r, float).reshape(-1, 2) for r in with_empty_island]
    polygons = [*as_arrays([*plain[:3], bowtie, [], *plain[3:]]), island_case]
    assert differences(polygons) == []
    packed = triangulate_packed(PackedPolygons.of(polygons), on_error="return")
    assert sorted(packed.errors) == [3]
    assert packed.vertex_count[3] == 0 and packed.triangle_count[3] == 0
    with pytest.raises(TriangulationError):
        triangulate_packed(PackedPolygons.of(polygons))


def test_two_and_four_columns_read_as_xy_and_xyz() -> None:
    rnd = random.Random(4)
    polygons = [with_z(rnd, random_polygon(rnd, islands=1)) for _ in range(40)]
    xyz = PackedPolygons.of(polygons)
    xy = PackedPolygons(xyz.points[:, :2], xyz.ring_len, xyz.ring_count)
    xyzm = PackedPolygons(np.c_[xyz.points, np.ones(len(xyz.points))], xyz.ring_len, xyz.ring_count)
    flat = triangulate_packed(xy)
    assert (flat.vertices[:, 2] == 0).all() and len(flat.triangles) > 0
    with_m = triangulate_packed(xyzm)
    plain = triangulate_packed(xyz)
    assert np.array_equal(with_m.vertices, plain.vertices)
    assert np.array_equal(with_m.triangles, plain.triangles)


def test_rings_are_views_of_the_points_and_lengths_are_checked() -> None:
    polygons = as_arrays(
        [[[(0, 0), (2, 0), (0, 2)]], [[(5, 5), (9, 5), (5, 9)], [(6, 6), (7, 6), (6, 7)]]]
    )
    packed = PackedPolygons.of(polygons)
    second = packed.rings(1)
    assert [len(r) for r in second] == [3, 3]
    assert np.shares_memory(second[1], packed.points)
    assert np.array_equal(second[1][:, :2], polygons[1][1])
    with pytest.raises(ValueError):
        PackedPolygons(packed.points, packed.ring_len[:-1], packed.ring_count)
    with pytest.raises(ValueError):
        PackedPolygons(packed.points, packed.ring_len, np.array([1, 1]))
    with pytest.raises(ValueError):
        PackedPolygons(packed.points[:, :1], packed.ring_len, packed.ring_count)


def test_proven_flags_must_match_the_polygons() -> None:
    packed = PackedPolygons.of(as_arrays([[[(0, 0), (2, 0), (0, 2)]]] * 3))
    with pytest.raises(ValueError):
        triangulate_packed(packed, proven=[True, False])
    assert len(triangulate_packed(packed, proven=[True] * 3).triangles) == 3
