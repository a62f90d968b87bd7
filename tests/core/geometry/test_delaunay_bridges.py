"""Rule delaunay's bridges skip the island vertices whose bridge surely has a vertex inside
its diametral circle (every target within the bound that the vertices around h set has one,
by those vertices or, for the few they leave, by the exact test), and stop each search where
every farther target would have one; the sequences are those of the search without that
shortcut, also on grids full of cocircular points and on clusters of islands beside open
ground."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

import bsp_triangulate.geometry.bridges as bridges
from bsp_triangulate.geometry.bridges import _witness_bound, bridge_islands
from bsp_triangulate.geometry.rings import normalise_rings, prepare
from tests.core.geometry.test_bridge_plan import scattered_squares, square


def delaunay_bridged(
    rings: list[np.ndarray], shortcut: bool, monkeypatch: pytest.MonkeyPatch
) -> np.ndarray:
    clean, axes = normalise_rings(rings, "xy")
    prepared = prepare(clean, axes)
    with monkeypatch.context() as patch:
        # the one-by-one search, not the links (test_delaunay_links.py)
        patch.setattr(bridges, "LINKED_ISLANDS", len(rings))
        if not shortcut:
            patch.setattr(
                bridges._Bridger,
                "_disk_never_empty_beyond",
                lambda self, h: (math.inf, np.zeros(0, dtype=np.int64)),
            )
        return bridge_islands(
            prepared.x,
            prepared.y,
            prepared.rings,
            list(range(len(prepared.rings))),
            delaunay=True,
        )


@pytest.mark.parametrize("seed", range(6))
def test_scattered_square_islands_get_the_same_delaunay_bridges(
    seed: int, monkeypatch: pytest.MonkeyPatch
):
    rings = scattered_squares(seed, count=40)
    expected = delaunay_bridged(rings, False, monkeypatch)
    assert np.array_equal(delaunay_bridged(rings, True, monkeypatch), expected)


def test_grid_of_square_islands_with_cocircular_corners_gets_the_same_delaunay_bridges(
    monkeypatch: pytest.MonkeyPatch,
):
    islands = [square(4.0 * i + 2.0, 4.0 * j + 2.0, 2.0) for i in range(7) for j in range(7)]
    rings = [square(0.0, 0.0, 30.0), *islands]
    expected = delaunay_bridged(rings, False, monkeypatch)
    assert np.array_equal(delaunay_bridged(rings, True, monkeypatch), expected)


def test_a_vertex_ringed_by_close_neighbours_has_a_near_bound_and_a_wide_open_one_a_far_one():
    # h at the centre of a small octagon of vertices; far vertices elsewhere
    octagon = [(math.cos(a), math.sin(a)) for a in np.linspace(0.0, 2 * math.pi, 8, endpoint=False)]
    x = np.array([0.0, *(p[0] for p in octagon), 50.0, 60.0, 60.0])
    y = np.array([0.0, *(p[1] for p in octagon), 50.0, 50.0, 60.0])
    bridger = bridges._Bridger(x, y, [np.arange(1, 9), np.array([9, 10, 11])])
    reach, near = bridger._disk_never_empty_beyond(0)
    # the octagon the eight leave: its corners are 1 / cos(22.5 degrees) away
    assert 1.0 / math.cos(math.pi / 8.0) <= reach < 1.09 and len(near) == 8
    # nearly nothing around on one side: a bound far beyond its neighbours
    assert bridger._disk_never_empty_beyond(9)[0] > 1000.0


def clustered_squares(seed: int, clusters: int = 4, per_cluster: int = 30) -> list[np.ndarray]:
    """Small square islands packed in a few clusters, with open ground between them and the
    shell: the searches from a cluster's edge look far across it."""
    rng = np.random.default_rng(seed)
    islands: list[np.ndarray] = []
    for _ in range(clusters):
        cx, cy = rng.uniform(15.0, 85.0, 2)
        placed = 0
        while placed < per_cluster:
            x, y = cx + rng.uniform(-8.0, 8.0), cy + rng.uniform(-8.0, 8.0)
            side = rng.uniform(0.2, 0.8)
            if not 2.0 < x < 97.0 or not 2.0 < y < 97.0:
                continue
            if all(abs(x - i[0, 0]) > 1.2 or abs(y - i[0, 1]) > 1.2 for i in islands):
                islands.append(square(x, y, side))
                placed += 1
    return [square(0.0, 0.0, 100.0), *islands]


