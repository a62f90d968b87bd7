"""Rule first on long sub-polygons skips the candidates in a straight run on from either corner
of the base (``_Tree._straight_runs``: the corner's neighbour lies on their side, condition 3):
the trees are those of the scan without the skip, and a canal with exactly straight banks takes
a few tests per node instead of one per vertex of the bank."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.tree import one_polygon

FIELDS = ("triangles", "parent", "depth", "side")


def _canal(rnd: random.Random, count: int, turn: float, wobble: float = 0.0) -> list:
    """Two straight banks of ``count`` vertices each (spacing at random, on a 1/8 grid so that
    points on a bank are exactly collinear), the whole turned by a multiple of 90 degrees
    (``turn``: 0, 1, 2, 3); ``wobble`` moves every other vertex of the upper bank off its line."""
    xs = np.cumsum([rnd.randint(4, 16) / 8 for _ in range(count)])
    upper_x = np.cumsum([rnd.randint(4, 16) / 8 for _ in range(count)])
    upper_x *= xs[-1] / upper_x[-1]
    upper_x = np.round(upper_x * 8) / 8
    lower = np.column_stack([xs, np.full(count, -1.0)])
    offsets = np.where(np.arange(count) % 2 == 1, wobble, 0.0)
    upper = np.column_stack([upper_x, 1.0 + offsets])[::-1]
    ring = np.concatenate([lower, upper])
    for _ in range(int(turn)):
        ring = np.column_stack([-ring[:, 1], ring[:, 0]])
    return [ring]


def _with_repeats_and_spikes(rings: list) -> list:
    """The ring with a repeated point and a spike (out and back along the bank) in its first
    bank: positions that are not strictly between their neighbours end a run."""
    ring = rings[0]
    spike = ring[40] + (ring[41] - ring[40]) * 0.5
    out = np.concatenate([ring[:20], ring[19:20], ring[20:41], [spike], ring[40:]])
    return [out]


def _plain(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(one_polygon._Tree, "_straight_runs", lambda self, lo, hi: (lo + 1, hi - 1))


CASES = [
    _canal(random.Random(1), 300, 0),
    _canal(random.Random(2), 300, 1),
    _canal(random.Random(3), 300, 2, wobble=0.25),
    _canal(random.Random(4), 300, 3),
    _with_repeats_and_spikes(_canal(random.Random(5), 300, 0)),
]


@pytest.mark.parametrize("rings", CASES, ids=["east", "north", "west-wobbly", "south", "spikes"])
def test_trees_equal_the_scan_of_every_candidate(
    rings: list, monkeypatch: pytest.MonkeyPatch
) -> None:
    skipped = triangulate(rings, invalid="as_given")
    with monkeypatch.context() as patch:
        _plain(patch)
        plain = triangulate(rings, invalid="as_given")
    for name in FIELDS:
        assert np.array_equal(getattr(skipped, name), getattr(plain, name)), name


def test_a_straight_canal_takes_few_tests_per_node(monkeypatch: pytest.MonkeyPatch) -> None:
    """The exact edge tests of the scan on a canal of 2 x 600 vertices: a few per node with
    the runs skipped, about one per vertex of the bank (quadratic) without (the apex seen
    from s_lo, which decides most of these nodes first, left out)."""
    rings = _canal(random.Random(6), 600, 0)
    monkeypatch.setattr(one_polygon, "visible_apex", lambda *args: None)
    blocked = one_polygon._Tree._blocked
    calls = []

    def counted(self, *args):
        calls.append(1)
        return blocked(self, *args)

    monkeypatch.setattr(one_polygon._Tree, "_blocked", counted)
    triangulate(rings)
    with_runs = len(calls)
    calls.clear()
    _plain(monkeypatch)
    triangulate(rings)
    assert with_runs < 4 * 1200 < len(calls)


def _densified_rectangle(count: int, width: float, height: float) -> np.ndarray:
    """A rectangle with ``count`` vertices on each side (exactly collinear: a 1/8 grid)."""
    t = np.arange(count) / count
    sides = [
        np.column_stack([width * t, np.zeros(count)]),
        np.column_stack([np.full(count, width), height * t]),
        np.column_stack([width * (1 - t), np.full(count, height)]),
        np.column_stack([np.zeros(count), height * (1 - t)]),
    ]
    return np.round(np.concatenate(sides) * 8) / 8


def test_the_batch_path_skips_the_runs_with_the_engines_trees(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Densified rectangles, some with a densified hole, through the lock-step builder: the
    trees equal the engine's, and the candidates of the runs take no rounds (a node moves past
    a run at once instead of a few candidates per round)."""
    from bsp_triangulate.tree import lockstep

    from .test_batch_internals import batch_equals_engine

    rnd = random.Random(7)
    polygons = []
    for _ in range(40):
        count = rnd.randint(3, 40)
        outer = _densified_rectangle(count, 8.0 * rnd.randint(8, 40), 8.0 * rnd.randint(8, 40))
        polygons.append([outer])
        hole = _densified_rectangle(max(count // 3, 2), 16.0, 16.0)[::-1] + 24.0
        polygons.append(
            [outer, hole] if outer[:, 0].max() > 48 and outer[:, 1].max() > 48 else [outer]
        )
    rounds = []
    next_state = lockstep._next_state
    monkeypatch.setattr(
        lockstep, "_next_state", lambda *args: rounds.append(1) or next_state(*args)
    )
    monkeypatch.setattr(lockstep, "_ONE_BY_ONE", 0)
    assert batch_equals_engine(polygons) >= 0.9 * len(polygons)
    skipping = len(rounds)
    rounds.clear()
    monkeypatch.setattr(lockstep, "_past_runs", lambda seqs, lo, hi, c: c)
    assert batch_equals_engine(polygons) >= 0.9 * len(polygons)
    assert 2 * skipping < len(rounds)
