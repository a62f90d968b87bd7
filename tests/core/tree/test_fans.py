"""Rule first decides runs of fan nodes in long sub-polygons a batch at a time
(``_Tree._fan_apexes``), each node's apex its base's top's neighbour or a few positions further
back past a pocket: every node it decides is the one-step search's choice, and the trees are
those built one node at a time."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.tree import one_polygon

from ..random_polygons import add_islands, is_valid, rotate_start, star_ring, touching_island
from .rivers import river
from .test_shadows import _same


def _wavy(
    vertices: int, islands: int, seed: int, grid: float = 0.0, ripple: float = 331.0
) -> list[np.ndarray]:
    """A circle whose radius waves, far from the origin, with small rotated squares inside;
    ``grid`` > 0 rounds every coordinate to that step (collinear runs, repeated points);
    ``ripple``: the frequency of the small wave (near half the vertices, a zigzag whose
    every other vertex is a pocket of the fans)."""
    rng = np.random.default_rng(seed)
    angles = 2.0 * np.pi * np.arange(vertices) / vertices
    radius = 300.0 * (1.0 + 0.08 * np.sin(25.0 * angles) + 0.02 * np.sin(ripple * angles))
    centre = np.array([5.0e5, 6.0e6])
    rings = [np.column_stack([radius * np.cos(angles), radius * np.sin(angles)]) + centre]
    square = np.array([(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)])  # clockwise
    for _ in range(islands):
        at = rng.uniform(0, 2 * np.pi)
        distance = rng.uniform(0.0, 200.0)
        turn = rng.uniform(0, np.pi / 2)
        rotation = np.array([[np.cos(turn), np.sin(turn)], [-np.sin(turn), np.cos(turn)]])
        middle = centre + distance * np.array([np.cos(at), np.sin(at)])
        rings.append(square * rng.uniform(2.0, 6.0) @ rotation + middle)
    if grid:
        rings = [np.round(ring / grid) * grid for ring in rings]
    return rings


def _comb(count: int) -> list[np.ndarray]:
    """One vertex seeing a comb of ``count`` vertices around it over nearly a whole turn (its
    fans must be cut into batches that turn by less than a half-turn each)."""
    angles = np.linspace(0.05, 1.95 * math.pi, count)
    radius = 100.0 + 5.0 * (np.arange(count) % 2)
    comb = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
    return [np.concatenate([comb[-1:], [[0.0, 0.0]], comb[:-1]])]


CASES = {
    "comb around one vertex": _comb(1500),
    "wavy": _wavy(3000, 12, 1),
    "wavy on a 0.25 m grid": _wavy(3000, 12, 2, grid=0.25),
    "wavy, dense": _wavy(6000, 4, 3),
    "wavy zigzag": _wavy(3000, 12, 8, ripple=1477.0),
    "wavy zigzag on a 0.25 m grid": _wavy(3000, 12, 7, grid=0.25, ripple=1477.0),
    "river": river(900, 30, 4),
    "river on a 5 m grid": river(900, 30, 5, grid=5.0),
}


def _counted_fan_steps(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The nodes each fan batch call decides, recorded as the calls come."""
    steps: list[int] = []
    fan_apexes = one_polygon._Tree._fan_apexes

    def counting(self: one_polygon._Tree, *args: int) -> list[int]:
        apexes = fan_apexes(self, *args)
        steps.append(len(apexes))
        return apexes

    monkeypatch.setattr(one_polygon._Tree, "_fan_apexes", counting)
    return steps


def _same_as_one_node_at_a_time(monkeypatch: pytest.MonkeyPatch, rings: list) -> None:
    """The trees with fan batches equal those without, in both invalid-polygon modes."""
    for invalid in ("fail", "as_given"):
        batched = triangulate(rings, invalid=invalid)
        with monkeypatch.context() as patch:
            patch.setattr(one_polygon, "_FAN_BATCH", 0)
            _same(batched, triangulate(rings, invalid=invalid))