@pytest.mark.parametrize("seed", range(4))
def test_clustered_islands_beside_open_ground_get_the_same_delaunay_bridges(
    seed: int, monkeypatch: pytest.MonkeyPatch
):
    rings = clustered_squares(seed)
    expected = delaunay_bridged(rings, False, monkeypatch)
    assert np.array_equal(delaunay_bridged(rings, True, monkeypatch), expected)


def test_witnesses_around_h_bound_the_targets_with_an_empty_circle():
    # four at distance 1 on the axes: the corner of the square they leave is sqrt(2) away
    bound, closed = _witness_bound(np.array([1.0, 0.0, -1.0, 0.0]), np.array([0.0, 1.0, 0.0, -1.0]))
    assert not closed and math.sqrt(2.0) <= bound < 1.415
    # three at 120 degrees: an equilateral triangle of inradius 1, circumradius 2
    angles = np.radians([90.0, 210.0, 330.0])
    bound, _ = _witness_bound(np.cos(angles), np.sin(angles))
    assert 2.0 <= bound < 2.001
    # all on one side of h: targets on the other side may be as far as they like
    assert _witness_bound(np.array([1.0, 1.0, 1.0]), np.array([-1.0, 0.0, 1.0]))[0] == math.inf


@pytest.mark.parametrize("scale", [2.0**-530, 1.0, 2.0**520])
@pytest.mark.parametrize("seed", range(20))
def test_every_point_beyond_the_bound_has_a_witness_inside_its_circle(seed: int, scale: float):
    # also where the squares of the offsets would be subnormal or overflow
    rng = np.random.default_rng(seed)
    count = int(rng.integers(3, 12))
    dx, dy = rng.normal(size=count) * scale, rng.normal(size=count) * scale
    bound, _ = _witness_bound(dx, dy)
    if bound == math.inf:
        return
    for angle in rng.uniform(0.0, 2.0 * math.pi, 200):
        r = bound * float(rng.uniform(1.0, 3.0))
        vx, vy = Fraction(r * math.cos(angle)), Fraction(r * math.sin(angle))
        # w strictly inside the circle on h-v (h at the origin): w . (w - v) < 0, exactly
        assert any(
            Fraction(wx) * (Fraction(wx) - vx) + Fraction(wy) * (Fraction(wy) - vy) < 0
            for wx, wy in zip(dx.tolist(), dy.tolist())
        )


def test_witnesses_in_the_subnormal_range_bound_nothing():
    # rounding in the last products there exceeds any margin: no bound rather than a wrong one
    s = 2.0**-1060
    bound, _ = _witness_bound(np.array([s, 0.0, -s, 0.0]), np.array([0.0, s, 0.0, -s]))
    assert bound == math.inf


def test_a_vertex_inside_a_huge_circle_spoils_it_where_the_float_products_overflow():
    # (w - h) . (w - v) overflows to nan in floats; exactly, w lies strictly inside
    x = np.array([0.0, 0.0, 2e154, 3e201, 3e201])
    y = np.array([0.0, 1e201, 1e200, 0.0, 1e201])
    bridger = bridges._Bridger(x, y, [np.array([0, 3, 4, 1]), np.array([2])])
    w = (Fraction(2e154), Fraction(1e200))
    assert w[0] * (w[0] - 0) + w[1] * (w[1] - Fraction(1e201)) < 0
    with np.errstate(over="ignore", invalid="ignore"):  # as the engine runs
        assert not bridger.diametral_disk_empty(0, 1)


@pytest.mark.parametrize("seed", range(4))
def test_vertices_whose_few_open_circles_are_all_spoilt_are_passed_over_without_a_search(
    seed: int, monkeypatch: pytest.MonkeyPatch
):
    rings = clustered_squares(seed)
    expected = delaunay_bridged(rings, False, monkeypatch)
    searches = {}
    for few in (0, bridges._FEW_DISKS):
        calls = []
        search = bridges._Bridger.find_bridge
        with monkeypatch.context() as patch:
            patch.setattr(bridges, "_FEW_DISKS", few)
            patch.setattr(
                bridges._Bridger,
                "find_bridge",
                lambda self, *args, search=search, calls=calls: (
                    calls.append(1) or search(self, *args)
                ),
            )
            assert np.array_equal(delaunay_bridged(rings, True, monkeypatch), expected)
        searches[few] = len(calls)
    assert searches[bridges._FEW_DISKS] < searches[0]
