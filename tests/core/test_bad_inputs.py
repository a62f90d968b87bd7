"""The bad-input matrix through the engine: every row with invalid="fail" and "as_given".

Each row gives a correct triangulation (exact checks), an empty one (degenerate input), or a
``TriangulationError`` whose message names the ring; never a crash or a hang.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import shapely

from bsp_triangulate import PackedPolygons, triangulate, triangulate_many, triangulate_packed
from bsp_triangulate.triangulation import Triangulation, TriangulationError
from tests.core.checks import check_triangulation, check_vertices

ROOT = Path(__file__).resolve().parents[2]
MODES = ("fail", "as_given")
SQUARE = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
NAN, INF = float("nan"), float("inf")


def exact_area(result: Triangulation) -> Fraction:
    """Sum of the triangles' XY areas, exact (triangles of any orientation)."""
    total = Fraction(0)
    v = result.vertices
    for a, b, c in result.triangles.tolist():
        ax, ay, bx, by, cx, cy = (Fraction(float(t)) for t in (*v[a, :2], *v[b, :2], *v[c, :2]))
        total += abs((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))
    return total / 2


def repaired_area(rings: list) -> float:
    """Area of the rings made valid the way the engine repairs them (shapely, "structure")."""
    polygon = shapely.Polygon(rings[0], rings[1:])
    return shapely.make_valid(polygon, method="structure").area


# --- degenerate input: an empty result in both modes --------------------------------------------

DEGENERATE = {
    "no_rings": [],
    "empty_outer_ring": [[]],
    "two_points": [[(0, 0), (5, 5)]],
    "three_points_two_distinct": [[(0, 0), (5, 5), (0, 0)]],
    "one_point_repeated": [[(3, 3)] * 6],
    "all_points_collinear": [[(0, 0), (1, 1), (2, 2), (3, 3), (1.5, 1.5)]],
    "collinear_with_duplicates": [[(0, 0), (0, 0), (4, 0), (4, 0), (2, 0)]],
    "island_identical_to_outer_ring": [SQUARE, SQUARE],
    "island_identical_reversed": [SQUARE, SQUARE[::-1]],
}


@pytest.mark.parametrize("invalid", MODES)
@pytest.mark.parametrize("name", sorted(DEGENERATE))
def test_degenerate_input_gives_an_empty_triangulation(name: str, invalid: str):
    result = triangulate(DEGENERATE[name], invalid=invalid)
    assert result.is_empty and len(result.parent) == 0
    assert result.vertices.ndim == 2 and result.vertices.shape[1] == 3


# --- valid (or harmlessly degenerate) input: exact tiling in both modes --------------------------

VALID = {
    "duplicate_consecutive_points": [
        [(0, 0), (0, 0), (10, 0), (10, 0), (10, 0), (10, 10), (0, 10), (0, 10), (0, 0)]
    ],
    "closing_point_repeated_twice": [[(0, 0), (10, 0), (5, 8), (0, 0), (0, 0)]],
    "collinear_run_on_an_edge": [[(0, 0), (2, 0), (4, 0), (6, 0), (6, 6), (0, 6)]],
    "island_with_two_distinct_points_ignored": [SQUARE, [(2, 2), (3, 3), (2, 2)]],
    "island_collinear_ignored": [SQUARE, [(2, 2), (3, 3), (4, 4)]],
    "island_touching_outer_ring_at_a_vertex": [SQUARE, [(0, 0), (3, 1), (1, 3)]],
    "island_touching_outer_ring_inside_an_edge": [SQUARE, [(5, 0), (7, 2), (3, 2)]],
    "island_along_an_outer_edge": [SQUARE, [(2, 0), (4, 0), (3, 2)]],
    "islands_touching_each_other_at_a_vertex": [
        SQUARE,
        [(2, 2), (4, 2), (4, 4)],
        [(4, 4), (6, 4), (6, 6)],
    ],
    "islands_sharing_an_edge": [
        SQUARE,
        [(2, 2), (4, 2), (4, 4), (2, 4)],
        [(4, 2), (6, 2), (6, 4), (4, 4)],
    ],
    "coordinates_around_1e15": [
        [(1e15 + x, 1e15 + y) for x, y in [(0, 0), (3, 0), (3, 2), (1, 1), (0, 2)]],
        [(1e15 + x, 1e15 + y) for x, y in [(0.5, 0.25), (1, 0.25), (0.75, 0.5)]],
    ],
    "polygon_of_size_1e_9": [
        [(1e-9 * x, 1e-9 * y) for x, y in [(0, 0), (3, 0), (3, 2), (1, 1), (0, 2)]],
        [(1e-9 * x, 1e-9 * y) for x, y in [(0.5, 0.25), (1, 0.25), (0.75, 0.5)]],
    ],
    "size_1e_9_at_1e6_offset": [
        [(1e6 + 1e-9 * x, -1e6 + 1e-9 * y) for x, y in [(0, 0), (3, 0), (3, 2), (1, 1), (0, 2)]]
    ],
    "clockwise_outer_ring_with_z": [[(0, 0, 1), (0, 6, 2), (4, 3, 3), (8, 6, 4), (8, 0, 5)]],
}


