"""Rule first, one step at a time: the one-polygon builder builds a whole small tree, and each
sub-polygon it does not hand to the lock-step rounds, with the scalar tests of
``one_by_one.first_nodes``, and leaves the rest to its own step (``_Tree._grow``) where a node
finds no correct candidate (invalid input: fallbacks, errors) or the budget of edge tests is
spent. The results are those of ``_grow`` alone, field by field, errors included."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from bsp_triangulate.tree import one_by_one, one_polygon

from ..engine_equal import engine_or_error, same_result
from ..random_polygons import random_polygon


def _star(count: int, islands: int, seed: int) -> list[np.ndarray]:
    """A star-shaped polygon of ``count`` vertices with small square islands along a circle."""
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0.0, 2.0 * math.pi, count))
    radii = rng.uniform(60.0, 100.0, count)
    rings = [np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])]
    for k in range(islands):
        turn = 2.0 * math.pi * k / max(islands, 1)
        cx, cy = 30.0 * math.cos(turn), 30.0 * math.sin(turn)
        rings.append(
            np.array([(cx - 2, cy - 2), (cx - 2, cy + 2), (cx + 2, cy + 2), (cx + 2, cy - 2)])
        )
    return rings


def _polygons() -> list:
    rnd = random.Random(67)
    polygons: list = [
        random_polygon(rnd, islands=rnd.randint(0, 3), touching=rnd.randint(0, 2))
        for _ in range(40)
    ]
    polygons += [random_polygon(rnd, islands=1, integer=False) for _ in range(10)]
    polygons += [random_polygon(rnd, islands=2, grid=True) for _ in range(10)]
    # invalid: a bow-tie, an island crossing the outer ring, a ring touching itself
    polygons += [
        [np.array([(0.0, 0.0), (4.0, 4.0), (4.0, 0.0), (0.0, 4.0)])],
        [
            np.array([(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]),
            np.array([(2.0, 2.0), (2.0, 12.0), (8.0, 8.0)]),
        ],
        [np.array([(0.0, 0.0), (6.0, 0.0), (3.0, 3.0), (6.0, 6.0), (0.0, 6.0), (3.0, 3.0)])],
    ]
    # larger than the lock-step builder's sub-polygons: a top tree and deferred ones
    polygons += [_star(300 + 50 * seed, seed, seed) for seed in range(4)]
    return polygons


POLYGONS = _polygons()


def _grow_alone(xs, ys, lo, hi, top, at_hi, exact, budget, runs=None):
    """``first_nodes`` that builds nothing: every node is left to ``_grow``."""
    return [], [(lo, hi, top, at_hi, -1, 0, 0)]


@pytest.mark.parametrize("invalid", ["fail", "as_given"])
def test_trees_equal_grow_alone(monkeypatch: pytest.MonkeyPatch, invalid: str) -> None:
    # sub-polygons one step at a time rather than in the lock-step rounds
    monkeypatch.setattr(
        one_polygon, "built_if_worth", lambda requests, _alive=None: [None] * len(requests)
    )
    with monkeypatch.context() as patch:
        patch.setattr(one_polygon, "first_nodes", _grow_alone)
        wanted = [engine_or_error(rings, "first", invalid) for rings in POLYGONS]
    calls = []

    def counted(*args):
        nodes, pending = one_by_one.first_nodes(*args)
        calls.append(bool(pending))
        return nodes, pending

    monkeypatch.setattr(one_polygon, "first_nodes", counted)
    # a budget of one edge scan per position stops mid-tree: _grow takes over from there
    for tests in (256, 1, 0):
        monkeypatch.setattr(one_polygon, "_FIRST_BLOCK_TESTS", tests)
        calls.clear()
        for number, rings in enumerate(POLYGONS):
            assert same_result(engine_or_error(rings, "first", invalid), wanted[number]), (
                tests,
                number,
            )
        assert calls and (any(calls) if tests < 256 else not all(calls))


def test_nodes_and_the_work_left_continue_the_pre_order() -> None:
    """Where a node finds no correct candidate, the nodes found come first in pre-order and
    the open nodes are left with the failing one to be built next."""
    # a bow-tie: the root's base (0, 0) - (4, 4) has no correct apex
    xs = [0.0, 4.0, 4.0, 0.0, 0.0]
    ys = [0.0, 4.0, 0.0, 4.0, 0.0]
    nodes, pending = one_by_one.first_nodes(xs, ys, 1, 4, 3, True, True, 1 << 20)
    assert pending and pending[-1][:2] == (1, 4) and not nodes
    square = [0.0, 1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0, 0.0]
    nodes, pending = one_by_one.first_nodes(*square, 1, 4, 3, True, True, 1 << 20)
    assert not pending and [node[:3] for node in nodes] == [(1, 4, 3), (1, 3, 2)]


def test_a_long_tree_one_step_at_a_time_keeps_the_chain_boxes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A whole tree built one step at a time (here forced: the lock-step attempt fails on
    some invalid input): sub-polygons of more than ``MAX_POSITIONS`` positions stay with
    ``_grow``, whose chain boxes and shadows the scalar tests lack; the result is the same."""
    rings = _star(900, 4, 11)
    want = engine_or_error(rings, "first", "as_given")
    spans = []

    def recorded(xs, ys, lo, hi, *args):
        spans.append(hi - lo)
        return one_by_one.first_nodes(xs, ys, lo, hi, *args)

    monkeypatch.setattr(one_polygon._Tree, "_lockstep_rule", lambda self: None)
    monkeypatch.setattr(one_polygon, "first_nodes", recorded)
    assert same_result(engine_or_error(rings, "first", "as_given"), want)
    assert not spans
