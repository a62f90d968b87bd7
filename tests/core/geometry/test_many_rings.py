"""Many rings are parsed and cleaned in one pass over their concatenation: the same rings as
one by one (consecutive duplicates and the closing point dropped), the same errors; and a
sequence with no spike leaves ``remove_spikes`` unchanged without the element by element walk."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.geometry import rings as rings_module
from bsp_triangulate.geometry.bridges import remove_spikes
from bsp_triangulate.geometry.rings import normalise_rings
from bsp_triangulate.triangulation import TriangulationError


def one_by_one(rings: list, plane: str) -> tuple[list[np.ndarray], tuple[int, int]]:
    raw = [rings_module._as_points(ring, number) for number, ring in enumerate(rings)]
    axes = (0, 1) if plane == "xy" else rings_module.working_axes(raw[0])
    return [rings_module._clean(points, axes) for points in raw], axes


def noisy_rings(seed: int, width: int) -> list[np.ndarray]:
    """Rings on a 3 x 3 grid of points (many repeats), some closed, one of a single point."""
    rng = np.random.default_rng(seed)
    rings = []
    for k in range(rings_module._MANY_RINGS + 8):
        points = rng.integers(0, 3, size=(int(rng.integers(1, 9)), width)).astype(float)
        if k % 2:
            points = np.vstack([points, points[:1]])
        rings.append(points)
    return rings


@pytest.mark.parametrize("width", [2, 3, 4])
@pytest.mark.parametrize("plane", ["xy", "auto"])
def test_many_noisy_rings_clean_as_one_by_one(width: int, plane: str) -> None:
    for seed in range(40):
        rings = noisy_rings(seed, width)
        if seed % 5 == 0:
            rings = [ring.tolist() for ring in rings]
        expected, expected_axes = one_by_one(rings, plane)
        cleaned, axes = normalise_rings(rings, plane)
        assert axes == expected_axes
        assert len(cleaned) == len(expected)
        for got, want in zip(cleaned, expected):
            assert got.shape == want.shape
            assert np.array_equal(got, want)


def test_a_closed_ring_of_two_repeats_keeps_one_point() -> None:
    # (p, p, p): duplicates leave (p), alone, which keeps its point
    rings = [np.zeros((3, 3))] * (rings_module._MANY_RINGS + 1)
    cleaned, _ = normalise_rings(rings, "xy")
    assert all(ring.shape == (1, 3) for ring in cleaned)


def test_many_rings_with_a_coordinate_not_finite_name_the_ring() -> None:
    rings = noisy_rings(1, 3)
    rings[7] = rings[7].copy()
    rings[7][0, 1] = np.nan
    message = r"ring 8 \(island 7\): coordinates are not finite"
    with pytest.raises(TriangulationError, match=message):
        normalise_rings(rings, "xy")


def test_many_rings_of_mixed_widths_take_the_ring_by_ring_path() -> None:
    rings = noisy_rings(2, 3)
    rings[3] = rings[3][:, :2]
    expected, _ = one_by_one(rings, "xy")
    cleaned, _ = normalise_rings(rings, "xy")
    assert all(np.array_equal(got, want) for got, want in zip(cleaned, expected))


def test_a_sequence_without_spikes_comes_back_unchanged() -> None:
    x = np.array([0.0, 4.0, 4.0, 0.0, 1.0, 2.0, 2.0])
    y = np.array([0.0, 0.0, 4.0, 4.0, 1.0, 1.0, 2.0])
    seq = np.array([0, 1, 2, 3, 0, 4, 6, 5, 4])
    assert remove_spikes(x, y, seq) is seq


def test_a_spike_across_the_sequence_end_is_still_cancelled() -> None:
    # the last position walks back to the second one's point: (.., 4, | 0, 4, ..)
    x = np.array([0.0, 4.0, 4.0, 0.0, 2.0])
    y = np.array([0.0, 0.0, 4.0, 4.0, 2.0])
    seq = np.array([4, 0, 1, 2, 3, 0])
    assert remove_spikes(x, y, seq).tolist() == [0, 1, 2, 3]


@pytest.mark.parametrize("islands", [2, rings_module._MANY_RINGS + 1])
def test_rings_given_as_an_iterator_are_read_once(islands: int) -> None:
    shell = np.array([(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)])
    holes = [
        np.array([(x, 10.0), (x, 12.0), (x + 2.0, 12.0), (x + 2.0, 10.0)])
        for x in np.linspace(5.0, 90.0, islands)
    ]
    rings = [shell, *holes]
    expected = triangulate(rings)
    result = triangulate(ring for ring in rings)
    assert np.array_equal(result.triangles, expected.triangles)
