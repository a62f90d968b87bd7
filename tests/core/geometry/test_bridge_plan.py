"""Bridges planned for many islands at once are the bridges of the one-by-one search.

The reference is ``bridge_islands`` with the plan switched off; the inputs have many islands
(the plan's domain), with exact distance ties, islands in a row whose bridges would cross,
and islands near the shell.
"""

from __future__ import annotations

import numpy as np
import pytest

import bsp_triangulate.geometry.bridges as bridges
from bsp_triangulate.geometry.bridges import bridge_islands
from bsp_triangulate.geometry.rings import normalise_rings, prepare


def bridged(rings: list[np.ndarray], plan: bool, monkeypatch: pytest.MonkeyPatch) -> np.ndarray:
    clean, axes = normalise_rings(rings, "xy")
    prepared = prepare(clean, axes)
    with monkeypatch.context() as patch:
        if not plan:
            patch.setattr(bridges, "_plannable", lambda *args: False)
        return bridge_islands(
            prepared.x, prepared.y, prepared.rings, list(range(len(prepared.rings)))
        )


def square(x: float, y: float, side: float) -> np.ndarray:
    return np.array([(x, y), (x + side, y), (x + side, y + side), (x, y + side)])


def scattered_squares(seed: int, count: int = 60) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    islands: list[np.ndarray] = []
    while len(islands) < count:
        x, y = rng.uniform(2.0, 96.0, 2)
        side = rng.uniform(0.1, 2.0)
        if all(abs(x - i[0, 0]) > 2.5 or abs(y - i[0, 1]) > 2.5 for i in islands):
            islands.append(square(x, y, side))
    return [square(0.0, 0.0, 100.0), *islands]


def count_found(monkeypatch: pytest.MonkeyPatch, method: str) -> list[bool]:
    """Per call of the bridger's ``method`` from now on: whether it gave a target."""
    used: list[bool] = []
    original = getattr(bridges._Bridger, method)

    def counting(self, *args):
        result = original(self, *args)
        used.append(result is not None)
        return result

    monkeypatch.setattr(bridges._Bridger, method, counting)
    return used


@pytest.mark.parametrize("seed", range(12))
def test_scattered_square_islands_get_the_bridges_of_the_one_by_one_search(
    seed: int, monkeypatch: pytest.MonkeyPatch
):
    rings = scattered_squares(seed)
    expected = bridged(rings, False, monkeypatch)
    used = count_found(monkeypatch, "planned")
    assert np.array_equal(bridged(rings, True, monkeypatch), expected)
    assert sum(used) > len(rings) // 2


def test_grid_of_islands_with_exact_distance_ties_gets_the_same_bridges(
    monkeypatch: pytest.MonkeyPatch,
):
    # every island's leftmost vertex is equally far from two vertices to its left
    islands = [square(10.0 * i + 5.0, 10.0 * j + 5.0, 2.0) for i in range(6) for j in range(6)]
    rings = [square(0.0, 0.0, 70.0), *islands]
    expected = bridged(rings, False, monkeypatch)
    assert np.array_equal(bridged(rings, True, monkeypatch), expected)


def test_staircase_of_thin_islands_whose_nearest_bridges_cross_gets_the_same_bridges(
    monkeypatch: pytest.MonkeyPatch,
):
    # long thin slabs, each leftmost vertex nearest to a vertex whose segment an earlier
    # bridge may cross
    islands = []
    for k in range(24):
        x, y = 5.0 + 3.0 * k, 5.0 + 2.5 * k
        islands.append(np.array([(x, y), (x + 30.0, y + 0.5), (x + 30.0, y + 1.0), (x, y + 0.6)]))
    rings = [np.array([(0.0, 0.0), (120.0, 0.0), (120.0, 80.0), (0.0, 80.0)]), *islands]
    expected = bridged(rings, False, monkeypatch)
    assert np.array_equal(bridged(rings, True, monkeypatch), expected)


def test_islands_near_a_wavy_shell_get_the_same_bridges(monkeypatch: pytest.MonkeyPatch):
    t = np.linspace(0.0, 2.0 * np.pi, 400, endpoint=False)
    radius = 50.0 + 4.0 * np.sin(9.0 * t)
    shell = np.column_stack([radius * np.cos(t), radius * np.sin(t)])
    islands = [
        square(r * np.cos(a), r * np.sin(a), 1.5)
        for r in (20.0, 30.0, 40.0)
        for a in np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    ]
    rings = [shell, *islands]
    expected = bridged(rings, False, monkeypatch)
    used = count_found(monkeypatch, "planned")
    assert np.array_equal(bridged(rings, True, monkeypatch), expected)
    assert sum(used) > 0


