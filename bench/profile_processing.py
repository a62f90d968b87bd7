"""Where the time of ``bsptriangulate:triangulate`` goes: cProfile of one in-process run.

Runs the algorithm with ``processing.run`` on the benchmark's star polygons with DEM
elevation and a .2dm mesh, triangles to memory (default) or to a GeoPackage, and prints the
functions that take the most time, the wall time and the peak resident memory.

With ``--stages`` there is no cProfile: the run's stages (feature reading with the validity
decisions, elevation, the engine, the per-batch mesh arrays, the mesh file: vertex merge and
writer) are timed in CPU and wall seconds instead, and ``--root`` runs the plugin of another
checkout (an earlier commit) in the same way, for before/after tables in one session.

Usage: python bench/profile_processing.py [--count 5000] [--footprints]
       [--gpkg | --mesh-only] [--mesh-format 2dm|ply] [--no-profile | --stages] [--root PATH]
       [--repeat N] [--top 30]
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import importlib
import importlib.util
import os
import pstats
import resource
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from common import BUILD, ROOT
from generate import ensure_footprints, ensure_stars

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("QGIS_CUSTOM_CONFIG_PATH", tempfile.mkdtemp(prefix="bsptri-profile-"))


def load_plugin(root: Path):
    """The plugin package ``bsptriangulate`` from the checkout at ``root``."""
    spec = importlib.util.spec_from_file_location(
        "bsptriangulate", root / "__init__.py", submodule_search_locations=[str(root)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["bsptriangulate"] = module
    spec.loader.exec_module(module)
    return module


def start_qgis(root: Path = ROOT):
    """QgsApplication (offscreen), Processing and the plugin's provider; keep the references."""
    from qgis.core import QgsApplication

    sys.path.insert(0, "/usr/share/qgis/python/plugins")
    application = QgsApplication([], False)
    application.initQgis()
    from processing.core.Processing import Processing

    Processing.initialize()
    package = load_plugin(root)
    provider_module = importlib.import_module(f"{package.__name__}.processing_provider.provider")
    provider = provider_module.BspTriangulateProvider()
    QgsApplication.processingRegistry().addProvider(provider)
    return application, provider