@pytest.mark.parametrize("invalid", MODES)
@pytest.mark.parametrize("name", sorted(VALID))
def test_valid_or_touching_input_tiles_the_polygon_exactly(name: str, invalid: str):
    rings = VALID[name]
    result = triangulate(rings, invalid=invalid)
    counts = check_triangulation(rings, result, valid=True)
    assert counts.triangles > 0 and len(result) == counts.triangles


SPIKES = {
    "outward_zero_width_spike": [[(0, 0), (10, 0), (10, 10), (5, 10), (5, 15), (5, 10), (0, 10)]],
    "inward_zero_width_spike": [[(0, 0), (10, 0), (10, 10), (5, 10), (5, 5), (5, 10), (0, 10)]],
    "spike_with_a_collinear_middle_point": [
        [(0, 0), (10, 0), (10, 10), (5, 10), (5, 12), (5, 14), (5, 12), (5, 10), (0, 10)]
    ],
}


@pytest.mark.parametrize("invalid", MODES)
@pytest.mark.parametrize("name", sorted(SPIKES))
def test_zero_width_spikes_are_dropped_and_the_square_is_tiled(name: str, invalid: str):
    rings = SPIKES[name]
    result = triangulate(rings, invalid=invalid)
    check_triangulation(rings, result, valid=True, expect_count=False)
    assert exact_area(result) == 100
    assert len(result) == 3  # the square with the spike's foot (5, 10) on its top edge


# --- invalid input: an error naming the ring, or triangles of the repaired area -----------------

INVALID = {
    "bow_tie_with_cancelling_lobes": ([[(0, 0), (10, 10), (10, 0), (0, 10)]], "ring 1 (outer)"),
    "bow_tie_with_unequal_lobes": ([[(0, 0), (10, 10), (10, 0), (0, 6)]], "ring 1 (outer)"),
    "self_crossing_pentagram": ([[(0, 0), (10, 4), (2, 8), (6, -2), (8, 8)]], "ring 1 (outer)"),
    "island_outside_the_outer_ring": ([SQUARE, [(20, 0), (22, 0), (22, 2)]], "ring 2 (island 1)"),
    "island_crossing_the_outer_ring": (
        [SQUARE, [(8, 2), (12, 2), (12, 4), (8, 4)]],
        "ring 2 (island 1)",
    ),
    "island_nested_in_another_island": (
        [SQUARE, [(1, 1), (9, 1), (9, 9), (1, 9)], [(3, 3), (5, 3), (5, 5), (3, 5)]],
        "ring 3 (island 2)",
    ),
    "islands_crossing_each_other": (
        [SQUARE, [(2, 2), (6, 2), (6, 6), (2, 6)], [(4, 4), (8, 4), (8, 8), (4, 8)]],
        "(island ",
    ),
}


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_input_fails_with_a_message_naming_the_ring(name: str):
    rings, label = INVALID[name]
    with pytest.raises(TriangulationError, match=r"invalid polygon|outside") as caught:
        triangulate(rings, invalid="fail")
    assert label in str(caught.value)


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_input_as_given_covers_the_repaired_area_with_input_or_crossing_vertices(
    name: str,
):
    rings, _label = INVALID[name]
    result = triangulate(rings, invalid="as_given")
    check_triangulation(rings, result, valid=False)
    assert len(result) > 0
    assert float(exact_area(result)) == pytest.approx(repaired_area(rings), rel=1e-12)


