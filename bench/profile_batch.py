"""The batch path of triangulate_many against the engine, mapbox_earcut and shapely.

Star polygons as in the benchmark set (20-60 vertices, one island each), generated in memory,
and the Swellendam farms layer. The engine runs on a prefix only (it is slow) and is reported
per vertex; on that prefix every batch result is compared with the engine's.

Usage: python bench/profile_batch.py [--counts 5000 50000] [--engine 300] [--rule first]
       [--profile] [--stages]

``--stages`` prints the CPU seconds of each step of the batch path (ring normalisation,
validity proof, touching search, area check, bridges, and in the tree: per-position tables,
facing and ear tests, blocker tests, vertex tables, the rest being the round bookkeeping).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

import numpy as np
import shapely
from generate import star_polygons

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bsp_triangulate import TriangulationError, triangulate  # noqa: E402
from bsp_triangulate.tree import batch  # noqa: E402
from bsp_triangulate.tree import lockstep as batch_bsp  # noqa: E402
from bsp_triangulate.tree.batch import triangulate_batch  # noqa: E402

FARMS = ROOT.parent / "shared" / "data" / "swellendam" / "farms_33S.shp"
FIELDS = ("vertices", "triangles", "parent", "depth", "side")


def vertex_count(polygons: list) -> int:
    return sum(len(ring) for rings in polygons for ring in rings)


def farms() -> list:
    """Polygons of the farms layer (multipolygon parts separately) as lists of rings."""
    from osgeo import ogr

    source = ogr.Open(str(FARMS))
    layer = source.GetLayer(0)
    polygons = []
    for feature in layer:
        geometry = shapely.from_wkb(bytes(feature.GetGeometryRef().ExportToWkb()))
        for part in getattr(geometry, "geoms", [geometry]):
            rings = [np.asarray(part.exterior.coords)]
            rings += [np.asarray(r.coords) for r in part.interiors]
            polygons.append(rings)
    return polygons


def timed(function):
    """Wall and CPU seconds of one call (the machine may be shared), and its result."""
    start, cpu = time.perf_counter(), time.process_time()
    result = function()
    return time.perf_counter() - start, time.process_time() - cpu, result


def earcut_time(polygons: list) -> float:
    import mapbox_earcut

    prepared = []
    for rings in polygons:
        arrays = [np.asarray(r, dtype=np.float64)[:, :2] for r in rings]
        ends = np.cumsum([len(r) for r in arrays]).astype(np.uint32)
        prepared.append((np.concatenate(arrays), ends))
    start = time.perf_counter()
    for verts, ends in prepared:
        mapbox_earcut.triangulate_float64(verts, ends)
    return time.perf_counter() - start


def shapely_time(polygons: list) -> float:
    geometries = np.array([shapely.Polygon(r[0], r[1:]) for r in polygons], dtype=object)
    start = time.perf_counter()
    shapely.constrained_delaunay_triangles(geometries)
    return time.perf_counter() - start


def compare_with_engine(polygons: list, results: list, rule: str) -> tuple[float, int, int]:
    """Engine time on ``polygons`` and the numbers of batch results compared and different."""
    start = time.perf_counter()
    compared = different = 0
    expected = []
    for rings in polygons:
        try:
            expected.append(triangulate(rings, rule=rule))
        except TriangulationError as exc:
            expected.append(exc)
    elapsed = time.perf_counter() - start
    for mine, theirs in zip(results, expected):
        if mine is None:
            continue
        compared += 1
        if isinstance(theirs, Exception) or not all(
            np.array_equal(getattr(mine, f), getattr(theirs, f)) for f in FIELDS
        ):
            different += 1
    return elapsed, compared, different


# (module, function) pairs timed by --stages, in pipeline order; nested ones count inside
# their caller too
STAGES = (
    (batch, "flatten_rings"),
    (batch, "proven_valid_rings"),
    (batch, "touching_polygons"),
    (batch, "clear_area"),
    (batch, "bridge_sequences"),
    (batch, "build_trees"),
    (batch_bsp.Sequences, "of"),
    (batch_bsp, "_facing"),
    (batch_bsp, "_facing_ear"),
    (batch_bsp, "_strictly_inside"),
    (batch_bsp, "_tables"),
    (batch_bsp, "_bad_rows"),
    (batch_bsp, "_bent_in_triangle"),
)


def stage_times(polygons: list, rule: str) -> tuple[float, dict[str, float]]:
    """CPU seconds of one batch call and of each step in ``STAGES`` within it."""
    seconds: dict[str, float] = {}
    saved = [(owner, name, owner.__dict__[name]) for owner, name in STAGES]

    def timer(name: str, function):
        def wrapped(*args, **kwargs):
            start = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                seconds[name] = seconds.get(name, 0.0) + time.process_time() - start

        return wrapped

    for owner, name, original in saved:
        if isinstance(original, classmethod):
            setattr(owner, name, classmethod(timer(name, original.__func__)))
        else:
            setattr(owner, name, timer(name, original))
    try:
        start = time.process_time()
        triangulate_batch(polygons, rule)
        total = time.process_time() - start
    finally:
        for owner, name, original in saved:
            setattr(owner, name, original)
    return total, seconds


def print_stages(polygons: list, rule: str) -> None:
    total, seconds = stage_times(polygons, rule)
    tree = seconds.get("build_trees", 0.0)
    inner = ("of", "_facing", "_facing_ear", "_strictly_inside", "_tables")
    rows = [(name, seconds.get(name, 0.0)) for _, name in STAGES]
    rows.append(("tree bookkeeping", tree - sum(seconds.get(name, 0.0) for name in inner)))
    rows.append(("other", total - sum(seconds.get(name, 0.0) for _, name in STAGES[:6])))
    print(f"stages (CPU, total {total:.3f} s):")
    for name, value in rows:
        print(f"  {name:20s} {value:8.3f} s  {100.0 * value / total:5.1f} %")


def report(name: str, polygons: list, rule: str, engine_count: int, profile: bool) -> None:
    vertices = vertex_count(polygons)
    if profile:
        profiler = cProfile.Profile()
        profiler.enable()
    batch_s, batch_cpu, results = timed(lambda: triangulate_batch(polygons, rule))
    if profile:
        profiler.disable()
        pstats.Stats(profiler).sort_stats("cumulative").print_stats(25)
    handled = sum(r is not None for r in results)
    print(f"## {name}: {len(polygons)} polygons, {vertices} vertices, rule {rule}")
    print(
        f"batch     {batch_s:8.3f} s  {vertices / batch_s:12,.0f} vertices/s "
        f"(CPU {batch_cpu:.3f} s: {vertices / batch_cpu:,.0f} vertices/s)"
    )
    print(f"handled   {handled} of {len(polygons)} ({100.0 * handled / len(polygons):.1f} %)")
    earcut_s = earcut_time(polygons)
    print(f"earcut    {earcut_s:8.3f} s  {vertices / earcut_s:12,.0f} vertices/s")
    print(f"ratio     batch / earcut = {batch_s / earcut_s:.2f}")
    try:
        shapely_s = shapely_time(polygons)
        print(f"shapely   {shapely_s:8.3f} s  {vertices / shapely_s:12,.0f} vertices/s (CDT)")
    except (AttributeError, shapely.errors.GEOSException) as exc:
        print(f"shapely   not measured: {exc}")
    head = polygons[:engine_count]
    if head:
        engine_s, compared, different = compare_with_engine(head, results[:engine_count], rule)
        head_vertices = vertex_count(head)
        print(
            f"engine    {engine_s:8.3f} s  {head_vertices / engine_s:12,.0f} vertices/s "
            f"(first {len(head)} polygons); batch equal to engine on {compared - different} "
            f"of {compared} compared"
        )
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="*", default=[5_000, 50_000])
    parser.add_argument("--engine", type=int, default=300, help="polygons run by the engine")
    parser.add_argument("--rule", default="first", choices=("first", "elevation", "delaunay"))
    parser.add_argument("--no-farms", action="store_true")
    parser.add_argument("--profile", action="store_true", help="cProfile the batch call")
    parser.add_argument("--stages", action="store_true", help="CPU time per step of the batch")
    arguments = parser.parse_args()
    for count in arguments.counts:
        polygons = star_polygons(count)
        report(f"stars {count}", polygons, arguments.rule, arguments.engine, arguments.profile)
        if arguments.stages:
            print_stages(polygons, arguments.rule)
            print()
    if not arguments.no_farms and FARMS.exists():
        report("Swellendam farms", farms(), arguments.rule, 10**9, arguments.profile)


if __name__ == "__main__":
    main()
