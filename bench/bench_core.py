"""Core triangulation speed: ours vs mapbox_earcut vs GEOS constrained Delaunay (shapely 2).

All three triangulate the same polygons, read once into numpy rings; only the triangulation
call is timed (each library's input is prepared beforehand).

Usage: python bench/bench_core.py [--quick]
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import dataclass

import mapbox_earcut
import numpy as np
import shapely
from common import SHARED_DATA, Row, rows_table, timed
from generate import DEFAULT_COUNT, ensure_islands, ensure_stars, read_rings

from bsp_triangulate import triangulate_many

QUICK_COUNT = 5_000
WATER_HUGE3 = SHARED_DATA / "earcut" / "fixtures" / "water-huge3.json"

Rings = list[np.ndarray]


@dataclass
class Timing:
    """Seconds and total triangle count of one library on one input set."""

    seconds: float
    triangles: int


def earcut_inputs(polygons: list[Rings]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(vertices (n, 2) float64, ring end indices uint32) per polygon, as earcut wants them."""
    inputs = []
    for rings in polygons:
        vertices = np.ascontiguousarray(np.vstack([ring[:, :2] for ring in rings]), np.float64)
        ends = np.cumsum([len(ring) for ring in rings]).astype(np.uint32)
        inputs.append((vertices, ends))
    return inputs


def time_ours(polygons: list[Rings], repeat: int = 1, rule: str = "first") -> Timing:
    seconds, results = timed(lambda: triangulate_many(polygons, rule=rule), repeat)
    return Timing(seconds, sum(len(result) for result in results))


def time_earcut(polygons: list[Rings], repeat: int = 1) -> Timing:
    inputs = earcut_inputs(polygons)
    triangulate = mapbox_earcut.triangulate_float64

    def run() -> list[np.ndarray]:
        return [triangulate(vertices, ends) for vertices, ends in inputs]

    seconds, results = timed(run, repeat)
    return Timing(seconds, sum(len(indices) // 3 for indices in results))


def time_geos(polygons: list[Rings], repeat: int = 1) -> Timing:
    geometries = np.array([shapely.Polygon(rings[0], rings[1:]) for rings in polygons])
    try:
        seconds, results = timed(lambda: shapely.constrained_delaunay_triangles(geometries), repeat)
    except shapely.errors.GEOSException as error:
        print(f"GEOS failed: {error}")
        return Timing(float("nan"), 0)
    return Timing(seconds, int(shapely.get_num_geometries(results).sum()))


def vertex_count(polygons: list[Rings]) -> int:
    return sum(len(ring) for rings in polygons for ring in rings)


def compare(case: str, polygons: list[Rings], repeat: int = 1) -> tuple[list[Row], Timing]:
    """Rows with vertices/s of the three libraries and our time ratios to the other two."""
    vertices = vertex_count(polygons)
    timings: dict[str, Timing] = {}
    runners: dict[str, Callable[[], Timing]] = {
        "bsp_triangulate (first)": lambda: time_ours(polygons, repeat),
        "mapbox_earcut": lambda: time_earcut(polygons, repeat),
        "GEOS constrained Delaunay": lambda: time_geos(polygons, repeat),
    }
    rows: list[Row] = []
    for name, run in runners.items():
        timing = run()
        timings[name] = timing
        rows.append(
            Row(
                case,
                f"{name}: time",
                timing.seconds,
                "s",
                f"{vertices / timing.seconds:,.0f} vertices/s, {timing.triangles:,} triangles",
            )
        )
    ours = timings["bsp_triangulate (first)"].seconds
    rows.append(Row(case, "ours / earcut time", ours / timings["mapbox_earcut"].seconds, "x"))
    rows.append(
        Row(case, "ours / GEOS time", ours / timings["GEOS constrained Delaunay"].seconds, "x")
    )
    return rows, timings["bsp_triangulate (first)"]


def earcut_fixture(path) -> Rings:
    """An earcut JSON fixture as rings (closing point kept as in the file)."""
    data = json.loads(path.read_text())
    return [np.asarray(ring, dtype=np.float64).reshape(-1, 2) for ring in data if len(ring)]


def scaling_rows() -> list[Row]:
    """Time of each library on the 100,000-vertex polygon over its time on the 10,000 one."""
    small = read_rings(ensure_islands(10_000))
    large = read_rings(ensure_islands(100_000))
    rows: list[Row] = []
    for name, run in (
        ("bsp_triangulate (first)", time_ours),
        ("mapbox_earcut", time_earcut),
        ("GEOS constrained Delaunay", time_geos),
    ):
        small_time = run(small, 3).seconds
        large_time = run(large, 1).seconds
        rows.append(
            Row(
                "1 polygon, 10k -> 100k vertices (100 -> 1,000 islands)",
                f"{name}: scaling",
                large_time / small_time,
                "x",
                f"{small_time:.3f} s -> {large_time:.3f} s (target for ours: <= 15x)"
                if name.startswith("bsp")
                else f"{small_time:.3f} s -> {large_time:.3f} s",
            )
        )
    return rows


def run(quick: bool = False) -> list[Row]:
    """All core benchmarks; ``quick`` uses 5,000 instead of 50,000 star polygons."""
    count = QUICK_COUNT if quick else DEFAULT_COUNT
    stars_path, _ = ensure_stars(count)
    stars = read_rings(stars_path)
    case = f"{len(stars):,} stars with 1 island ({vertex_count(stars):,} vertices)"
    rows, _ = compare(case, stars, repeat=2 if quick else 1)
    if WATER_HUGE3.exists():
        water = [earcut_fixture(WATER_HUGE3)]
        water_case = (
            f"earcut water-huge3 ({vertex_count(water):,} vertices, {len(water[0]) - 1} holes)"
        )
        rows += compare(water_case, water, repeat=3)[0]
    rows += scaling_rows()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5,000 instead of 50,000 polygons")
    arguments = parser.parse_args()
    print(rows_table(run(arguments.quick)))


if __name__ == "__main__":
    main()
