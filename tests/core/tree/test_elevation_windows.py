"""Rule "elevation" on long sub-polygons takes its candidates from shared sorted windows;
the tree is the one of testing every sub-polygon's candidates sorted afresh (field by
field), with distinct elevations, with plateaus of equal ones and with near-ties."""

from __future__ import annotations

import numpy as np
import pytest

import bsp_triangulate.tree.one_polygon as one_polygon
from bsp_triangulate import triangulate


def wavy_shell_with_islands(count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    radius = 100.0 + 12.0 * np.sin(37.0 * t) + rng.uniform(-2.0, 2.0, count)
    shell = np.column_stack([radius * np.cos(t), radius * np.sin(t)])
    islands = []
    for a in np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False):
        cx, cy = 50.0 * np.cos(a), 50.0 * np.sin(a)
        islands.append(np.array([(cx, cy), (cx + 3.0, cy), (cx + 3.0, cy + 3.0), (cx, cy + 3.0)]))
    return [shell, *islands]


def with_z(rings: list[np.ndarray], kind: str) -> list[np.ndarray]:
    out = []
    for ring in rings:
        x, y = ring[:, 0], ring[:, 1]
        z = 300.0 + 40.0 * np.sin(x / 17.0) * np.cos(y / 23.0)
        if kind == "plateaus":
            z = np.round(z / 25.0) * 25.0
        elif kind == "near_ties":
            z = 1000.0 + np.floor(z * 64.0) * 2.0**-42  # neighbours one ulp apart
        out.append(np.column_stack([x, y, z]))
    return out


def fields(rings: list[np.ndarray]) -> tuple:
    result = triangulate(rings, rule="elevation", plane="xy")
    return tuple(
        np.asarray(getattr(result, name)).tolist()
        for name in ("triangles", "parent", "depth", "side")
    )


@pytest.mark.parametrize("kind", ["distinct", "plateaus", "near_ties"])
@pytest.mark.parametrize("seed", [0, 1])
def test_long_sub_polygons_under_rule_elevation_give_the_tree_of_the_full_sort(
    kind: str, seed: int, monkeypatch: pytest.MonkeyPatch
):
    rings = with_z(wavy_shell_with_islands(3000, seed), kind)
    windowed = fields(rings)
    monkeypatch.setattr(one_polygon, "_WINDOWED", 10**9)
    assert windowed == fields(rings)