class StageClock:
    """CPU and wall seconds spent in named stages of the algorithm, by wrapping its functions
    (the names exist in every version of the plugin since the Processing provider).

    A stage's CPU time is that of the calling thread (QGIS's own worker threads count in the
    rest).
    """

    def __init__(self) -> None:
        self.cpu: dict[str, float] = defaultdict(float)
        self.wall: dict[str, float] = defaultdict(float)
        self.active: list[str] = []

    def _enter(self, name: str) -> tuple[float, float]:
        self.active.append(name)
        return time.thread_time(), time.perf_counter()

    def _leave(self, name: str, started: tuple[float, float]) -> None:
        cpu = time.thread_time() - started[0]
        wall = time.perf_counter() - started[1]
        self.active.pop()
        self.cpu[name] += cpu
        self.wall[name] += wall
        if self.active:  # an enclosing stage does not count this time again
            self.cpu[self.active[-1]] -= cpu
            self.wall[self.active[-1]] -= wall

    def wrap(self, owner: object, attribute: str, name: str) -> None:
        function = getattr(owner, attribute)
        clock = self

        @functools.wraps(function)
        def timed(*args, **kwargs):
            started = clock._enter(name)
            try:
                return function(*args, **kwargs)
            finally:
                clock._leave(name, started)

        if isinstance(owner, type) and isinstance(owner.__dict__.get(attribute), classmethod):
            function = owner.__dict__[attribute].__func__
            setattr(owner, attribute, classmethod(timed))
        else:
            setattr(owner, attribute, timed)

    def wrap_generator(self, owner: object, attribute: str, name: str) -> None:
        function = getattr(owner, attribute)
        clock = self

        @functools.wraps(function)
        def timed(*args, **kwargs):
            iterator = iter(function(*args, **kwargs))
            while True:
                started = clock._enter(name)
                try:
                    item = next(iterator)
                except StopIteration:
                    return
                finally:
                    clock._leave(name, started)
                yield item

        setattr(owner, attribute, timed)

    def install(self, package: str) -> None:
        algorithm = sys.modules[f"{package}.processing_provider.triangulate_algorithm"]
        elevation = sys.modules[f"{package}.processing_provider.elevation"]
        outputs = sys.modules[f"{package}.processing_provider.outputs"]
        self.wrap_generator(algorithm, "feature_batches", "read features (WKB, validity)")
        for source in ("FlatElevation", "GeometryElevation", "ExpressionElevation"):
            self.wrap(getattr(elevation, source), "apply", "elevation")
        self.wrap(elevation.DemElevation, "apply", "elevation")
        # the engine entry: in engine_runs since the engine runs moved there (packed), in the
        # algorithm's module before (packed, or a list before that)
        runs = sys.modules.get(f"{package}.processing_provider.engine_runs")
        owner = runs if runs is not None and hasattr(runs, "triangulate_packed") else algorithm
        entry = "triangulate_packed" if hasattr(owner, "triangulate_packed") else "triangulate_many"
        self.wrap(owner, entry, "engine (triangulate_many)")
        self.wrap(outputs.BatchMesh, "build", "batch mesh arrays")
        self.wrap(outputs.MeshAccumulator, "add", "batch mesh arrays")
        self.wrap(outputs, "merge_identical_vertices", "mesh: vertex merge")
        self.wrap(outputs, "write_ply", "mesh: writer (mesh.py)")
        self.wrap(outputs, "write_2dm", "mesh: writer (mesh.py)")
        self.wrap(outputs.MeshAccumulator, "stage", "mesh: gather")

    def table(self, total_cpu: float, total_wall: float) -> str:
        names = list(self.cpu)
        rows = [(name, self.cpu[name], self.wall[name]) for name in names]
        rest_cpu = total_cpu - sum(self.cpu.values())
        rows.append(("rest (CPU of all threads outside the stages)", rest_cpu, float("nan")))
        rows.append(("total (processing.run; CPU of all threads)", total_cpu, total_wall))
        width = max(len(name) for name, _cpu, _wall in rows)
        lines = [f"{'stage':<{width}}  {'CPU s':>7}  {'wall s':>7}"]
        lines += [f"{name:<{width}}  {cpu:7.2f}  {wall:7.2f}" for name, cpu, wall in rows]
        return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=5_000, help="star polygons (set size)")
    outputs = parser.add_mutually_exclusive_group()
    outputs.add_argument("--gpkg", action="store_true", help="triangles to a GeoPackage")
    outputs.add_argument("--mesh-only", action="store_true", help="no per-triangle output")
    parser.add_argument("--mesh-format", choices=("2dm", "ply"), default="2dm")
    parser.add_argument(
        "--footprints",
        action="store_true",
        help="the building layer (twice --count footprints, z from the geometry) instead",
    )
    timing = parser.add_mutually_exclusive_group()
    timing.add_argument("--no-profile", action="store_true", help="wall time only")
    timing.add_argument("--stages", action="store_true", help="CPU and wall time per stage")
    parser.add_argument("--root", type=Path, default=ROOT, help="plugin checkout to run")
    parser.add_argument("--repeat", type=int, default=1, help="runs (--stages: the fastest)")
    parser.add_argument("--top", type=int, default=30, help="functions to list")
    arguments = parser.parse_args()
    if arguments.footprints:
        polygons, dem = ensure_footprints(2 * arguments.count), None
    else:
        polygons, dem = ensure_stars(arguments.count)
    application, provider = start_qgis(arguments.root.resolve())
    import processing
    from qgis.core import QgsProcessingContext, QgsProcessingFeedback

    output = Path(tempfile.mkdtemp(prefix="bsptri-profile-out-"))
    parameters = {
        "INPUT": str(polygons),
        "APEX_RULE": 0,
        "OUTPUT_MESH": str(output / f"mesh.{arguments.mesh_format}"),
        "OUTPUT_TRIANGLES": str(output / "triangles.gpkg") if arguments.gpkg else "memory:",
    }
    if dem is not None:
        parameters.update({"ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_BAND": 1})
    if arguments.mesh_only:
        parameters["OUTPUT_TRIANGLES"] = None
    if arguments.stages:
        run_stages(arguments, parameters)
        del provider, application
        return
    context = QgsProcessingContext()
    feedback = QgsProcessingFeedback()
    profiler = None if arguments.no_profile else cProfile.Profile()
    start = time.perf_counter()
    if profiler is not None:
        profiler.enable()
    results = processing.run(
        "bsptriangulate:triangulate", parameters, context=context, feedback=feedback
    )
    if profiler is not None:
        profiler.disable()
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    counts = {key: value for key, value in results.items() if key.endswith("_COUNT")}
    print(f"{arguments.count:,} polygons: {seconds:.1f} s, peak RSS {peak:.0f} MiB, {counts}")
    if profiler is not None:
        suffix = "_gpkg" if arguments.gpkg else "_mesh" if arguments.mesh_only else ""
        name = f"profile_processing_{arguments.count}{suffix}.prof"
        profiler.dump_stats(str(BUILD / name))
        statistics = pstats.Stats(profiler).strip_dirs()
        statistics.sort_stats("tottime").print_stats(arguments.top)
        statistics.sort_stats("cumulative").print_stats(arguments.top)
    del provider, application


def run_stages(arguments: argparse.Namespace, parameters: dict) -> None:
    """The algorithm ``--repeat`` times with stage clocks; prints the fastest run's table."""
    import processing
    from qgis.core import QgsProcessingContext, QgsProcessingFeedback

    clock = StageClock()
    clock.install("bsptriangulate")
    best = None
    for _run in range(arguments.repeat):
        clock.cpu.clear()
        clock.wall.clear()
        cpu, wall = time.process_time(), time.perf_counter()
        processing.run(
            "bsptriangulate:triangulate",
            parameters,
            context=QgsProcessingContext(),
            feedback=QgsProcessingFeedback(),
        )
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        if best is None or cpu < best[0]:
            best = (cpu, wall, dict(clock.cpu), dict(clock.wall))
    cpu, wall, clock.cpu, clock.wall = best
    print(f"{arguments.count:,} polygons, {arguments.root}: {wall:.2f} s wall, {cpu:.2f} s CPU")
    print(clock.table(cpu, wall))


if __name__ == "__main__":
    main()
