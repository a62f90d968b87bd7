"""A long call reports its progress as it goes, in every long step (the touching search, the
bridges, the lock-step rounds), whether the polygon runs alone or side by side with others;
a progress callback that raises (a cancelled run) stops the call there."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bsp_triangulate import PackedPolygons, api, triangulate_packed
from bsp_triangulate.tree import engine_many

# the steps that report with no share told (a node's long search under rules elevation and
# delaunay too: see test_a_progress_that_raises_stops_the_call_in_each_long_step)
LONG_STEPS = ("split_touching", "bridge_islands", "build_trees")


def wavy_with_islands(vertices: int = 3000, islands: int = 40) -> list[np.ndarray]:
    """A wavy ring around a grid of small square islands (clockwise), with a z."""
    angles = 2.0 * np.pi * np.arange(vertices) / vertices
    radii = 1000.0 * (1.0 + 0.08 * np.sin(50.0 * angles) + 0.02 * np.sin(977.0 * angles))
    rings = [np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])]
    side = int(np.ceil(np.sqrt(islands)))
    for k in range(islands):
        cx, cy = (k % side - side / 2) * 120.0, (k // side - side / 2) * 120.0
        square = np.array([(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)]) * 20.0
        rings.append(square + np.array([cx, cy]))
    return [np.column_stack([ring, 0.01 * ring[:, 0]]) for ring in rings]


class StopError(Exception):
    """Raised by the progress callback in the step it waits for."""


def names_calling() -> set[str]:
    """The functions on the caller's stack."""
    names = set()
    frame = sys._getframe(1)
    while frame is not None:
        names.add(frame.f_code.co_name)
        frame = frame.f_back
    return names


@pytest.fixture(autouse=True)
def report_every_call(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(api, "_REPORT_SECONDS", 0.0)


@pytest.mark.parametrize("alone", [False, True], ids=["side by side", "alone"])
@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
def test_every_long_step_reports_and_the_shares_only_grow(
    monkeypatch: pytest.MonkeyPatch, alone: bool, rule: str
) -> None:
    if alone:
        monkeypatch.setattr(engine_many, "CHUNK_POINTS", 1000)
    polygons = PackedPolygons.of([wavy_with_islands()])
    shares: list[float] = []
    seen: set[str] = set()

    def progress(share: float) -> None:
        shares.append(share)
        seen.update(names_calling().intersection(LONG_STEPS))

    result = triangulate_packed(polygons, rule=rule, invalid="as_given", progress=progress)
    assert not result.errors and len(result.triangles) == 3000 + 40 * 4 + 2 * 40 - 2
    # rule delaunay's sub-polygons of this polygon are not worth the lock-step rounds
    assert seen == set(LONG_STEPS) - ({"build_trees"} if rule == "delaunay" else set())
    assert shares == sorted(shares) and shares[0] >= 0.0 and shares[-1] <= 1.0


@pytest.mark.parametrize(
    "step, rule",
    [(step, "first") for step in LONG_STEPS]
    + [("_closest_apex_windows", "elevation"), ("_delaunay_apex", "delaunay")],
)
def test_a_progress_that_raises_stops_the_call_in_each_long_step(step: str, rule: str) -> None:
    polygons = PackedPolygons.of([wavy_with_islands()])

    def progress(_share: float) -> None:
        if step in names_calling():
            raise StopError(step)

    with pytest.raises(StopError, match=step):
        triangulate_packed(polygons, rule=rule, invalid="as_given", progress=progress)


def test_several_polygons_side_by_side_report_without_going_back() -> None:
    polygons = PackedPolygons.of([wavy_with_islands(2000 + 100 * k, 20) for k in range(3)])
    shares: list[float] = []
    result = triangulate_packed(polygons, invalid="as_given", progress=shares.append)
    assert not result.errors
    assert len(shares) > 10 and shares == sorted(shares)


EARCUT = Path(__file__).resolve().parents[3] / "shared" / "data" / "earcut" / "fixtures"


@pytest.mark.parametrize("name", ["water", "water-huge2"])
@pytest.mark.parametrize("rule", ["first", "elevation"])
def test_invalid_polygons_as_given_get_the_same_trees_with_progress(name: str, rule: str) -> None:
    # their trees fail in the lock-step rounds and are repaired: every path of a round
    rings = json.loads((EARCUT / f"{name}.json").read_text())
    polygons = PackedPolygons.of([[np.array(ring, dtype=float) for ring in rings]])
    shares: list[float] = []
    runs = [
        triangulate_packed(polygons, rule=rule, invalid="as_given", progress=given)
        for given in (None, shares.append)
    ]
    assert shares == sorted(shares) and len(shares) > 1
    for field in ("vertices", "triangles", "parent", "depth", "side"):
        assert np.array_equal(getattr(runs[0], field), getattr(runs[1], field))


def stars(count: int) -> list[np.ndarray]:
    """Stars of 40 vertices in a row."""
    angles = 2.0 * np.pi * np.arange(40) / 40
    radii = np.where(np.arange(40) % 2 == 0, 10.0, 4.0)[:, None]
    star = np.column_stack([np.cos(angles), np.sin(angles)]) * radii
    return [star + np.array([30.0 * k, 0.0]) for k in range(count)]


def test_the_batch_path_reports_every_round_and_stops_there() -> None:
    polygons = PackedPolygons.of([[star] for star in stars(500)])
    seen: list[set[str]] = []
    result = triangulate_packed(polygons, progress=lambda _s: seen.append(names_calling()))
    assert not result.errors and len(result.triangles) == 500 * 38
    assert sum("batch_pieces" in names and "build_trees" in names for names in seen) > 5

    def progress(_share: float) -> None:
        if "batch_pieces" in names_calling():
            raise StopError("batch")

    with pytest.raises(StopError, match="batch"):
        triangulate_packed(polygons, progress=progress)


def test_a_tree_built_again_does_not_take_the_shares_back() -> None:
    # a self-crossing ring that is not taken as given: its lock-step tree fails and is
    # built again from its root, whose share starts over
    rings = wavy_with_islands(4000, 0)
    rings[0][[100, 140]] = rings[0][[140, 100]]
    polygons = PackedPolygons.of([rings])
    shares: list[float] = []
    result = triangulate_packed(polygons, on_error="return", progress=shares.append)
    assert len(result.errors) == 1
    assert len(shares) > 3 and shares == sorted(shares) and shares[-1] <= 1.0


@pytest.mark.parametrize("kind", [ValueError, TypeError, ArithmeticError])
def test_a_progress_raising_a_value_error_in_the_batch_path_stops_the_call(kind: type) -> None:
    # the batch path's own errors of these kinds leave its polygons to the engine
    polygons = PackedPolygons.of([[star] for star in stars(300)])

    def progress(_share: float) -> None:
        if "batch_pieces" in names_calling():
            raise kind("stop")

    with pytest.raises(kind, match="stop"):
        triangulate_packed(polygons, progress=progress)
