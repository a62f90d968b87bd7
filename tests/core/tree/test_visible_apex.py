"""Rule first's apex as the vertex visible from s_lo of least angle (``tree/visible_apex.py``,
and ``lockstep._least_angle`` for failing ears in the lock-step rounds): every apex it gives
is the first correct candidate of the plain scan, and the trees are those of the plain scan."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bsp_triangulate import triangulate, triangulate_many
from bsp_triangulate.geometry.spatial_index import ChainBoxes
from bsp_triangulate.tree import lockstep, one_polygon
from bsp_triangulate.tree.one_by_one import first_correct
from bsp_triangulate.tree.visible_apex import WIDE, Sign

from .rivers import river
from .test_shadows import _same


def _star(
    rng: np.random.Generator,
    centre: tuple[float, float],
    count: int,
    radius: float,
    spread: float,
    clockwise: bool = False,
) -> np.ndarray:
    angles = np.linspace(0.0, 2 * np.pi, count, endpoint=False) + rng.uniform(0, 1)
    radii = radius * (1.0 + spread * rng.uniform(-1, 1, count))
    ring = np.column_stack([centre[0] + radii * np.cos(angles), centre[1] + radii * np.sin(angles)])
    return ring[::-1].copy() if clockwise else ring


CASES = [
    # saw-tooth banks (the case that made rule first walk far back), islands near the middle
    river(700, 12, 1, wiggle=0.4, spread=0.2),
    river(900, 20, 2, wiggle=0.4, spread=0.2),
    river(600, 10, 3, grid=2.0, wiggle=0.4, spread=0.2),
    [_star(np.random.default_rng(4), (0.0, 0.0), 3000, 100.0, 0.45)],
]
IDS = ["saw-tooth strip", "saw-tooth strip 2", "saw-tooth strip on a 2 m grid", "radial 3,000"]


@pytest.mark.parametrize("rings", CASES, ids=IDS)
def test_each_visible_apex_is_the_first_correct_candidate(
    monkeypatch: pytest.MonkeyPatch, rings: list[np.ndarray]
) -> None:
    found = {"ear": 0, "beyond": 0}
    real = one_polygon.visible_apex

    def checked(
        xs: list[float], ys: list[float], sign: Sign, boxes: ChainBoxes, lo: int, hi: int
    ) -> int | None:
        apex = real(xs, ys, sign, boxes, lo, hi)
        if apex is not None and apex != WIDE:
            scan = first_correct(xs, ys, lo, hi, hi - 1, sign, [], [math.inf])
            assert apex == scan, (lo, hi)
            ear = sign(xs[hi], ys[hi], xs[lo], ys[lo], xs[hi - 1], ys[hi - 1]) > 0
            found["ear" if ear else "beyond"] += 1
        return apex

    monkeypatch.setattr(one_polygon, "visible_apex", checked)
    for invalid in ("fail", "as_given"):
        triangulate(rings, invalid=invalid)
    assert found["ear"] and (found["beyond"] or len(rings) == 1)


@pytest.mark.parametrize("rings", CASES, ids=IDS)
def test_trees_are_those_of_the_plain_scan(
    monkeypatch: pytest.MonkeyPatch, rings: list[np.ndarray]
) -> None:
    for invalid in ("fail", "as_given"):
        fast = triangulate(rings, invalid=invalid)
        with monkeypatch.context() as patch:
            patch.setattr(one_polygon, "visible_apex", lambda *args: None)
            _same(fast, triangulate(rings, invalid=invalid))


def _spiky_star(count: int, seed: int) -> list[np.ndarray]:
    """A star whose vertices alternate between two radii: the fans across its interior
    make ear triangles that hold much of the chain."""
    rng = np.random.default_rng(seed)
    angles = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
    radii = np.where(np.arange(count) % 2 == 0, 100.0, 30.0) * (
        1 + 0.05 * rng.uniform(-1, 1, count)
    )
    shell = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    return [shell, _star(rng, (0.0, 0.0), 8, 5.0, 0.1, clockwise=True)]


def test_wide_queries_leave_a_polygon_to_the_shadow_walk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where one in 8 of its queries holds more than 256 positions, a tree stops asking for
    the apex seen from s_lo (the shadow walk costs less there); the trees are the same."""
    rings = _spiky_star(4000, 5)
    seen: list[list[int]] = []
    real = one_polygon._Tree._visible_apex_pays

    def watched(self: one_polygon._Tree) -> bool:
        seen.append(self._seen)
        return real(self)

    monkeypatch.setattr(one_polygon._Tree, "_visible_apex_pays", watched)
    fast = triangulate(rings)
    asked, wide = seen[-1]
    assert wide * 8 > asked >= 64
    with monkeypatch.context() as patch:
        patch.setattr(one_polygon, "visible_apex", lambda *args: None)
        _same(fast, triangulate(rings))


def _radial_with_island(seed: int, count: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    shell = _star(rng, (0.0, 0.0), count, 100.0, 0.45)
    return [shell, _star(rng, (0.0, 0.0), 12, 10.0, 0.1, clockwise=True)]


def test_lockstep_least_angle_gives_the_trees_of_the_plain_rounds(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    polygons = [_radial_with_island(seed, 260 + 7 * seed) for seed in range(60)]
    monkeypatch.setattr(lockstep, "_LEAST_FEW", 1)
    used: list[int] = []
    real = lockstep._least_angle

    def counted(*args: object) -> None:
        least = args[-1]
        before = int((least >= 0).sum())
        real(*args)
        used.append(int((least >= 0).sum()) - before)

    monkeypatch.setattr(lockstep, "_least_angle", counted)
    fast = triangulate_many(polygons, invalid="as_given", on_error="return")
    assert sum(used)
    monkeypatch.setattr(lockstep, "_least_angle", lambda *args: None)
    plain = triangulate_many(polygons, invalid="as_given", on_error="return")
    for first, second in zip(fast, plain):
        _same(first, second)


def test_a_crossing_nearly_along_the_base_line_is_not_trusted() -> None:
    """The distance along the base's line where an edge crosses it is rounded by about
    4 eps / sin(angle): an edge within 1e-5 rad of the line gives none (nan), so the nearest
    crossing is never decided by a rounded distance."""
    from bsp_triangulate.tree.visible_apex import _along

    # the line from (0, 0) along (1, 0); an edge crossing it at x = 5, steep, then nearly flat
    steep = _along([4.0, 6.0], [-1.0, 1.0], 0, 1.0, 0.0, 0.0, 0.0, 1.0)
    assert steep == pytest.approx(5.0)
    flat = _along([0.0, 10.0], [-1e-7, 1e-7], 0, 1.0, 0.0, 0.0, 0.0, 1.0)
    assert math.isnan(flat)
