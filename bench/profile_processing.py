"""Where the time of ``bsptriangulate:triangulate`` goes: cProfile of one in-process run.

Runs the algorithm with ``processing.run`` on the benchmark's star polygons with DEM
elevation and a .2dm mesh, triangles to memory (default) or to a GeoPackage, and prints the
functions that take the most time, the wall time and the peak resident memory.

Usage: python bench/profile_processing.py [--count 5000] [--gpkg | --mesh-only]
       [--mesh-format 2dm|ply] [--no-profile]
       [--top 30]
"""

from __future__ import annotations

import argparse
import cProfile
import importlib
import os
import pstats
import resource
import sys
import tempfile
import time
from pathlib import Path

from common import BUILD, ROOT
from generate import ensure_stars

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("QGIS_CUSTOM_CONFIG_PATH", tempfile.mkdtemp(prefix="bsptri-profile-"))


def start_qgis():
    """QgsApplication (offscreen), Processing and the plugin's provider; keep the references."""
    from qgis.core import QgsApplication

    sys.path.insert(0, "/usr/share/qgis/python/plugins")
    application = QgsApplication([], False)
    application.initQgis()
    from processing.core.Processing import Processing

    Processing.initialize()
    sys.path.insert(0, str(ROOT))
    from tests.conftest import load_plugin_package

    package = load_plugin_package()
    provider_module = importlib.import_module(f"{package.__name__}.processing_provider.provider")
    provider = provider_module.BspTriangulateProvider()
    QgsApplication.processingRegistry().addProvider(provider)
    return application, provider


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=5_000, help="star polygons (set size)")
    outputs = parser.add_mutually_exclusive_group()
    outputs.add_argument("--gpkg", action="store_true", help="triangles to a GeoPackage")
    outputs.add_argument("--mesh-only", action="store_true", help="no per-triangle output")
    parser.add_argument("--mesh-format", choices=("2dm", "ply"), default="2dm")
    parser.add_argument("--no-profile", action="store_true", help="wall time only")
    parser.add_argument("--top", type=int, default=30, help="functions to list")
    arguments = parser.parse_args()
    polygons, dem = ensure_stars(arguments.count)
    application, provider = start_qgis()
    import processing
    from qgis.core import QgsProcessingContext, QgsProcessingFeedback

    output = Path(tempfile.mkdtemp(prefix="bsptri-profile-out-"))
    parameters = {
        "INPUT": str(polygons),
        "ELEVATION_SOURCE": 3,
        "DEM": str(dem),
        "DEM_BAND": 1,
        "APEX_RULE": 0,
        "OUTPUT_MESH": str(output / f"mesh.{arguments.mesh_format}"),
        "OUTPUT_TRIANGLES": str(output / "triangles.gpkg") if arguments.gpkg else "memory:",
    }
    if arguments.mesh_only:
        parameters["OUTPUT_TRIANGLES"] = None
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


if __name__ == "__main__":
    main()
