"""Interior points: ``triangulate`` of one farm-sized polygon with 0 to 5,000 points inside.

The polygon is a concave star of 300 vertices (a fixed seed); the points are drawn uniformly
inside it (shapely decides). Ours under rules "first" and "delaunay" against
``mapbox_earcut.triangulate_float64`` with each point as a one-point hole (earcut's Steiner
points), all on the same input in the same run; ratios: ours over earcut, and ours with
points over ours without.

Usage: python bench/bench_points.py [--quick]
"""

from __future__ import annotations

import argparse
import random

import mapbox_earcut
import numpy as np
import shapely
from common import Row, rows_table, timed

from bsp_triangulate import triangulate

VERTICES = 300
POINT_COUNTS = (0, 100, 1_000, 5_000)
QUICK_POINT_COUNTS = (0, 100, 1_000)
REPEAT = 3


def farm_polygon(seed: int = 1) -> np.ndarray:
    """A concave star of :data:`VERTICES` vertices, radii 300 to 500 (metres)."""
    rnd = random.Random(seed)
    angles = np.sort(np.array([rnd.uniform(0.0, 2.0 * np.pi) for _ in range(VERTICES)]))
    radii = np.array([rnd.uniform(300.0, 500.0) for _ in range(VERTICES)])
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


def points_inside(outer: np.ndarray, count: int, seed: int = 2) -> np.ndarray:
    """``count`` points drawn uniformly inside the polygon, (count, 2)."""
    rnd = np.random.default_rng(seed)
    polygon = shapely.Polygon(outer)
    found = np.zeros((0, 2))
    while len(found) < count:
        box = rnd.uniform(-500.0, 500.0, (2 * count, 2))
        inside = shapely.contains_xy(polygon, box[:, 0], box[:, 1])
        found = np.concatenate([found, box[inside]])
    return found[:count]


def earcut_with_steiner(outer: np.ndarray, points: np.ndarray) -> np.ndarray:
    vertices = np.concatenate([outer, points])
    ends = np.concatenate([[len(outer)], len(outer) + np.arange(1, len(points) + 1)])
    return mapbox_earcut.triangulate_float64(vertices, ends.astype(np.uint32))


def run(quick: bool) -> list[Row]:
    outer = farm_polygon()
    rows: list[Row] = []
    alone: dict[str, float] = {}
    for count in QUICK_POINT_COUNTS if quick else POINT_COUNTS:
        points = points_inside(outer, count)
        case = f"{VERTICES} vertices, {count:,} points"
        earcut, _ = timed(lambda points=points: earcut_with_steiner(outer, points), REPEAT)
        rows.append(Row(case, "earcut (Steiner points)", earcut * 1000, "ms"))
        for rule in ("first", "delaunay"):
            seconds, result = timed(
                lambda p=points, r=rule: triangulate([outer], points=p, rule=r), REPEAT
            )
            used = int((result.point_ids >= 0).sum())
            if used != count or len(result.triangles) != VERTICES - 2 + 2 * count:
                raise AssertionError(f"{case}, rule {rule}: {used} points used")
            alone.setdefault(rule, seconds)
            rows.append(Row(case, f"ours, rule {rule}", seconds * 1000, "ms"))
            rows.append(Row(case, f"ours {rule} / earcut", seconds / earcut, "x"))
            rows.append(
                Row(case, f"ours {rule} / ours {rule} without points", seconds / alone[rule], "x")
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="up to 1,000 points")
    arguments = parser.parse_args()
    print(rows_table(run(arguments.quick)))


if __name__ == "__main__":
    main()
