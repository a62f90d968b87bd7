"""Large polygons with many islands: ours (rules first, elevation, delaunay) against
mapbox_earcut, in the same run.

Cases: earcut's water fixtures, the mid-size bench set (concave stars of 260-600 vertices
with an island), random radial polygons of 260-600 vertices (every radius +-45 %), one wavy
polygon of 100,000 vertices with 1,000 square islands, a long thin "river" shell with
3,000 islands of varied size packed close to each other and to the shell, and a layer of 40
wavy polygons of 2,000 vertices with 20 square islands each (too large for the batch path,
their trees run side by side); real data from ../shared/data (``real_data.py``): the ground
around Swellendam's 4,708 buildings, every building an island, its road network 10 m wide
(the blocks between the roads are its islands) and the town's urban areas layer; plus the
growth from the wavy polygon of 10,000 vertices and 100 islands to the one of 100,000 and
1,000.

Ours is ``triangulate_many`` on lists of rings (``invalid="as_given"``, as earcut; z from the
benchmark DEM's height function, so that rule elevation has something to choose by, draped:
``plane="xy"``, as the plugin does for DEM z), earcut
``triangulate_float64`` per polygon; each in its own forked process, best of 2 calls, in 3
alternated rounds (earcut, then each rule), each side's best round counting.

Usage: python bench/bench_large.py [--quick] [--rules first,elevation,delaunay] [--rounds N]
"""

from __future__ import annotations

import argparse
import json

import mapbox_earcut
import numpy as np
from common import (
    SHARED_DATA,
    BudgetExceededError,
    Row,
    best_rounds,
    rows_table,
    timed,
    within,
)
from generate import dem_height, mid_size_polygons, radial_polygons, river_polygon, wavy_polygon
from real_data import ground_around_buildings, road_network, urban_areas

from bsp_triangulate import Triangulation, triangulate_many

RULES = ("first", "elevation", "delaunay")
DEFAULT_BUDGET = 600.0
FIXTURES = SHARED_DATA / "earcut" / "fixtures"
WATER = ("water", "water2", "water3", "water3b", "water4", "water-huge", "water-huge2")
TARGET = 8.0  # ours / earcut at most
GROWTH_TARGET = 12.0  # 10x the vertices and islands: at most this many times the time
# alternated rounds per case (the machine is shared: a side's best round is its least disturbed)
ROUNDS = 3

Rings = list[np.ndarray]


def fixture(name: str) -> Rings:
    data = json.loads((FIXTURES / f"{name}.json").read_text())
    return [np.asarray(ring, dtype=np.float64).reshape(-1, 2) for ring in data if len(ring)]


def with_z(polygons: list[Rings]) -> list[Rings]:
    """The rings with z from the benchmark DEM's height function."""
    return [
        [np.column_stack([ring, dem_height(ring[:, 0], ring[:, 1])]) for ring in rings]
        for rings in polygons
    ]


