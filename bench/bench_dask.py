"""The engine on a Dask LocalCluster: the 50,000-star set at 1 and 2 worker processes against
the same work in this process.

The stars (bench/generate.py) are written once as GeoParquet (8 row groups) beside their
GeoPackage. Timed, each from a warm start:

- ``triangulate_packed`` alone on the packed stars (what bench_core times);
- the same partition work in this process, without Dask (``run_partition`` on the whole
  layer: WKB reading, z from the DEM, triangulate_packed, GeoParquet triangles and PLY mesh);
- ``triangulate_dataset`` on a LocalCluster of 1 and of 2 worker processes, the file's row
  groups as partitions, and at 2 workers with the Hilbert spatial shuffle too (the cluster's
  start-up is not in these times: it is its own row).

Speed-up is 1 worker's time over 2 workers'; overhead is a cluster run's time over the same
work in this process (the same partitions one after another; one partition of the whole
layer is faster still, as the engine's batches grow). Per-worker throughput (polygons/s of
one worker) is what a scaling plan multiplies.

Usage: python bench/bench_dask.py [--quick] [--count N]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from common import Row, rows_table, timed
from generate import DEFAULT_COUNT, ensure_stars, read_rings

from bsp_triangulate import PackedPolygons, triangulate_packed

QUICK_COUNT = 5_000
ROW_GROUPS = 8
REPEAT = 2  # best of, for each timed run


def stars_parquet(count: int) -> tuple[Path, Path]:
    """The star set as GeoParquet (written once) and its DEM."""
    import geopandas

    gpkg, dem = ensure_stars(count)
    path = gpkg.with_suffix(".parquet")
    if not path.exists() or path.stat().st_mtime < gpkg.stat().st_mtime:
        frame = geopandas.read_file(gpkg, engine="pyogrio")
        partial = path.with_suffix(".partial.parquet")
        frame.to_parquet(partial, row_group_size=-(-len(frame) // ROW_GROUPS))
        partial.rename(path)
    return path, dem


def in_process(path: Path, dem: Path, out_dir: Path) -> tuple[float, float]:
    """Best times of the partition work in this process, without Dask: on the whole layer
    as one partition, and on its row groups one after another."""
    import geopandas

    from bsp_triangulate.distributed.dataset import _attributes
    from bsp_triangulate.distributed.dem import DemInfo
    from bsp_triangulate.distributed.partition import SOURCE_ID, Settings, run_partition

    frame = geopandas.read_parquet(path)
    frame[SOURCE_ID] = np.arange(len(frame))
    for folder in ("triangles", "meshes"):
        (out_dir / folder).mkdir(parents=True, exist_ok=True)
    settings = Settings(
        out_dir=str(out_dir),
        elevation="dem",
        dem=DemInfo.open(str(dem)),
        attributes=_attributes(frame.columns, frame.geometry.name),
    )
    whole, _entry = timed(lambda: run_partition(frame, 0, settings), REPEAT)
    # the cluster's partitions (the row groups), one after another
    step = -(-len(frame) // ROW_GROUPS)
    parts = [frame.iloc[start : start + step] for start in range(0, len(frame), step)]
    in_parts, _entries = timed(
        lambda: [run_partition(part, n, settings) for n, part in enumerate(parts)], REPEAT
    )
    return whole, in_parts


def _peak_rss_mib() -> float:
    """This process's peak resident memory (run on each worker)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def on_cluster(path: Path, dem: Path, out_dir: Path, workers: int) -> tuple[float, dict]:
    """(cluster start-up, {partitioning: (best run time, last summary)}) of
    triangulate_dataset on a LocalCluster of ``workers`` processes, with the file's row
    groups and with Hilbert partitions (2 workers or more), and the workers' peak memory."""
    from distributed import Client, LocalCluster

    from bsp_triangulate.distributed import triangulate_dataset

    start = time.perf_counter()
    cluster = LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    client = Client(cluster)
    client.wait_for_workers(workers)
    started = time.perf_counter() - start
    results = {}
    try:
        for partitioning in ("file", "hilbert") if workers > 1 else ("file",):

            def run(partitioning: str = partitioning) -> dict:
                return triangulate_dataset(
                    path, out_dir, dem=dem, client=client, partitioning=partitioning
                )

            results[partitioning] = timed(run, REPEAT)
        peaks = client.run(_peak_rss_mib)
        results["peak_mib"] = max(peaks.values())
    finally:
        client.close()
        cluster.close()
    return started, results


def run(quick: bool = False, budget: float | None = None, count: int | None = None) -> list[Row]:
    """The rows of this benchmark (``budget`` is not used: every run is bounded)."""
    count = count or (QUICK_COUNT if quick else DEFAULT_COUNT)
    path, dem = stars_parquet(count)
    gpkg, _dem = ensure_stars(count)
    packed = PackedPolygons.of(read_rings(gpkg))
    case = f"{count:,} stars, z from the DEM, PLY + GeoParquet"
    engine, _result = timed(lambda: triangulate_packed(packed, on_error="return"), REPEAT)
    out = Path(tempfile.mkdtemp(prefix="bsptri-bench-dask-"))
    rows = [Row(f"{count:,} stars", "triangulate_packed alone, in process", engine, "s")]
    try:
        whole, local = in_process(path, dem, out / "local")
        rows.append(Row(case, "partition work in process, one partition (no Dask)", whole, "s"))
        rows.append(Row(case, f"the same, {ROW_GROUPS} partitions one after another", local, "s"))
        timings = {}
        for workers in (1, 2):
            started, results = on_cluster(path, dem, out / f"w{workers}", workers)
            rows.append(Row(case, f"LocalCluster start, {workers} worker(s)", started, "s"))
            peak = results.pop("peak_mib")
            rows.append(Row(case, f"peak memory of a worker, {workers} worker(s)", peak, "MiB"))
            for partitioning, (seconds, summary) in results.items():
                label = "row groups" if partitioning == "file" else "Hilbert shuffle"
                timings[workers, partitioning] = seconds
                busy = sum(summary["worker_seconds"].values())
                note = (
                    f"{summary['partitions']} partitions, {summary['triangles']:,} triangles; "
                    f"tasks {busy:.1f} s in all"
                )
                rows.append(Row(case, f"{workers} worker(s), {label}", seconds, "s", note))
        one, two = timings[1, "file"], timings[2, "file"]
        rows += [
            Row(case, "speed-up 2 workers / 1 (row groups)", one / two, "x"),
            Row(case, "overhead 1 worker / in process, same partitions", one / local, "x"),
            Row(case, "2 workers / in process, same partitions", two / local, "x"),
            Row(case, "2 workers / in process, one partition", two / whole, "x"),
            Row(case, "per-worker throughput (1 worker)", count / one, "polygons/s"),
            Row(case, "Hilbert shuffle cost at 2 workers", timings[2, "hilbert"] - two, "s"),
        ]
    finally:
        shutil.rmtree(out, ignore_errors=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5,000 instead of 50,000 polygons")
    parser.add_argument("--count", type=int, help="number of star polygons (overrides --quick)")
    arguments = parser.parse_args()
    print(rows_table(run(arguments.quick, None, arguments.count)))


if __name__ == "__main__":
    main()
