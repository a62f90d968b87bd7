"""Crossing rings as given: a tree that surely loses more area than the repair stops early
(docs/algorithm.md, section 7), with the result the whole tree's comparison would give.

The reference is the same engine with the watch switched off (the whole as-given tree is
built, then compared with the repair); earcut's water fixtures are real crossing rings.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import bsp_triangulate.tree.one_polygon as one_polygon
from bsp_triangulate import triangulate
from bsp_triangulate.triangulation import Triangulation

EARCUT = Path(__file__).resolve().parents[4] / "shared" / "data" / "earcut" / "fixtures"
BOW_TIE_WITH_ISLAND = [
    [(0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)],
    [(1.0, 4.0), (2.0, 4.0), (2.0, 6.0), (1.0, 6.0)],
]


def water(name: str) -> list[np.ndarray]:
    data = json.loads((EARCUT / f"{name}.json").read_text())
    return [np.asarray(ring, dtype=np.float64).reshape(-1, 2) for ring in data if len(ring)]


def fields(result: Triangulation) -> tuple:
    return tuple(
        np.asarray(getattr(result, name)).tolist()
        for name in ("vertices", "triangles", "parent", "depth", "side")
    )


def whole_tree(monkeypatch: pytest.MonkeyPatch, rings: list, rule: str) -> Triangulation:
    with monkeypatch.context() as patch:
        patch.setattr(one_polygon._LossWatch, "reversed", lambda self, *args: None)
        return triangulate(rings, invalid="as_given", rule=rule)


def count_stops(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    stops: list[int] = []
    reversed_ = one_polygon._LossWatch.reversed

    def counting(self, *args) -> None:
        try:
            reversed_(self, *args)
        except one_polygon._RepairWinsError:
            stops.append(1)
            raise

    monkeypatch.setattr(one_polygon._LossWatch, "reversed", counting)
    return stops


@pytest.mark.parametrize(
    ("name", "rule"),
    [("water", "first"), ("water2", "first"), ("water-huge", "first"), ("water2", "elevation")],
)
def test_water_fixture_as_given_stops_its_doomed_tree_with_the_whole_trees_result(
    monkeypatch: pytest.MonkeyPatch, name: str, rule: str
):
    rings = water(name)
    expected = whole_tree(monkeypatch, rings, rule)
    stops = count_stops(monkeypatch)
    assert fields(triangulate(rings, invalid="as_given", rule=rule)) == fields(expected)
    assert stops == [1]


def test_without_shapely_the_whole_as_given_tree_is_output(monkeypatch: pytest.MonkeyPatch):
    rings = water("water2")
    monkeypatch.setattr(one_polygon, "_repaired", lambda *args, **kwargs: None)
    expected = whole_tree(monkeypatch, rings, "first")
    stops = count_stops(monkeypatch)
    assert fields(triangulate(rings, invalid="as_given")) == fields(expected)
    assert stops == []


def test_a_repair_losing_more_than_the_tree_never_stops_it(monkeypatch: pytest.MonkeyPatch):
    rings = water("water2")
    monkeypatch.setattr(one_polygon, "_repaired", lambda *args, **kwargs: None)
    tree = whole_tree(monkeypatch, rings, "first")
    # a "repair" that loses nearly everything: the tree must run to its end and be kept
    empty = Triangulation(vertices=tree.vertices, triangles=tree.triangles[:1])
    monkeypatch.setattr(one_polygon, "_repaired", lambda *args, **kwargs: empty)
    stops = count_stops(monkeypatch)
    assert fields(triangulate(rings, invalid="as_given")) == fields(tree)
    assert stops == []


def test_bow_tie_with_an_island_as_given_gives_the_whole_trees_result(
    monkeypatch: pytest.MonkeyPatch,
):
    expected = whole_tree(monkeypatch, BOW_TIE_WITH_ISLAND, "first")
    assert fields(triangulate(BOW_TIE_WITH_ISLAND, invalid="as_given")) == fields(expected)
