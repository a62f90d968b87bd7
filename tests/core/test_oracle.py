"""The engine against the reference implementation of docs/algorithm.md, triangle by triangle.

Each test id names the polygon family and the seed that builds it: star-shaped polygons on an
integer grid (collinear runs), polyomino outlines with every grid point (long collinear runs),
float star polygons, polygons with 1-3 islands apart from everything, polygons with islands
touching the outer ring or each other at a vertex, and polygons with z values triangulated with
rule "elevation". Rings are started at random vertices and reversed
at random, so clockwise outer rings (mirrored working plane) are covered too.
"""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate import triangulate

from .checks import (
    check_tiling,
    check_tree,
    check_triangulation,
    deviation,
    overlapping_pairs,
    polygon_counts,
)
from .random_polygons import random_polygon, with_z
from .reference_bsp import reference_triangulate, xy_is_working_plane
from .test_earcut_fixtures import FIXTURES, is_valid_polygon, load
from .test_geos_cases import CASES as GEOS_CASES
from .test_geos_cases import case_id, polygon_parts, read

FAMILIES = {
    "integer-star": (100, {"integer": True}),
    "polyomino": (40, {"grid": True}),
    "float-star": (30, {"integer": False}),
    "islands": (70, {"islands": None}),
    "touching": (60, {"islands": None, "touching": 2}),
}


def _build(family: str, seed: int) -> list:
    rnd = random.Random(f"{family}-{seed}")
    options = dict(FAMILIES[family][1]) if family in FAMILIES else {}
    if "islands" in options:
        options["islands"] = rnd.randint(0 if "touching" in options else 1, 3)
    if family == "elevation":
        rings = random_polygon(rnd, islands=rnd.randint(0, 2))
        for high in (9, 9, 9, 3, 1, 0):  # keep XY the working plane of every ring
            with_elevation = with_z(rnd, rings, high=high)
            if all(xy_is_working_plane(ring) for ring in with_elevation):
                return with_elevation
    return random_polygon(rnd, **options)


def _assert_same(rings: list, rule: str) -> None:
    expected = reference_triangulate(rings, rule=rule)
    check_triangulation(rings, expected)  # the reference itself tiles the polygon
    result = triangulate(rings, rule=rule)
    check_triangulation(rings, result)
    assert len(result.triangles) == len(expected.triangles)
    np.testing.assert_array_equal(result.vertices, np.asarray(expected.vertices, dtype=float))
    got = np.asarray(result.vertices)[np.asarray(result.triangles)]
    want = np.asarray(expected.vertices, dtype=float)[np.asarray(expected.triangles)]
    mismatch = [i for i in range(len(got)) if not np.array_equal(got[i], want[i])]
    assert not mismatch, (
        f"first differing triangle #{mismatch[0]}: engine {got[mismatch[0]][:, :2].tolist()} "
        f"reference {want[mismatch[0]][:, :2].tolist()}"
    )
    np.testing.assert_array_equal(result.parent, expected.parent)
    np.testing.assert_array_equal(result.depth, expected.depth)
    np.testing.assert_array_equal(result.side, expected.side)


CASES = [(family, seed) for family, (count, _) in FAMILIES.items() for seed in range(count)]


@pytest.mark.parametrize(("family", "seed"), CASES, ids=[f"{f}-{s}" for f, s in CASES])
def test_engine_matches_reference_with_rule_first(family: str, seed: int) -> None:
    _assert_same(_build(family, seed), "first")


@pytest.mark.parametrize("seed", range(60), ids=[f"z-{s}" for s in range(60)])
def test_engine_matches_reference_with_rule_elevation(seed: int) -> None:
    _assert_same(_build("elevation", seed), "elevation")


