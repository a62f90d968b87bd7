"""Small polygons that the batch path leaves to the engine (touching rings, invalid rings),
their sequences prepared as the engine prepares them and their trees built in lock-step
(``tree/prepared_batch.py``): ``triangulate_many`` and ``triangulate_packed`` give exactly
``triangulate``'s results (every field, dtypes included) or its errors, under every rule and
both modes for invalid input; the tests also check that the lock-step trees were taken."""

from __future__ import annotations

import random

import numpy as np
import pytest

from bsp_triangulate import PackedPolygons, triangulate
from bsp_triangulate.api import triangulate_many, triangulate_packed
from bsp_triangulate.tree import prepared_batch
from bsp_triangulate.tree.batch import triangulate_batch

from ..engine_equal import assert_each_as_engine, engine_or_error, same_result
from ..random_polygons import random_polygon, rings_are_disjoint, with_z


def _touching_set(seed: int, count: int, rule: str) -> list:
    """Polygons whose islands touch the outer ring or each other at a vertex, a few
    self-crossing rings (a bow-tie, invalid) and a degenerate one among them."""
    rnd = random.Random(seed)
    polygons = [random_polygon(rnd, islands=rnd.randint(0, 1), touching=2) for _ in range(count)]
    polygons += [[[(0, 0), (10, 10), (10, 0), (0, 10)]], [[(0, 0), (5, 0), (9, 0)]]]
    if rule == "elevation":
        polygons = [with_z(rnd, rings) for rings in polygons]
    return polygons


@pytest.mark.parametrize("invalid", ["fail", "as_given"])
@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
def test_touching_polygons_in_lockstep_equal_the_engine(
    rule: str, invalid: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    polygons = _touching_set(sum(map(ord, rule + invalid)), 70, rule)
    touching = [not rings_are_disjoint(rings) for rings in polygons[:-2]]
    assert sum(touching) >= 40
    # the batch path leaves these to the engine
    left = [r is None for r in triangulate_batch(polygons, rule)]
    assert sum(left) >= 40
    taken = []
    original = prepared_batch.triangulate_prepared

    def counted(*args: object) -> dict:
        done = original(*args)
        taken.append(len(done))
        return done

    monkeypatch.setattr(prepared_batch, "triangulate_prepared", counted)
    many = triangulate_many(polygons, rule=rule, invalid=invalid, on_error="return")
    assert sum(taken) >= 0.8 * sum(left)
    packed = triangulate_packed(
        PackedPolygons.of(polygons), rule=rule, invalid=invalid, on_error="return"
    )
    assert_each_as_engine(polygons, many, packed, rule, invalid)


def test_few_polygons_left_to_the_engine_are_not_batched(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two small touching polygons: too few for the lock-step rounds, the engine builds them."""
    polygons = _touching_set(3, 2, "first")[:2]
    built = []
    monkeypatch.setattr(prepared_batch, "build_trees", lambda *args: built.append(1))
    results = triangulate_many(polygons)
    assert built == []
    for rings, got in zip(polygons, results):
        assert same_result(got, triangulate(rings))


def test_large_polygons_are_bridged_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Large polygons (sequences over ``MAX_POSITIONS``) go to the engine without being
    prepared and bridged here first, and come out as ``triangulate`` gives them."""
    angles = np.linspace(0.0, 2.0 * np.pi, 400, endpoint=False)
    radius = 10.0 + np.where(np.arange(400) % 2, 2.0, 0.0)
    outer = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
    island = [(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)]
    shift = [np.array([30.0 * k, 0.0]) for k in range(3)]
    polygons = [[outer + d, [(x + d[0], y) for x, y in island]] for d in shift]
    small = _touching_set(5, 2, "first")[:2]
    bridged = []
    original = prepared_batch.bridged_sequence

    def counted(rings: object, **options: object) -> object:
        bridged.append(len(rings))
        return original(rings, **options)

    monkeypatch.setattr(prepared_batch, "bridged_sequence", counted)
    results = triangulate_many(polygons + small, on_error="return")
    assert len(bridged) == 2  # the small ones alone
    for rings, got in zip(polygons + small, results):
        assert same_result(got, engine_or_error(rings, "first", "fail"))
