"""Where few open nodes are left, the lock-step builder builds their subtrees one node at a time
(``one_by_one.first_nodes``, rule first): the trees are the engine's, whether every round,
none or only the last ones go that way, and whether a subtree keeps to its budget of edge
tests or goes back to the rounds."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate.tree import lockstep
from bsp_triangulate.tree.batch import triangulate_batch

from ..random_polygons import random_polygon
from .test_batch_internals import batch_equals_engine, near_collinear_polygon


def _polygons() -> list:
    rnd = random.Random(61)
    rng = np.random.default_rng(62)
    polygons = [
        random_polygon(rnd, islands=rnd.randint(0, 3), touching=rnd.randint(0, 2))
        for _ in range(60)
    ]
    polygons += [random_polygon(rnd, islands=2, grid=True) for _ in range(20)]
    polygons += [random_polygon(rnd, islands=1, integer=False) for _ in range(20)]
    for wobble in (0.0, 1e-15, 1e-9):
        polygons += [
            near_collinear_polygon(rng, int(rng.integers(5, 120)), wobble) for _ in range(8)
        ]
    return polygons


POLYGONS = _polygons()


@pytest.mark.parametrize(
    ("open_nodes", "tests"),
    [(0, 256), (1 << 30, 256), (1 << 30, 1), (1 << 30, 4), (16, 256)],
    ids=["never", "always", "no budget", "small budget", "the last rounds"],
)
def test_trees_equal_the_engines(
    monkeypatch: pytest.MonkeyPatch, open_nodes: int, tests: int
) -> None:
    monkeypatch.setattr(lockstep, "_ONE_BY_ONE", open_nodes)
    monkeypatch.setattr(lockstep, "_ONE_BY_ONE_TESTS", tests)
    if open_nodes > 16:  # every open node, however large its subtree
        monkeypatch.setattr(lockstep, "_ONE_BY_ONE_WORK", 1 << 30)
        monkeypatch.setattr(lockstep, "_ONE_BY_ONE_WORK_PROVEN", 1 << 30)
    assert batch_equals_engine(POLYGONS) >= 0.6 * len(POLYGONS)


def test_a_crossing_polygon_fails_as_in_the_rounds(monkeypatch: pytest.MonkeyPatch) -> None:
    """A bow-tie and a ring crossing its island: no tree, one node at a time or not."""
    bow_tie = [np.array([(0.0, 0.0), (4.0, 4.0), (4.0, 0.0), (0.0, 4.0)])]
    crossing = [
        np.array([(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]),
        np.array([(2.0, 2.0), (2.0, 12.0), (8.0, 8.0)]),
    ]
    square = [np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])]
    results = []
    monkeypatch.setattr(lockstep, "_ONE_BY_ONE_WORK", 1 << 30)
    for open_nodes in (0, 1 << 30):
        monkeypatch.setattr(lockstep, "_ONE_BY_ONE", open_nodes)
        results.append([r is None for r in triangulate_batch([bow_tie, crossing, square], "first")])
    assert results[0] == results[1]
    assert results[0][2] is False


def test_few_large_subtrees_stay_in_the_rounds() -> None:
    """Fifteen convex 255-gons (proven valid): their fans would test about s * s / 2 edges
    each one node at a time, where the rounds take s cheap rounds; the open nodes go one
    node at a time only once their squared spans are small beside the largest."""
    angles = np.linspace(0.0, 2.0 * np.pi, 255, endpoint=False)
    polygons = [
        [np.column_stack([np.cos(angles + k), np.sin(angles + k)]) * 100.0] for k in range(15)
    ]
    spans_seen = []
    few = lockstep._few_positions

    def recorded(seqs, state):
        chosen = few(seqs, state)
        if chosen:
            spans_seen.append(int((state[lockstep._HI] - state[lockstep._LO]).max()))
        return chosen

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(lockstep, "_few_positions", recorded)
        assert all(result is not None for result in triangulate_batch(polygons, "first"))
    assert spans_seen and max(spans_seen) <= 256 // 15 + 1
