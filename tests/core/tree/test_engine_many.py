"""Large polygons of one call run side by side (``tree/engine_many.py``): their lock-step
subtrees are built in shared calls, and every polygon gets exactly ``triangulate``'s result
(every field, dtypes included) or its error, under every rule and both modes for invalid
input, through ``triangulate_many`` and ``triangulate_packed``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bsp_triangulate import PackedPolygons, TriangulationError
from bsp_triangulate.api import triangulate_many, triangulate_packed
from bsp_triangulate.tree import subtrees
from bsp_triangulate.tree.one_polygon import _Tree

from ..engine_equal import assert_each_as_engine, engine_or_error
from ..test_large_islands import CASES, _lifted, _wavy

EARCUT = Path(__file__).resolve().parents[4] / "shared" / "data" / "earcut" / "fixtures"


def _fixture(name: str) -> list[np.ndarray]:
    rings = json.loads((EARCUT / f"{name}.json").read_text())
    return [np.asarray(ring, dtype=np.float64).reshape(-1, 2) for ring in rings if len(ring)]


def _crossed(rings: list[np.ndarray]) -> list[np.ndarray]:
    """The rings with two vertices of the shell swapped: the shell crosses itself."""
    shell = rings[0].copy()
    shell[[10, 400]] = shell[[400, 10]]
    return [shell, *rings[1:]]


def _polygons(rule: str) -> list[list[np.ndarray]]:
    polygons = [rings for _, rings in CASES]
    polygons += [_crossed(_wavy(900, 12, 5)), _fixture("water4"), _fixture("water")]
    polygons += [_wavy(700 + 20 * seed, 10, seed) for seed in range(12)]
    if rule == "delaunay":  # its lock-step builder takes sub-polygons of long sequences only
        polygons += [_wavy(2400 + 100 * seed, 20, seed) for seed in range(4)]
    return [_lifted(rings) for rings in polygons] if rule == "elevation" else polygons


@pytest.mark.parametrize("invalid", ["fail", "as_given"])
@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
def test_polygons_side_by_side_equal_each_alone(
    rule: str, invalid: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    polygons = _polygons(rule)
    shared = []
    original = subtrees.build_subtrees_many

    def counted(requests: list, alive: object = None) -> list:
        shared.append(len(requests))
        return original(requests, alive)

    monkeypatch.setattr(subtrees, "build_subtrees_many", counted)
    many = triangulate_many(polygons, rule=rule, invalid=invalid, on_error="return")
    assert max(shared) >= 3  # several polygons' subtrees in one call
    packed = triangulate_packed(
        PackedPolygons.of(polygons), rule=rule, invalid=invalid, on_error="return"
    )
    assert_each_as_engine(polygons, many, packed, rule, invalid)
    if invalid == "fail":
        assert isinstance(many[len(CASES)], TriangulationError)  # the crossed shell


def test_the_first_error_in_input_order_is_raised() -> None:
    polygons = [_wavy(800, 10, 7), _crossed(_wavy(900, 12, 5)), _crossed(_wavy(1000, 12, 6))]
    want = engine_or_error(polygons[1], "first", "fail")
    with pytest.raises(TriangulationError) as raised:
        triangulate_many(polygons)
    assert str(raised.value) == str(want)


def test_shared_subtrees_equal_each_request_alone() -> None:
    """``build_subtrees_many`` of the requests of polygons in both orientations of the
    working plane gives each request the subtrees ``build_subtrees`` gives it alone."""
    requests = []
    for _, rings in CASES:
        prepared_tree = _tree(rings)
        steps = prepared_tree.build_steps()
        requests.append(next(steps))
        steps.close()
    assert len({request[5] for request in requests}) == 2  # mirrored and not
    for request, shared in zip(requests, subtrees.build_subtrees_many(requests)):
        alone = subtrees.build_subtrees(*request)
        for name in ("triangles", "parent", "depth", "side", "start", "count", "ok"):
            assert np.array_equal(getattr(shared, name), getattr(alone, name)), name


def _tree(rings: list) -> _Tree:
    from bsp_triangulate.geometry.bridges import split_touching
    from bsp_triangulate.geometry.rings import normalise_rings, prepare
    from bsp_triangulate.rules import get_rule
    from bsp_triangulate.tree.one_polygon import _bridged

    clean, axes = normalise_rings(rings, "auto")
    prepared = prepare(clean, axes)
    ring_ids = split_touching(prepared.x, prepared.y, prepared.rings)
    rule = get_rule("first")
    sequence = _bridged(prepared, ring_ids, prepared.ring_numbers, rule, False, None)
    return _Tree(prepared, sequence, prepared.vertices[:, 2], rule, False, None)