def _small_valid_inputs() -> list:
    """Valid earcut fixtures and GEOS polygon parts small enough for the O(n^3) reference."""
    inputs = []
    for name in FIXTURES:
        rings = load(name)
        if sum(len(r) for r in rings) <= 220 and is_valid_polygon(rings):
            inputs.append(pytest.param(rings, id=f"earcut-{name}"))
    for case in GEOS_CASES:
        if case["input_wkt"].upper().startswith(("LINESTRING", "CURVEPOLYGON")):
            continue
        for number, rings in enumerate(polygon_parts(read(case["input_wkt"]))):
            if is_valid_polygon(rings):
                inputs.append(pytest.param(rings, id=f"geos-{case_id(case)}-{number}"))
    return inputs


@pytest.mark.parametrize("rings", _small_valid_inputs())
def test_engine_matches_reference_on_real_test_polygons(rings: list) -> None:
    _assert_same(rings, "first")


def test_reference_reproduces_a_hand_checked_square_with_an_island() -> None:
    """The oracle itself on a case worked out by hand from docs/algorithm.md."""
    outer = [(0, 0), (10, 0), (10, 10), (0, 10)]
    island = [(4, 4), (6, 4), (6, 6), (4, 6)]
    # Island reversed to clockwise from (4, 4): 4,4 -> 4,6 -> 6,6 -> 6,4. Its nearest valid
    # bridge from (4, 4) goes to (0, 0) (k = 0, distance 32, (0, 10) is 52 away), so the island
    # is appended: S = 0 1 2 3 0 4 7 6 5 4.
    result = reference_triangulate([outer, island])
    assert len(result.triangles) == 8
    assert result.triangles[0] == (0, 1, 4)
    # Root base (s10, s1) = (0, 0)-(10, 0): the first candidate s9 = (4, 4) is correct; its
    # left child (s10, s9) would be adjacent, so the next node is the right child (s1, s9),
    # whose first candidate s8 = (6, 4) is correct.
    assert result.triangles[1] == (4, 1, 5)
    assert (result.parent[1], result.depth[1], result.side[1]) == (0, 1, 2)


# --- the checks used above can fail ---------------------------------------------------------------


def test_checks_reject_overlapping_triangles_of_a_square() -> None:
    square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    vertices = np.array([(*p, 0.0) for p in square])
    overlapping = np.array([[0, 1, 2], [0, 1, 3]])
    assert overlapping_pairs(vertices, overlapping) == [(0, 1)]
    with pytest.raises(AssertionError, match="overlapping"):
        check_tiling([square], vertices, overlapping)
    with pytest.raises(AssertionError, match="do not tile"):
        check_tiling([square], vertices, overlapping[:1])
    check_tiling([square], vertices, np.array([[0, 1, 2], [0, 2, 3]]))


def test_checks_count_touching_rings_and_split_edges() -> None:
    outer = [(0, 0), (4, 0), (4, 4), (0, 4)]
    touching_vertex = [(0, 0), (1, 2), (2, 1)]  # shares the outer corner (0, 0)
    on_edge = [(4, 2), (3, 3), (3, 1)]  # (4, 2) splits the outer edge (4, 0)-(4, 4)
    counts = polygon_counts([outer, touching_vertex, on_edge])
    assert (counts.vertices, counts.segments, counts.islands) == (9, 11, 2)
    assert counts.triangles == 9


def test_deviation_is_exact_for_a_tiny_gap() -> None:
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    vertices = np.array([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0 - 2**-52, 0)])
    assert deviation([square], vertices, np.array([[0, 1, 2], [0, 2, 3]])) == 2.0**-53


def test_check_tree_rejects_a_swapped_side_and_a_broken_pre_order() -> None:
    outer = [(0, 0), (10, 0), (10, 10), (0, 10)]
    result = reference_triangulate([outer, [(4, 4), (6, 4), (6, 6), (4, 6)]])
    tris, parent = np.asarray(result.triangles), np.asarray(result.parent)
    depth, side = np.asarray(result.depth), np.asarray(result.side)
    check_tree(tris, parent, depth, side)
    swapped = side.copy()
    swapped[1] = 3 - swapped[1]
    with pytest.raises(AssertionError, match="base is not"):
        check_tree(tris, parent, depth, swapped)
    order = [0, *range(2, len(tris)), 1]
    with pytest.raises(AssertionError):
        check_tree(tris[order], parent[order], depth[order], side[order])
