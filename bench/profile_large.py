"""Where the time of the engine goes on large polygons (earcut water-huge3, generated islands).

Cases: ``water``; ``islands_<vertices>`` (bench/generate.py, cached as a GeoPackage);
``coast_<vertices>`` (the same polygon generated in memory, for sizes not worth caching);
``star_<vertices>`` (the scale run's star ring); ``wavy_<vertices>`` (a wavy shell with one
square island per 100 vertices) and ``river_<islands>`` (a thin shell of 8 vertices per
island).

Times the engine on each case and, with ``--profile``, runs it under cProfile (bridging and
tree building then show up separately). ``--stages`` splits the plain run's time, without a
profiler's overhead, into bridging, the apex search of the large sub-polygons (one Python
step per node), the small sub-polygons built in lock-step, and the rest. ``--save`` stores
the triangulations and ``--check`` compares a run with a saved one field by field (the speed
work must not change results).

Usage: python bench/profile_large.py [--cases water,islands_10000] [--rule first] [--profile]
       [--stages] [--top 25] [--save DIR | --check DIR]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import resource
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np
from bench_core import WATER_HUGE3, earcut_fixture
from common import BUILD
from generate import ensure_islands, polygon_with_islands, read_rings, river_polygon, wavy_polygon
from scale_run import star_ring

from bsp_triangulate import Triangulation, triangulate
from bsp_triangulate.tree import one_polygon

# (label, owner, attribute) of the engine's stages timed by --stages
STAGES = (
    ("bridging", one_polygon, "bridge_islands"),
    ("apex search, large sub-polygons", one_polygon._Tree, "_apex"),
    ("fans, large sub-polygons", one_polygon._Tree, "_fan_apexes"),
    ("lock-step, small sub-polygons", one_polygon, "built_if_worth"),
)

FIELDS = ("vertices", "triangles", "parent", "depth", "side")


def load_case(name: str) -> list[np.ndarray]:
    """Rings of one named case (see the module docstring)."""
    if name == "water":
        return earcut_fixture(WATER_HUGE3)
    kind, _, size = name.partition("_")
    if kind == "islands":
        return read_rings(ensure_islands(int(size)))[0]
    if kind == "coast":
        return polygon_with_islands(int(size))
    if kind == "star":
        return [star_ring(int(size))]
    if kind == "wavy":
        return wavy_polygon(int(size), int(size) // 100)
    if kind == "river":
        return river_polygon(8 * int(size), int(size))
    raise ValueError(f"unknown case {name!r}")


def save(result: Triangulation, path: Path) -> None:
    np.savez(path, **{field: getattr(result, field) for field in FIELDS})


def same(result: Triangulation, path: Path) -> bool:
    """True if ``result`` equals the saved triangulation in every field."""
    saved = np.load(path)
    return all(np.array_equal(getattr(result, field), saved[field]) for field in FIELDS)


@contextmanager
def stage_timers() -> Iterator[dict[str, list[float]]]:
    """Wrap the functions of ``STAGES`` so that each call adds its time and a count to the
    yielded {label: [seconds, calls]} (restored on exit)."""
    totals = {label: [0.0, 0] for label, _, _ in STAGES}
    saved = []
    for label, owner, name in STAGES:
        original = getattr(owner, name)
        saved.append((owner, name, original))

        def timed_call(*args, _original: Callable = original, _label: str = label, **kwargs):
            start = time.perf_counter()
            try:
                return _original(*args, **kwargs)
            finally:
                totals[_label][0] += time.perf_counter() - start
                totals[_label][1] += 1

        setattr(owner, name, timed_call)
    try:
        yield totals
    finally:
        for owner, name, original in saved:
            setattr(owner, name, original)


def print_stages(totals: dict[str, list[float]], seconds: float) -> None:
    rest = seconds - sum(value[0] for value in totals.values())
    for label, (spent, calls) in totals.items():
        print(f"  {label}: {spent:.3f} s ({spent / seconds:.0%}), {calls:,} calls")
    rest_label = "rest (normalisation, touching search, the tree loop, output)"
    print(f"  {rest_label}: {rest:.3f} s ({rest / seconds:.0%})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="water,islands_10000")
    parser.add_argument("--rule", default="first", help="apex rule: first, elevation, delaunay")
    parser.add_argument("--profile", action="store_true", help="run under cProfile")
    parser.add_argument("--stages", action="store_true", help="time the engine's stages")
    parser.add_argument("--top", type=int, default=25, help="functions to list")
    parser.add_argument("--save", type=Path, help="directory to store the results in")
    parser.add_argument("--check", type=Path, help="directory of results to compare with")
    arguments = parser.parse_args()
    for name in arguments.cases.split(","):
        rings = load_case(name)
        vertices = sum(len(ring) for ring in rings)
        profiler = cProfile.Profile() if arguments.profile else None
        with stage_timers() if arguments.stages else nullcontext({}) as totals:
            start, cpu = time.perf_counter(), time.process_time()
            if profiler:
                profiler.enable()
            result = triangulate(rings, rule=arguments.rule)
            if profiler:
                profiler.disable()
            seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(
            f"{name}: {vertices:,} vertices, {len(rings) - 1:,} islands -> "
            f"{len(result):,} triangles in {seconds:.2f} s ({cpu:.2f} s CPU), "
            f"peak {peak:,.0f} MiB so far"
        )
        if totals:
            print_stages(totals, seconds)
        if arguments.save:
            arguments.save.mkdir(parents=True, exist_ok=True)
            save(result, arguments.save / f"{name}.npz")
        if arguments.check:
            reference = arguments.check / f"{name}.npz"
            print(f"  same as {reference}: {same(result, reference)}")
        if profiler:
            output = BUILD / f"profile_large_{name}.prof"
            output.parent.mkdir(parents=True, exist_ok=True)
            profiler.dump_stats(str(output))
            statistics = pstats.Stats(profiler).strip_dirs()
            statistics.sort_stats("tottime").print_stats(arguments.top)
            statistics.sort_stats("cumulative").print_stats(arguments.top)


if __name__ == "__main__":
    main()
