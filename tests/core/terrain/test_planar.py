"""Planar snapping (paper section 4.2): noisy roofs, islands, walls, the movement guarantee."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bsp_triangulate.terrain.planar import snap_to_plane


def _plane_residual(rings: list[np.ndarray]) -> float:
    """Largest vertical distance of the vertices from their own least-squares plane."""
    points = np.concatenate(rings)
    design = np.column_stack([points[:, :2] - points[:, :2].mean(axis=0), np.ones(len(points))])
    coefficients, *_ = np.linalg.lstsq(design, points[:, 2], rcond=None)
    return float(np.abs(design @ coefficients - points[:, 2]).max())


def _roof(n: int, centre=(303250.0, 6217600.0), radius=12.0, seed=0, noise=0.05):
    """An n-gon footprint in UTM-sized coordinates on the plane z = 0.3 x' - 0.2 y' + 120."""
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * np.pi, n))
    x = centre[0] + radius * np.cos(angles)
    y = centre[1] + radius * np.sin(angles)
    z = 0.3 * (x - centre[0]) - 0.2 * (y - centre[1]) + 120.0
    return np.column_stack([x, y, z + rng.uniform(-noise, noise, n)])


def _moves(before: list[np.ndarray], after: list[np.ndarray]) -> float:
    for b, a in zip(before, after):
        np.testing.assert_array_equal(a[:, :2], b[:, :2])
    return max(float(np.abs(a[:, 2] - b[:, 2]).max()) for b, a in zip(before, after))


def test_noisy_tilted_roof_with_tolerance_above_noise_becomes_coplanar():
    roof = _roof(16)
    assert _plane_residual([roof]) > 0.02
    (snapped,) = snap_to_plane([roof], 0.1)
    assert _plane_residual([snapped]) < 1e-9
    assert _moves([roof], [snapped]) <= 0.1


def test_noisy_roof_with_tolerance_below_noise_is_unchanged():
    roof = _roof(16)
    (snapped,) = snap_to_plane([roof], 0.01)
    np.testing.assert_array_equal(snapped, roof)


def test_square_roof_whose_twist_exceeds_tolerance_is_unchanged():
    # Four corners: the plane misses each by the same 0.04 (the twist), above 0.01.
    roof = np.array([[0, 0, 10.04], [10, 0, 9.96], [10, 10, 10.04], [0, 10, 9.96]])
    (snapped,) = snap_to_plane([roof], 0.01)
    np.testing.assert_array_equal(snapped, roof)
    (snapped,) = snap_to_plane([roof], 0.05)
    np.testing.assert_allclose(snapped[:, 2], 10.0, atol=1e-12)


def test_zero_or_missing_tolerance_returns_equal_copies():
    roof = _roof(8)
    for tolerance in (0, 0.0, None):
        (out,) = snap_to_plane([roof], tolerance)
        np.testing.assert_array_equal(out, roof)
        assert out is not roof


def test_roof_with_courtyard_island_snaps_both_rings_onto_one_plane():
    outer = _roof(20, radius=30.0, seed=1)
    island = _roof(8, radius=6.0, seed=2)[::-1]
    rings = snap_to_plane([outer, island], 0.1)
    assert [len(r) for r in rings] == [20, 8]
    assert _plane_residual(rings) < 1e-9
    assert _moves([outer, island], rings) <= 0.1


def test_island_on_a_different_level_gets_its_own_plane():
    outer = _roof(20, radius=30.0, seed=3)
    island = _roof(8, radius=6.0, seed=4)
    island[:, 2] += 2.5  # a raised skylight: not within the tolerance of the roof plane
    rings = snap_to_plane([outer, island], 0.1)
    assert _plane_residual(rings) > 1.0
    assert _plane_residual([rings[0]]) < 1e-9
    assert _plane_residual([rings[1]]) < 1e-9
    assert _moves([outer, island], rings) <= 0.1


def test_ring_with_two_roof_faces_beyond_the_tolerance_is_unchanged():
    # A gable end seen as one ring: face A (z = 5 + 0.5 y) then face B; no single plane fits.
    face_a = np.column_stack([np.linspace(0, 20, 8), np.linspace(0, 6, 8) ** 1.5, np.zeros(8)])
    face_a[:, 2] = 5 + 0.5 * face_a[:, 1]
    face_b = np.column_stack([np.linspace(20, 0, 8), np.linspace(20, 14, 8), np.zeros(8)])
    face_b[:, 0] += np.linspace(0, 3, 8) ** 2
    face_b[:, 2] = 30 - 0.8 * face_b[:, 1]
    ring = np.vstack([face_a, face_b])
    (snapped,) = snap_to_plane([ring], 0.05)
    np.testing.assert_array_equal(snapped, ring)


def test_vertical_wall_is_unchanged_even_when_lower_than_the_tolerance():
    wall = np.array([[0, 5, 0.0], [10, 5, 0.0], [10, 5, 0.5], [5, 5, 0.52], [0, 5, 0.5]])
    (out,) = snap_to_plane([wall], 1.0)
    np.testing.assert_array_equal(out, wall)


def test_ring_with_a_nan_elevation_is_left_unchanged():
    roof = _roof(8)
    roof[3, 2] = np.nan
    (out,) = snap_to_plane([roof], 0.1)
    np.testing.assert_array_equal(out, roof)


def test_closing_point_stays_equal_to_the_first_point():
    roof = _roof(10, seed=5)
    closed = np.vstack([roof, roof[:1]])
    (out,) = snap_to_plane([closed], 0.1)
    assert len(out) == 11
    np.testing.assert_array_equal(out[-1], out[0])
    assert _plane_residual([out[:-1]]) < 1e-9
    (out,) = snap_to_plane([closed], 0.01)
    np.testing.assert_array_equal(out[-1], out[0])


coordinate = st.floats(-1e5, 1e5, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.lists(st.tuples(coordinate, coordinate, st.floats(-50, 50)), min_size=3, max_size=25),
        min_size=1,
        max_size=3,
    ),
    st.floats(1e-6, 10.0),
    st.floats(0.0, 0.3),
)
def test_no_vertex_moves_more_than_the_tolerance(rings, tolerance, squash):
    # ``squash`` pulls z towards a plane so that both the polygon and the ring rules get exercised.
    arrays = []
    for ring in rings:
        points = np.asarray(ring, dtype=np.float64)
        points[:, 2] = points[:, 2] * squash + 0.001 * points[:, 0]
        arrays.append(points)
    out = snap_to_plane(arrays, tolerance)
    assert [a.shape for a in out] == [a.shape for a in arrays]
    assert _moves(arrays, out) <= tolerance