def test_self_touching_figure_eight_as_given_keeps_both_lobes_and_adds_no_vertex():
    ring = [(7, 18), (7, 15), (5, 15), (7, 13), (7, 15), (17, 17)]
    with pytest.raises(TriangulationError, match=r"ring 1 \(outer\)"):
        triangulate([ring], invalid="fail")
    result = triangulate([ring], invalid="as_given")
    check_triangulation([ring], result, valid=False)
    check_vertices([ring], result.vertices, result.triangles, crossings=False)
    assert exact_area(result) == 17


# --- non-finite coordinates ---------------------------------------------------------------------

NON_FINITE = {
    "nan_x_in_outer_ring": ([[(0, 0), (NAN, 1), (1, 1)]], "ring 1 (outer)"),
    "nan_y_in_outer_ring": ([[(0, 0), (1, NAN), (1, 1)]], "ring 1 (outer)"),
    "infinite_x_in_island": ([SQUARE, [(1, 1), (INF, 2), (2, 2)]], "ring 2 (island 1)"),
    "minus_infinite_in_second_island": (
        [SQUARE, [(1, 1), (2, 1), (2, 2)], [(5, 5), (6, -INF), (6, 6)]],
        "ring 3 (island 2)",
    ),
    "nan_z_in_outer_ring": ([[(0, 0, 0), (1, 0, NAN), (1, 1, 0)]], "ring 1 (outer)"),
}


@pytest.mark.parametrize("invalid", MODES)
@pytest.mark.parametrize("name", sorted(NON_FINITE))
def test_non_finite_coordinates_fail_naming_the_ring(name: str, invalid: str):
    rings, label = NON_FINITE[name]
    with pytest.raises(TriangulationError, match="not finite") as caught:
        triangulate(rings, invalid=invalid)
    assert str(caught.value).startswith(label)


@pytest.mark.parametrize(
    "rings",
    [[[(0, 0), (1, 0)], "not a ring"], [[("a", "b"), (1, 0), (1, 1)]], [[(0, 0, 0, 0, 0)] * 3]],
    ids=["ring_is_a_string", "non_numeric_points", "five_coordinates_per_point"],
)
def test_malformed_rings_fail_with_a_triangulation_error(rings: list):
    with pytest.raises(TriangulationError, match=r"ring \d"):
        triangulate(rings)


# --- vertical faces (zero area in XY) -----------------------------------------------------------


def area_3d(result: Triangulation) -> float:
    v = result.vertices
    t = result.triangles
    cross = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    return float(np.linalg.norm(cross, axis=1).sum() / 2)


@pytest.mark.parametrize("invalid", MODES)
@pytest.mark.parametrize(
    ("ring", "area"),
    [
        ([(0, 0, 0), (10, 0, 0), (10, 0, 5), (5, 0, 3), (0, 0, 5)], 40.0),
        ([(0, 0, 0), (0, 8, 0), (0, 8, 4), (0, 0, 4)], 32.0),
        ([(0, 0, 0), (6, 8, 0), (6, 8, 5), (3, 4, 2), (0, 0, 5)], 35.0),
    ],
    ids=["wall_in_xz", "wall_in_yz", "diagonal_wall"],
)
def test_vertical_face_gets_n_minus_2_triangles_of_input_vertices_over_its_3d_area(
    ring: list, area: float, invalid: str
):
    result = triangulate([ring], invalid=invalid)
    assert len(result) == len(ring) - 2
    check_vertices([ring], result.vertices, result.triangles)
    assert area_3d(result) == pytest.approx(area, rel=1e-12)


# --- multipolygon parts that touch: each part on its own -----------------------------------------


def test_multipolygon_parts_touching_at_a_vertex_and_an_edge_each_tile_their_part():
    parts = [
        [SQUARE],
        [[(10, 0), (20, 0), (20, 10), (10, 10)]],  # shares the edge x = 10
        [[(20, 10), (25, 15), (20, 15)]],  # touches the second part at (20, 10)
    ]
    for invalid in MODES:
        results = triangulate_many(parts, invalid=invalid, on_error="return")
        for rings, result in zip(parts, results):
            check_triangulation(rings, result, valid=True)
        assert sum(exact_area(r) for r in results) == 100 + 100 + Fraction(25, 2)


