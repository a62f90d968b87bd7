"""Rule delaunay's bridges skip the island vertices whose bridge surely has a vertex inside
its diametral circle (the vertices around them leave no gap of 90 degrees); the sequences
are those of the search without that shortcut, also on grids full of cocircular points."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bsp_triangulate.geometry.bridges as bridges
from bsp_triangulate.geometry.bridges import bridge_islands
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


def test_a_vertex_ringed_by_close_neighbours_has_a_bound_and_a_wide_open_one_has_none():
    # h at the centre of a small octagon of vertices; far vertices elsewhere
    octagon = [(math.cos(a), math.sin(a)) for a in np.linspace(0.0, 2 * math.pi, 8, endpoint=False)]
    x = np.array([0.0, *(p[0] for p in octagon), 50.0, 60.0, 60.0])
    y = np.array([0.0, *(p[1] for p in octagon), 50.0, 50.0, 60.0])
    bridger = bridges._Bridger(x, y, [np.arange(1, 9), np.array([9, 10, 11])])
    reach, near = bridger._disk_never_empty_beyond(0)
    assert math.sqrt(2.0) <= reach < 1.5 and len(near) == 8
    assert bridger._disk_never_empty_beyond(9)[0] == math.inf  # nothing around on one side