def cases(quick: bool) -> list[tuple[str, list[Rings]]]:
    """(name, polygons) of every case."""
    found: list[tuple[str, list[Rings]]] = []
    if (FIXTURES / "water-huge3.json").exists():
        found.append(("earcut water-huge3", [fixture("water-huge3")]))
        found.append(("earcut water fixtures (7 others)", [fixture(name) for name in WATER]))
    ground = ground_around_buildings()
    if ground is not None:
        name = f"ground around Swellendam's buildings, {len(ground) - 1:,} islands (real data)"
        found.append((name, [ground]))
    roads = road_network()
    if roads is not None:
        name = f"Swellendam's roads 10 m wide, {len(roads) - 1} blocks as islands (real data)"
        found.append((name, [roads]))
    urban = urban_areas()
    if urban is not None and not quick:
        islands = sum(len(rings) - 1 for rings in urban)
        name = f"Swellendam's urban areas, {len(urban)} polygons, {islands} islands (real data)"
        found.append((name, urban))
    mid = 200 if quick else 1_000
    found.append((f"{mid:,} concave polygons of 260-600 vertices", mid_size_polygons(mid)))
    radial = 60 if quick else 300
    found.append((f"{radial} radial polygons of 260-600 vertices", radial_polygons(radial)))
    wavy = 20_000 if quick else 100_000
    found.append(
        (
            f"wavy polygon, {wavy:,} vertices, {wavy // 100:,} squares",
            [wavy_polygon(wavy, wavy // 100)],
        )
    )
    islands = 600 if quick else 3_000
    found.append(
        (f"river, {islands:,} islands of varied size", [river_polygon(8 * islands, islands)])
    )
    layer = 10 if quick else 40
    found.append(
        (
            f"a layer of {layer} wavy polygons, 2,000 vertices, 20 squares each",
            [wavy_polygon(2_000, 20, seed=seed) for seed in range(layer)],
        )
    )
    return found


def time_ours(polygons: list[Rings], rule: str, repeat: int) -> tuple[float, int, int]:
    """(seconds, triangles, failed polygons) of ``triangulate_many``."""
    seconds, results = timed(
        lambda: triangulate_many(
            polygons, rule=rule, invalid="as_given", plane="xy", on_error="return"
        ),
        repeat,
    )
    good = [r for r in results if isinstance(r, Triangulation)]
    return seconds, sum(len(r) for r in good), len(results) - len(good)


def time_earcut(polygons: list[Rings], repeat: int) -> tuple[float, int, int]:
    inputs = [
        (
            np.ascontiguousarray(np.vstack([ring[:, :2] for ring in rings]), np.float64),
            np.cumsum([len(ring) for ring in rings]).astype(np.uint32),
        )
        for rings in polygons
    ]
    triangulate = mapbox_earcut.triangulate_float64
    seconds, results = timed(lambda: [triangulate(v, e) for v, e in inputs], repeat)
    return seconds, sum(len(indices) // 3 for indices in results), 0


def measure(function, budget: float | None) -> tuple[float, int, int] | str:
    try:
        return within(function, budget)
    except BudgetExceededError:
        return f"> {budget:.0f} s (stopped)"
    except RuntimeError as error:
        return f"failed: {error}"


def compare(
    case: str,
    polygons: list[Rings],
    rules: tuple[str, ...],
    budget: float | None,
    rounds: int = 1,
) -> list[Row]:
    """Earcut and ours under each rule, in ``rounds`` alternated rounds (each measurement in
    its own forked process, best of 2 calls); each side's time is its best round, so that a
    burst of load on the shared machine during one measurement does not decide a ratio."""
    vertices = sum(len(ring) for rings in polygons for ring in rings)
    case = f"{case} ({vertices:,} vertices)"
    lifted = with_z(polygons)
    runs = {"earcut": lambda: measure(lambda: time_earcut(polygons, 2), budget)}
    for rule in rules:
        runs[rule] = lambda rule=rule: measure(lambda: time_ours(lifted, rule, 2), budget)
    best = best_rounds(runs, rounds, lambda timing: timing[0])
    earcut = best["earcut"]
    if isinstance(earcut, str):
        return [Row(case, "mapbox_earcut: time", earcut)]
    of_rounds = f", best of {rounds} alternated rounds" if rounds > 1 else ""
    rows = [Row(case, "mapbox_earcut: time", earcut[0], "s", f"{earcut[1]:,} triangles{of_rounds}")]
    for rule in rules:
        ours = best[rule]
        if isinstance(ours, str):
            rows.append(Row(case, f"ours ({rule}): time", ours))
            continue
        seconds, triangles, failed = ours
        note = f"{triangles:,} triangles" + (f", {failed} failed" if failed else "") + of_rounds
        rows.append(Row(case, f"ours ({rule}): time", seconds, "s", note))
        rows.append(
            Row(case, f"ours ({rule}) / earcut", seconds / earcut[0], "x", f"target <= {TARGET:g}x")
        )
    return rows


def growth_rows(rules: tuple[str, ...], budget: float | None, rounds: int = 1) -> list[Row]:
    """Time on the wavy polygon of 100,000 vertices over the time on the 10,000 one (each
    the best of 2 calls, in ``rounds`` alternated rounds, each side's best round)."""
    small = with_z([wavy_polygon(10_000, 100)])
    large = with_z([wavy_polygon(100_000, 1_000)])
    case = "wavy polygon, 10k -> 100k vertices (100 -> 1,000 squares)"
    rows = []
    for rule in rules:
        runs = {
            "small": lambda rule=rule: measure(lambda: time_ours(small, rule, 2), budget),
            "large": lambda rule=rule: measure(lambda: time_ours(large, rule, 2), budget),
        }
        best = best_rounds(runs, rounds, lambda timing: timing[0])
        first, second = best["small"], best["large"]
        if isinstance(first, str) or isinstance(second, str):
            rows.append(Row(case, f"ours ({rule}): growth", "n/a", "", f"{first} -> {second}"))
            continue
        note = f"{first[0]:.3f} s -> {second[0]:.3f} s (target <= {GROWTH_TARGET:g}x)"
        rows.append(Row(case, f"ours ({rule}): growth", second[0] / first[0], "x", note))
    return rows


def run(
    quick: bool = False,
    budget: float | None = DEFAULT_BUDGET,
    count: int | None = None,
    rules: tuple[str, ...] = RULES,
    rounds: int | None = None,
) -> list[Row]:
    """Every case, every rule, against earcut (``rounds`` alternated rounds, by default
    ``ROUNDS``, one with ``quick``); ``count`` is ignored (run_all's signature)."""
    rounds = rounds or (1 if quick else ROUNDS)
    rows: list[Row] = []
    for case, polygons in cases(quick):
        case_rows = compare(case, polygons, rules, budget, rounds)
        print(rows_table(case_rows), flush=True)
        rows += case_rows
    if not quick:
        rows += growth_rows(rules, budget, rounds)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller cases")
    parser.add_argument("--rules", default=",".join(RULES))
    parser.add_argument("--budget", type=float, default=DEFAULT_BUDGET)
    parser.add_argument("--rounds", type=int, help=f"alternated rounds ({ROUNDS}; --quick 1)")
    arguments = parser.parse_args()
    rules = tuple(rule.strip() for rule in arguments.rules.split(",") if rule.strip())
    print(rows_table(run(arguments.quick, arguments.budget, rules=rules, rounds=arguments.rounds)))


if __name__ == "__main__":
    main()