def spliced_beside(third: list[tuple[float, float]]) -> tuple[bridges._Bridger, np.ndarray]:
    """A bridger over an outer square (with a vertex at (0, 10)), a triangle at (10, 10) and a
    third island (clockwise ``third``, its first point leftmost), the triangle joined by
    the bridge (0, 0)-(10, 10), which makes (0, 0) occur twice; and the third island's ids."""
    points = [(0.0, 0.0), (20.0, 0.0), (20.0, 20.0), (0.0, 20.0), (10.0, 10.0), (11.0, 10.0)]
    points += [(11.0, 11.0), (0.0, 10.0), *third]
    x, y = (np.array(column) for column in zip(*points))
    outer = np.array([0, 1, 2, 3, 7])
    island = np.array([4, 5, 6])
    other = np.arange(8, 8 + len(third))
    bridger = bridges._Bridger(x, y, [outer, island, other])
    bridger.splice(0, island, 0)  # the bridge 0-4: (0, 0)-(10, 10)
    return bridger, other


def test_a_planned_target_behind_an_earlier_bridge_is_left_to_the_one_by_one_search():
    # the bridge crosses the planned segment (10, 0)-(0, 10) but not (10, 0)-(20, 0)
    bridger, other = spliced_beside([(10.0, 0.0), (11.0, 1.0), (10.0, 1.0)])
    assert bridger.planned(7, other, 0) is None  # (10, 0)-(0, 10) crosses it
    assert bridger.planned(1, other, 0) == (int(bridger.first[1]), 1)
    # a bridge end: neither occurrence holds (10, 0) in its open angle (it lies along 0-1)
    assert bridger.planned(0, other, 0) is None


def test_a_planned_target_at_a_bridge_end_takes_the_occurrence_whose_angle_holds_the_island():
    # the third island's leftmost vertex (2, 4) is nearest to (0, 0), which the bridge to
    # (10, 10) splits into two occurrences: the one between that bridge and the edge up to
    # (0, 10) holds it, and the one-by-one search takes it too
    bridger, third = spliced_beside([(2.0, 4.0), (2.5, 4.5), (3.0, 4.0)])
    assert len(bridger.occurrences(0)) == 2
    expected = bridger.find_bridge(third, 0)
    assert expected is not None and expected[1] == 0
    assert bridger.planned(0, third, 0) == expected


@pytest.mark.parametrize("seed", range(6))
def test_islands_touching_the_shell_and_each_other_get_the_same_bridges(
    seed: int, monkeypatch: pytest.MonkeyPatch
):
    # chains of squares sharing corners, some touching the shell, among free squares
    rng = np.random.default_rng(seed)
    rings = scattered_squares(seed, count=30)
    for k in range(8):
        x, y = 10.0 * k + 2.0, float(rng.integers(10, 90))
        rings.append(square(x, 0.0, 1.0) if k % 3 == 0 else square(x, y, 1.0))
        rings.append(square(x + 1.0, (1.0 if k % 3 == 0 else y + 1.0), 1.0))
    expected = bridged(rings, False, monkeypatch)
    used = count_found(monkeypatch, "planned")
    assert np.array_equal(bridged(rings, True, monkeypatch), expected)
    assert sum(used) > 0


@pytest.mark.parametrize("seed", range(4))
def test_the_earliest_occurrence_is_the_first_in_the_sequence(seed: int) -> None:
    # islands spliced in at random nodes, often right after one just spliced in (nested, as
    # a river's islands chain up): every pair of nodes compares as their sequence positions
    rng = np.random.default_rng(seed)
    shell = np.array([(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)])
    islands = [square(x, y, 0.5) for x, y in rng.uniform(1.0, 98.0, (40, 2))]
    rings = [np.arange(4)] + [np.arange(4 + 4 * k, 8 + 4 * k) for k in range(len(islands))]
    x, y = np.concatenate([shell, *islands]).T
    bridger = bridges._Bridger(x, y, rings)
    for k, island in enumerate(rings[1:]):
        node = bridger.count - 1 if k % 3 else int(rng.integers(0, bridger.count))
        bridger.splice(node, island, 0)
    order = bridger._order()
    # the order walks every node once along the links, from node 0
    assert order[0] == 0 and sorted(order.tolist()) == list(range(bridger.count))
    assert np.array_equal(bridger.nxt[order[:-1]], order[1:]) and bridger.nxt[order[-1]] == 0
    position = np.empty(bridger.count, dtype=np.int64)
    position[order] = np.arange(bridger.count)
    for _ in range(300):
        nodes = rng.choice(bridger.count, size=int(rng.integers(1, 5)), replace=False).tolist()
        assert bridger.earliest(nodes) == min(nodes, key=lambda k: position[k])