@pytest.mark.parametrize("name", sorted(CASES))
def test_fan_batches_give_the_trees_of_one_node_at_a_time(
    monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    steps = _counted_fan_steps(monkeypatch)
    _same_as_one_node_at_a_time(monkeypatch, CASES[name])
    assert sum(steps) > 200


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_fan_decision_is_the_one_step_search(
    monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    """Each node of a batch (base (lo, last): last the batch's top, then the node before's
    apex) is decided with the apex the one-step search of that base picks; the zigzags'
    fans skip pockets."""
    checked: list[int] = []
    pockets: list[int] = []
    fan_apexes = one_polygon._Tree._fan_apexes

    def checking(self: one_polygon._Tree, lo: int, top: int, floor: int) -> list[int]:
        apexes = fan_apexes(self, lo, top, floor)
        last = top
        for apex in apexes:
            assert last > floor
            assert self._first_apex(lo, last) == apex, (lo, last, apex)
            checked.append(apex)
            if apex < last - 1:
                pockets.append(last - apex - 1)
            last = apex
        return apexes

    monkeypatch.setattr(one_polygon._Tree, "_fan_apexes", checking)
    triangulate(CASES[name])
    assert len(checked) > 100
    if "zigzag" in name:
        assert len(pockets) > 100


def test_a_pocket_vertex_moved_across_the_fan(monkeypatch: pytest.MonkeyPatch) -> None:
    """A zigzag polygon with one pocket vertex moved off its place (its edges now cross the
    fan's triangles: invalid, as given): a batch stops where a pocket's edge breaks a node's
    triangle, and the trees are those built one node at a time."""
    rings = [ring.copy() for ring in CASES["wavy zigzag"]]
    rings[0][1808] = (499763.99587715894, 5999830.976882643)
    assert not is_valid([[tuple(point) for point in rings[0].tolist()]])
    batched = triangulate(rings, invalid="as_given")
    monkeypatch.setattr(one_polygon, "_FAN_BATCH", 0)
    _same(batched, triangulate(rings, invalid="as_given"))


def test_batches_stop_short_of_a_half_turn(monkeypatch: pytest.MonkeyPatch) -> None:
    """With batches as long as the whole comb, its fan would turn around the centre by more
    than a half-turn: each batch stops before it, and the tree is the same."""
    rings = CASES["comb around one vertex"]
    batched = triangulate(rings)
    monkeypatch.setattr(one_polygon, "_FAN_BATCH", 4096)
    monkeypatch.setattr(one_polygon, "_MAX_FAN_BATCH", 4096)
    turned: list[float] = []
    sectors = one_polygon._Tree._fan_sectors

    def recording(self: one_polygon._Tree, lo: int, positions: list[int], near: float) -> object:
        found = sectors(self, lo, positions, near)
        if found is not None:
            turned.append(found[2][-1])
        return found

    monkeypatch.setattr(one_polygon._Tree, "_fan_sectors", recording)
    _same(batched, triangulate(rings))
    assert max(turned) > 0.9 * math.pi
    assert max(turned) < math.pi


def _random_polygon(seed: int) -> list | None:
    """A valid polygon of 150-400 outer vertices on an integer grid: a random star ring or
    a wavy circle with noise (collinear runs, vertices on chords), a few small islands, some
    touching the shell, a third moved by 1e15 and a third scaled by 2**-30; None where the
    draw gives no valid one."""
    rnd = random.Random(seed)
    count = rnd.randint(150, 400)
    if seed % 2:
        outer = star_ring(rnd, count, radius=rnd.choice((300.0, 3000.0)))
    else:
        radius = rnd.choice((200.0, 2000.0))
        outer = []
        for k in range(count):
            angle = 2.0 * math.pi * k / count
            r = radius * (1.0 + 0.1 * math.sin(7 * angle)) + rnd.uniform(-2.0, 2.0)
            outer.append((float(round(r * math.cos(angle))), float(round(r * math.sin(angle)))))
    if not is_valid([outer]):
        return None
    rings = add_islands(rnd, outer, rnd.randint(0, 5), 10.0) or [outer]
    if rnd.random() < 0.5:
        island = touching_island(rnd, rings, 0)
        if island is not None:
            rings.append(island)
    rings = [rotate_start(rnd, ring) for ring in rings]
    if seed % 3 == 1:  # exact: integers below 2**53
        rings = [[(x + 1e15, y + 1e15) for x, y in ring] for ring in rings]
    elif seed % 3 == 2:  # exact: a power of two
        rings = [[(x * 2.0**-30, y * 2.0**-30) for x, y in ring] for ring in rings]
    return rings


def test_random_polygons_give_the_trees_of_one_node_at_a_time(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    steps = _counted_fan_steps(monkeypatch)
    compared = 0
    for seed in range(60):
        rings = _random_polygon(seed)
        if rings is None:
            continue
        _same_as_one_node_at_a_time(monkeypatch, rings)
        compared += 1
    assert compared > 40
    assert sum(steps) > 1000
