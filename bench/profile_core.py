"""Where the time of triangulate_many goes: cProfile on the first N benchmark polygons.

Usage: python bench/profile_core.py [--count 5000] [--rule first] [--top 25]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats

from common import BUILD
from generate import ensure_stars, read_rings

from bsp_triangulate import triangulate_many


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=5_000, help="polygons to triangulate")
    parser.add_argument("--rule", default="first", choices=("first", "elevation"))
    parser.add_argument("--top", type=int, default=25, help="functions to list")
    arguments = parser.parse_args()
    stars, _ = ensure_stars(max(arguments.count, 5_000))
    polygons = read_rings(stars)[: arguments.count]
    profiler = cProfile.Profile()
    profiler.enable()
    triangulate_many(polygons, rule=arguments.rule)
    profiler.disable()
    output = BUILD / f"profile_{arguments.count}_{arguments.rule}.prof"
    profiler.dump_stats(str(output))
    statistics = pstats.Stats(profiler).strip_dirs()
    statistics.sort_stats("tottime").print_stats(arguments.top)
    statistics.sort_stats("cumulative").print_stats(arguments.top)
    print(f"profile written to {output} (open with python -m pstats)")


if __name__ == "__main__":
    main()
