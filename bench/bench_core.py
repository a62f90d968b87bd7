"""Core triangulation speed: ours vs mapbox_earcut vs GEOS constrained Delaunay (shapely 2).

All triangulate the same polygons, read once into numpy rings; only the triangulation call is
timed (each library's input is prepared beforehand). Ours twice: ``triangulate_many`` on
lists of rings, ``triangulate_packed`` on the same polygons packed into flat arrays. On the
sets of many polygons also ours under rule "delaunay" (the constrained Delaunay
triangulation, as GEOS's), with its time over rule "first" and over GEOS.

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
from common import (
    SHARED_DATA,
    BudgetExceededError,
    Row,
    best_rounds,
    rows_table,
    timed,
    within,
)
from generate import (
    DEFAULT_COUNT,
    densified_rectangles,
    ensure_islands,
    ensure_stars,
    footprint_polygons,
    mid_size_polygons,
    read_rings,
)

from bsp_triangulate import PackedPolygons, Triangulation, triangulate_many, triangulate_packed

QUICK_COUNT = 5_000
# building footprints: twice as many polygons as the star set, with far fewer vertices each
FOOTPRINTS_PER_STAR = 2
# polygons of a few hundred vertices: one per 50 stars
STARS_PER_MID_SIZE = 50
STARS_PER_DENSIFIED = 50
# alternated rounds of every library on the star set (the set of the speed target)
STAR_ROUNDS = 3
DEFAULT_BUDGET = 1_800.0  # seconds per measurement before it is abandoned
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
    seconds, results = timed(
        lambda: triangulate_many(polygons, rule=rule, on_error="return"), repeat
    )
    failed = sum(not isinstance(result, Triangulation) for result in results)
    if failed:
        print(f"bsp_triangulate: {failed} of {len(results)} polygons failed")
    return Timing(seconds, sum(len(r) for r in results if isinstance(r, Triangulation)))


def time_ours_packed(polygons: list[Rings], repeat: int = 1) -> Timing:
    """``triangulate_packed``: the polygons packed beforehand, as earcut and GEOS get theirs."""
    packed = PackedPolygons.of(polygons)
    seconds, results = timed(lambda: triangulate_packed(packed, on_error="return"), repeat)
    if results.errors:
        print(f"bsp_triangulate packed: {len(results.errors)} of {len(packed)} polygons failed")
    return Timing(seconds, len(results.triangles))


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


def time_ours_delaunay(polygons: list[Rings], repeat: int = 1) -> Timing:
    return time_ours(polygons, repeat, rule="delaunay")


LIBRARIES: dict[str, Callable[[list[Rings], int], Timing]] = {
    "bsp_triangulate (first)": time_ours,
    "bsp_triangulate packed (first)": time_ours_packed,
    "mapbox_earcut": time_earcut,
    "GEOS constrained Delaunay": time_geos,
}
DELAUNAY = "bsp_triangulate (delaunay)"


def measure(
    run: Callable[[list[Rings], int], Timing],
    polygons: list[Rings],
    repeat: int,
    budget: float | None,
) -> Timing | str:
    """The timing, or why there is none (over budget, failed)."""
    try:
        return within(lambda: run(polygons, repeat), budget)
    except BudgetExceededError:
        return f"> {budget:.0f} s (stopped)"
    except RuntimeError as error:
        return f"failed: {error}"


def compare(
    case: str,
    polygons: list[Rings],
    repeat: int = 1,
    budget: float | None = DEFAULT_BUDGET,
    rounds: int = 1,
    delaunay: bool = False,
) -> list[Row]:
    """Rows with vertices/s of the three libraries and our time ratios to the other two;
    ``delaunay``: ours under rule "delaunay" too, with its ratios to rule "first" and GEOS.

    Each of ``rounds`` rounds measures every library once, in turn, each in its own forked
    process (best of ``repeat`` calls there); a library's time is its best round. On a shared
    machine whose speed drifts by 5-25 % over a minute, alternating gives every library the
    same chances, and the best round of each is the least disturbed one."""
    vertices = vertex_count(polygons)
    libraries = dict(LIBRARIES)
    if delaunay:
        libraries[DELAUNAY] = time_ours_delaunay
    runs = {
        name: lambda run=run: measure(run, polygons, repeat, budget)
        for name, run in libraries.items()
    }
    best = best_rounds(runs, rounds, lambda timing: timing.seconds)
    seconds: dict[str, float] = {}
    rows: list[Row] = []
    for name, timing in best.items():
        if isinstance(timing, str):
            rows.append(Row(case, f"{name}: time", timing))
            seconds[name] = float("nan")
            continue
        seconds[name] = timing.seconds
        note = f"{vertices / timing.seconds:,.0f} vertices/s, {timing.triangles:,} triangles"
        if rounds > 1:
            note += f", best of {rounds} alternated rounds"
        rows.append(Row(case, f"{name}: time", timing.seconds, "s", note))
    for api, label in (("", "ours"), (" packed", "ours packed")):
        ours = seconds[f"bsp_triangulate{api} (first)"]
        rows.append(Row(case, f"{label} / earcut time", ours / seconds["mapbox_earcut"], "x"))
        geos = seconds["GEOS constrained Delaunay"]
        rows.append(Row(case, f"{label} / GEOS time", ours / geos, "x"))
    if delaunay:
        ours = seconds[DELAUNAY]
        first = seconds["bsp_triangulate (first)"]
        rows.append(Row(case, "delaunay / first time", ours / first, "x"))
        geos = seconds["GEOS constrained Delaunay"]
        rows.append(Row(case, "delaunay / GEOS time", ours / geos, "x"))
    return rows


def earcut_fixture(path) -> Rings:
    """An earcut JSON fixture as rings (closing point kept as in the file)."""
    data = json.loads(path.read_text())
    return [np.asarray(ring, dtype=np.float64).reshape(-1, 2) for ring in data if len(ring)]


def scaling_rows(budget: float | None = DEFAULT_BUDGET) -> list[Row]:
    """Time of each library on the 100,000-vertex polygon over its time on the 10,000 one."""
    small = read_rings(ensure_islands(10_000))
    large = read_rings(ensure_islands(100_000))
    case = "1 polygon, 10k -> 100k vertices (100 -> 1,000 islands)"
    rows: list[Row] = []
    for name, run in LIBRARIES.items():
        small_timing = measure(run, small, 3, budget)
        if isinstance(small_timing, str):
            rows.append(Row(case, f"{name}: scaling", "n/a", "", f"10k: {small_timing}"))
            continue
        large_timing = measure(run, large, 1, budget)
        if isinstance(large_timing, str):
            note = f"{small_timing.seconds:.3f} s -> {large_timing}"
            rows.append(Row(case, f"{name}: scaling", "n/a", "", note))
            continue
        note = f"{small_timing.seconds:.3f} s -> {large_timing.seconds:.3f} s"
        if name.startswith("bsp"):
            note += " (target: <= 15x)"
        rows.append(
            Row(case, f"{name}: scaling", large_timing.seconds / small_timing.seconds, "x", note)
        )
    return rows


def run(
    quick: bool = False, budget: float | None = DEFAULT_BUDGET, count: int | None = None
) -> list[Row]:
    """All core benchmarks; ``quick`` uses 5,000 instead of 50,000 star polygons."""
    count = count or (QUICK_COUNT if quick else DEFAULT_COUNT)
    stars_path, _ = ensure_stars(count)
    stars = read_rings(stars_path)
    case = f"{len(stars):,} stars with 1 island ({vertex_count(stars):,} vertices)"
    # best of 2 for every library: a first call in a fresh process also pays for the pages
    # of its new arrays (about 0.35 s of ours on the stars), which later calls reuse; the
    # target set in alternated rounds
    rows = compare(case, stars, 2, budget, rounds=1 if quick else STAR_ROUNDS, delaunay=True)
    footprints = footprint_polygons(FOOTPRINTS_PER_STAR * count)
    courtyards = sum(len(rings) - 1 for rings in footprints)
    footprint_case = (
        f"{len(footprints):,} building footprints, {courtyards:,} with a courtyard "
        f"({vertex_count(footprints):,} vertices)"
    )
    rows += compare(footprint_case, footprints, 2, budget, delaunay=True)
    densified = densified_rectangles(max(count // STARS_PER_DENSIFIED, 1))
    densified_case = (
        f"{len(densified):,} rotated rectangles densified to 240 vertices "
        f"({vertex_count(densified):,} vertices)"
    )
    rows += compare(densified_case, densified, 2, budget, delaunay=True)
    mid_size = mid_size_polygons(max(count // STARS_PER_MID_SIZE, 1))
    mid_case = f"{len(mid_size):,} polygons of 260-600 vertices with 1 island"
    mid_case = f"{mid_case} ({vertex_count(mid_size):,} vertices)"
    rows += compare(mid_case, mid_size, 1, budget, delaunay=True)
    if WATER_HUGE3.exists():
        water = [earcut_fixture(WATER_HUGE3)]
        holes = len(water[0]) - 1
        water_case = f"earcut water-huge3 ({vertex_count(water):,} vertices, {holes} holes)"
        rows += compare(water_case, water, 3, budget)
    rows += scaling_rows(budget)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5,000 instead of 50,000 polygons")
    parser.add_argument(
        "--budget", type=float, default=DEFAULT_BUDGET, help="seconds per measurement at most"
    )
    parser.add_argument("--count", type=int, help="number of star polygons (overrides --quick)")
    arguments = parser.parse_args()
    print(rows_table(run(arguments.quick, arguments.budget, arguments.count)))


if __name__ == "__main__":
    main()
