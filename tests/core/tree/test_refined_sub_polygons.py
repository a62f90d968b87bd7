"""A large polygon's lock-step sub-polygons split further before the rounds where they hold few
nodes (``subtrees.worth_refining``, ``one_polygon._Tree._refined``): the same tree, field by
field, as without the split, for valid polygons, for invalid ones as given (a fallback apex in
a sub-polygon being split keeps the plan as it was) and failing."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.tree import one_polygon, subtrees

from ..engine_equal import engine_or_error, same_result
from ..test_large_islands import CASES, _wavy
from .test_engine_many import _crossed, _fixture


def _swapped(rings: list[np.ndarray], k: int, d: int) -> list[np.ndarray]:
    """The rings with shell vertices k and k + d swapped: two edges cross within a stretch of
    the shell that the tree reaches only in sub-polygons of a few hundred positions."""
    shell = rings[0].copy()
    shell[[k, k + d]] = shell[[k + d, k]]
    return [shell, *rings[1:]]


def _polygons() -> list[list[np.ndarray]]:
    polygons = [rings for _, rings in CASES]
    polygons += [_wavy(3000, 30, 1), _wavy(5000, 40, 2), _crossed(_wavy(900, 12, 5))]
    polygons += [_swapped(_wavy(3000, 30, 1), 294, 100), _swapped(_wavy(3000, 30, 1), 682, 150)]
    polygons += [_fixture(name) for name in ("water", "water4", "water-huge", "water-huge3")]
    return polygons


@pytest.mark.parametrize("invalid", ["fail", "as_given"])
def test_split_sub_polygons_give_the_same_trees(
    invalid: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    outcomes: list[str] = []
    original = one_polygon._Tree._refined

    def recorded(self: one_polygon._Tree, rows: object, deferred: list) -> tuple:
        large = any(hi - lo >= subtrees.REFINED_POSITIONS for _, lo, hi, *_ in deferred)
        before = self.used_fallback
        out = original(self, rows, deferred)
        if out[1] is not deferred:
            outcomes.append("split")
        elif large and not before:
            outcomes.append("kept for a fallback")
        return out

    monkeypatch.setattr(one_polygon._Tree, "_refined", recorded)
    polygons = _polygons()
    split = [engine_or_error(rings, "first", invalid) for rings in polygons]
    assert "split" in outcomes
    if invalid == "as_given":
        assert "kept for a fallback" in outcomes
    monkeypatch.setattr(subtrees, "REFINE_NODES", 0)
    outcomes.clear()
    plain = [engine_or_error(rings, "first", invalid) for rings in polygons]
    assert not outcomes
    for number, (got, want) in enumerate(zip(split, plain)):
        assert same_result(got, want), number


def _request(spans: list[tuple[int, int]], rule: str = "first") -> tuple:
    empty = np.zeros(0)
    return (empty, empty, empty, empty, np.array(spans, dtype=np.int64), False, rule)


def test_worth_refining_counts_the_nodes_of_the_larger_sub_polygons() -> None:
    large = subtrees.REFINED_POSITIONS
    few = [(0, large), (500, 600)]  # large - 1 nodes would move
    assert subtrees.worth_refining([_request(few)])
    assert not subtrees.worth_refining([_request(few, "elevation")])
    assert not subtrees.worth_refining([_request([(0, large - 1), (500, 600)])])
    many = [(k * 300, k * 300 + 255) for k in range(subtrees.REFINE_NODES // 254 + 1)]
    assert not subtrees.worth_refining([_request(many)])
    # the requests of one lock-step call count together
    half = many[: len(many) // 2 + 1]
    assert subtrees.worth_refining([_request(half)])
    assert not subtrees.worth_refining([_request(half), _request(half)])