# --- the batch path agrees with the engine on every row ------------------------------------------


@pytest.mark.parametrize("invalid", MODES)
def test_triangulate_many_matches_triangulate_on_every_row_of_the_matrix(invalid: str):
    rows = [
        *DEGENERATE.values(),
        *VALID.values(),
        *SPIKES.values(),
        *(rings for rings, _ in INVALID.values()),
        *(rings for rings, _ in NON_FINITE.values()),
    ]
    many = triangulate_many(rows, invalid=invalid, on_error="return")
    for rings, got in zip(rows, many):
        try:
            alone = triangulate(rings, invalid=invalid)
        except TriangulationError as exc:
            assert isinstance(got, TriangulationError), (rings, got)
            assert str(got) == str(exc)
            continue
        assert isinstance(got, Triangulation), (rings, got)
        np.testing.assert_array_equal(got.triangles, alone.triangles)
        np.testing.assert_array_equal(got.vertices, alone.vertices)


@pytest.mark.parametrize("invalid", MODES)
def test_triangulate_packed_matches_triangulate_many_on_every_row_of_the_matrix(invalid: str):
    rows = [
        *DEGENERATE.values(),
        *VALID.values(),
        *SPIKES.values(),
        *(rings for rings, _ in INVALID.values()),
        *(rings for rings, _ in NON_FINITE.values()),
    ]
    many = triangulate_many(rows, invalid=invalid, on_error="return")
    packed = triangulate_packed(PackedPolygons.of(rows), invalid=invalid, on_error="return")
    assert len(packed) == len(rows)
    for index, (rings, want) in enumerate(zip(rows, many)):
        got = packed[index]
        if isinstance(want, TriangulationError):
            assert isinstance(got, TriangulationError), (rings, got)
            assert str(got) == str(want)
            continue
        assert isinstance(got, Triangulation), (rings, got)
        for name in ("vertices", "triangles", "parent", "depth", "side"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name))


def test_triangulate_many_raises_the_first_error_by_default():
    with pytest.raises(TriangulationError, match="not finite"):
        triangulate_many([[SQUARE], [[(0, 0), (NAN, 1), (1, 1)]]])


def test_unknown_invalid_mode_and_on_error_are_refused():
    with pytest.raises(ValueError, match="invalid must be"):
        triangulate([SQUARE], invalid="repair")
    with pytest.raises(ValueError, match="on_error"):
        triangulate_many([[SQUARE]], on_error="ignore")


# --- hostile input: every loop is bounded --------------------------------------------------------

HOSTILE_SCRIPT = textwrap.dedent(
    """
    import sys
    import numpy as np
    import shapely
    from bsp_triangulate import triangulate
    from bsp_triangulate.triangulation import TriangulationError

    mode, count = sys.argv[1], int(sys.argv[2])
    ring = np.random.default_rng(20240601).uniform(0, 1000, size=(count, 2))
    try:
        result = triangulate([ring], invalid=mode)
    except TriangulationError as exc:
        print("error", exc)
    else:
        v, t = result.vertices, result.triangles
        a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        ab, ac = b - a, c - a
        cross = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
        repaired = shapely.make_valid(shapely.Polygon(ring), method="structure").area
        print("triangles", len(t), abs(cross).sum() / 2, repaired)
    """
)


def run_hostile(invalid: str, count: int) -> list[str]:
    """Triangulate ``count`` random points as one ring in a child process killed after 60 s."""
    try:
        proc = subprocess.run(
            [sys.executable, "-c", HOSTILE_SCRIPT, invalid, str(count)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"triangulate(invalid={invalid!r}) on {count} random points ran over 60 s")
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout.strip().split(" ", 1)


def test_two_thousand_random_points_as_one_ring_fail_cleanly_within_a_minute():
    kind, detail = run_hostile("fail", 2000)
    assert kind == "error" and detail.startswith("ring 1 (outer): no correct triangle"), detail


def test_random_points_as_one_ring_as_given_cover_the_repaired_area_within_a_minute():
    # the repaired polygon has a vertex at each of the ring's Theta(n^2) crossings
    kind, detail = run_hostile("as_given", 300)
    assert kind == "triangles", detail
    count, area, repaired = detail.split()
    assert int(count) > 300
    assert float(area) == pytest.approx(float(repaired), rel=1e-9)
