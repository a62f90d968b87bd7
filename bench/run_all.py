"""Run every benchmark and print one Markdown report (also written to build/bench/results.md).

Usage: python bench/run_all.py [--quick]
       [--only core,large,end_to_end,fidelity,terrain_run,buildings,dask]
"""

from __future__ import annotations

import argparse
import time
import traceback
from collections.abc import Callable

import bench_buildings
import bench_core
import bench_dask
import bench_end_to_end
import bench_fidelity
import bench_large
import bench_terrain_run
from common import BUILD, Row, machine_info, markdown_table, rows_table

BENCHMARKS: dict[str, tuple[str, Callable[[bool, float, int | None], list[Row]]]] = {
    "core": ("Core triangulation speed (in one process)", bench_core.run),
    "large": ("Large polygons with many islands, every rule, against earcut", bench_large.run),
    "end_to_end": ("End to end through qgis_process", bench_end_to_end.run),
    "fidelity": (
        "Terrain fidelity (surface - DEM at DEM cell centres)",
        bench_fidelity.run,
    ),
    "terrain_run": (
        "The farms with DEM points to 5 m through qgis_process, against without",
        bench_terrain_run.run,
    ),
    "buildings": (
        "Buildings to a GLB against the mesh-only triangulate run",
        lambda quick, budget, count: bench_buildings.run(
            10_000 if quick else bench_buildings.DEFAULT_COUNT, budget=budget
        ),
    ),
    "dask": ("The engine on a Dask LocalCluster of 1 and 2 workers", bench_dask.run),
}


def describe_set(quick: bool, count: int | None) -> str:
    if count:
        return f"{count:,} star polygons"
    return "quick (5,000 polygons, 300 farms)" if quick else "full (50,000 polygons)"


def report(quick: bool, only: list[str], budget: float, count: int | None = None) -> str:
    """Run the chosen benchmarks; a failing one is reported in its section, not fatal."""
    info = machine_info()
    sections = [
        "# BSP Triangulate benchmarks",
        "",
        markdown_table(["machine", ""], info.items()),
        "",
        f"Set: {describe_set(quick, count)}; a measurement is stopped after {budget:.0f} s.",
    ]
    print("\n".join(sections), flush=True)
    for key in only:
        title, run = BENCHMARKS[key]
        print(f"running {key} ...", flush=True)
        start = time.perf_counter()
        try:
            body = rows_table(run(quick, budget, count))
        except Exception:  # one broken benchmark must not hide the others' figures
            body = "Failed:\n\n```\n" + traceback.format_exc(limit=4) + "```"
        elapsed = time.perf_counter() - start
        section = ["", f"## {title}", "", body, "", f"({elapsed:.0f} s to run)"]
        sections += section
        print("\n".join(section), flush=True)  # each table as soon as it is measured
    return "\n".join(sections) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5,000 polygons instead of 50,000")
    parser.add_argument(
        "--only",
        default=",".join(BENCHMARKS),
        help=f"comma-separated subset of {', '.join(BENCHMARKS)}",
    )
    parser.add_argument(
        "--budget", type=float, default=1_800.0, help="seconds per measurement at most"
    )
    parser.add_argument("--count", type=int, help="number of star polygons (overrides --quick)")
    arguments = parser.parse_args()
    only = [name.strip() for name in arguments.only.split(",") if name.strip()]
    unknown = [name for name in only if name not in BENCHMARKS]
    if unknown:
        parser.error(f"unknown benchmark(s): {', '.join(unknown)}")
    text = report(arguments.quick, only, arguments.budget, arguments.count)
    BUILD.mkdir(parents=True, exist_ok=True)
    results = BUILD / "results.md"
    results.write_text(text, encoding="utf-8")
    print(f"\nThe whole report is in {results}")


if __name__ == "__main__":
    main()
