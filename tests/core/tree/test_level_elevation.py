"""Rule "elevation" on level polygons (every vertex at one z, as a lake or a flat roof): all
candidates are equally close, so the rule takes the first correct one, rule first's apex.
Both builders take that shortcut; the trees are the ones of the full search (field by
field), on a long shell with islands, on many small polygons and on a batch that mixes level
and sloping polygons."""

from __future__ import annotations

import numpy as np
import pytest

import bsp_triangulate.tree.batch as batch
import bsp_triangulate.tree.one_polygon as one_polygon
from bsp_triangulate import triangulate, triangulate_many

from .test_elevation_windows import wavy_shell_with_islands

FIELDS = ("triangles", "parent", "depth", "side")


def fields(result) -> tuple:
    return tuple(np.asarray(getattr(result, name)).tolist() for name in FIELDS)


def level(rings: list[np.ndarray], z: float) -> list[np.ndarray]:
    return [np.column_stack([ring[:, :2], np.full(len(ring), z)]) for ring in rings]


def sloping(rings: list[np.ndarray]) -> list[np.ndarray]:
    return [np.column_stack([ring[:, :2], 0.3 * ring[:, 0] - 0.1 * ring[:, 1]]) for ring in rings]


def small_polygons(count: int, seed: int) -> list[list[np.ndarray]]:
    """Concave stars of 12-80 vertices, half of them with a square island."""
    rng = np.random.default_rng(seed)
    polygons = []
    for k in range(count):
        n = int(rng.integers(12, 80))
        t = np.sort(rng.uniform(0.0, 2.0 * np.pi, n))
        radius = rng.uniform(6.0, 10.0, n)
        centre = np.array([30.0 * (k % 40), 30.0 * (k // 40)])
        shell = centre + np.column_stack([radius * np.cos(t), radius * np.sin(t)])
        rings = [shell]
        if k % 2:
            rings.append(centre + np.array([(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)]))
        polygons.append(rings)
    return polygons


@pytest.mark.parametrize("z", [0.0, 12.5, -3.0e5])
def test_level_wavy_shell_with_islands_gives_the_full_search_tree(
    z: float, monkeypatch: pytest.MonkeyPatch
):
    rings = level(wavy_shell_with_islands(1500, 0), z)
    shortcut = triangulate(rings, rule="elevation", plane="xy")
    assert fields(shortcut) == fields(triangulate(rings, rule="first", plane="xy"))
    monkeypatch.setattr(one_polygon._Tree, "_level", lambda self, lo, hi: False)
    assert fields(shortcut) == fields(triangulate(rings, rule="elevation", plane="xy"))


def test_level_and_sloping_small_polygons_batched_give_the_full_search_trees(
    monkeypatch: pytest.MonkeyPatch,
):
    polygons = [
        level(rings, 7.0) if k % 3 else sloping(rings)
        for k, rings in enumerate(small_polygons(400, 1))
    ]
    shortcut = triangulate_many(polygons, rule="elevation", plane="xy")
    monkeypatch.setattr(batch, "_level", lambda flat: np.zeros(len(flat.poly_vcount), bool))
    full = triangulate_many(polygons, rule="elevation", plane="xy")
    assert [fields(r) for r in shortcut] == [fields(r) for r in full]
    one_by_one = [triangulate(rings, rule="elevation", plane="xy") for rings in polygons[:60]]
    assert [fields(r) for r in shortcut[:60]] == [fields(r) for r in one_by_one]


def test_all_level_batch_takes_rule_first_apexes():
    polygons = [level(rings, 2.0) for rings in small_polygons(120, 2)]
    elevation = triangulate_many(polygons, rule="elevation", plane="xy")
    first = triangulate_many(polygons, rule="first", plane="xy")
    assert [fields(r) for r in elevation] == [fields(r) for r in first]


@pytest.mark.parametrize("step", [1.0, 5.0])
def test_terraced_wavy_shell_gives_the_tree_of_testing_every_tie(
    step: float, monkeypatch: pytest.MonkeyPatch
):
    """Elevations in whole steps (as SRTM's metres): once a candidate at one z is correct,
    the later ones at that z are skipped; the tree is the one of testing all of them."""
    rings = [
        np.column_stack([ring, np.round((300.0 + 40.0 * np.sin(ring[:, 0] / 17.0)) / step) * step])
        for ring in wavy_shell_with_islands(1500, 1)
    ]
    skipping = triangulate(rings, rule="elevation", plane="xy")
    monkeypatch.setattr(one_polygon._Tree, "_ties_in_order", property(lambda self: False))
    assert fields(skipping) == fields(triangulate(rings, rule="elevation", plane="xy"))


@pytest.mark.parametrize("step", [1.0, 0.5])
def test_terraced_small_polygons_batched_give_the_one_polygon_builder_trees(step: float):
    """Whole-step elevations put a base's corners on two levels and candidates on both,
    exactly as far from the mean: the lock-step builder takes a correct candidate once every
    one left is farther, at its level, or at the mirrored level after it in candidate order.
    The trees are the one-polygon builder's (which tests candidates its own way)."""
    polygons = [
        [
            np.column_stack([ring, np.round(3.0 * np.sin(ring[:, 0] / 3.0) / step) * step])
            for ring in rings
        ]
        for rings in small_polygons(300, 3)
    ]
    batched = triangulate_many(polygons, rule="elevation", plane="xy")
    one_by_one = [triangulate(rings, rule="elevation", plane="xy") for rings in polygons]
    assert [fields(r) for r in batched] == [fields(r) for r in one_by_one]
