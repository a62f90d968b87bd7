"""End to end through qgis_process: wall time and peak memory of whole algorithm runs.

Each run is one ``qgis_process.bin run`` under ``/usr/bin/time -v`` on the benchmark's star
polygons (GeoPackage) and DEM: QGIS's ``3d:tessellate``, ``bsptriangulate:triangulate`` with
DEM elevation and a mesh (.2dm or .ply alone, in worker processes as by default and in one
process, then with the per-triangle output to memory and to a GeoPackage),
``native:setzfromraster`` and ``native:multiparttosingleparts`` on the tessellated layer (QGIS
writing one feature per triangle) for reference. Times include
qgis_process's start-up (first row). ``3d:tessellate`` and our four mesh-only runs come first,
in three alternated rounds (one with ``--quick``), and each gives its best time; the runs that
write large GeoPackages come after them, once each. Then a layer of building footprints (twice
as many polygons, z from the geometry): ``3d:tessellate`` and our mesh-only runs, alternated,
best of three each. Peak memory adds the peaks of the worker processes to qgis_process's own.

Usage: python bench/bench_end_to_end.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from common import (
    BudgetExceededError,
    Row,
    enable_plugin,
    plugin_dir,
    qgis_environment,
    qgis_process_binary,
    rows_table,
)
from generate import DEFAULT_COUNT, ensure_footprints, ensure_stars

QUICK_COUNT = 5_000
# the building layer: twice as many polygons as the star set (as in bench_core)
FOOTPRINTS_PER_STAR = 2
DEFAULT_BUDGET = 1_800.0  # seconds per run before it is stopped
TIME_BINARY = "/usr/bin/time"
MESH_ONLY_2DM = "bsptriangulate:triangulate DEM -> .2dm only (triangles skipped)"
MESH_ONLY_PLY = "bsptriangulate:triangulate DEM -> .ply only (triangles skipped)"
MESH_ONLY_2DM_ONE = "bsptriangulate:triangulate DEM -> .2dm only, WORKERS=1 (one process)"
MESH_ONLY_PLY_ONE = "bsptriangulate:triangulate DEM -> .ply only, WORKERS=1 (one process)"
SPLIT_TRIANGLES = (
    "native:multiparttosingleparts tessellated -> gpkg (QGIS writing a feature per triangle)"
)
WITH_TRIANGLES = "bsptriangulate:triangulate DEM -> .2dm + triangles gpkg"
STARTUP = "qgis_process start-up (--version)"
TESSELLATE = "3d:tessellate -> gpkg"
# 3d:tessellate and our mesh-only runs: timed in alternated rounds, best of each (the machine
# is shared, and its speed drifts within a minute)
COMPARED = (TESSELLATE, MESH_ONLY_2DM, MESH_ONLY_PLY, MESH_ONLY_2DM_ONE, MESH_ONLY_PLY_ONE)
COMPARED_ROUNDS = 3
COPY_OURS = (
    "native:multiparttosingleparts on our triangles gpkg -> gpkg "
    "(QGIS reading and writing the same triangle features, same fields)"
)


@dataclass
class ProcessRun:
    """Wall time, peak resident memory and JSON results of one qgis_process run; ``peak_mib``
    adds the peaks of the worker processes it started (each process's own peak, so at least
    the peak of all of them at once)."""

    seconds: float
    peak_mib: float
    results: dict
    worker_peaks_mib: list[float]


def _group_peaks(group: int) -> dict[int, tuple[int, float]]:
    """Per process of the process group but its leader: its parent and its peak RSS so far
    (MiB)."""
    peaks = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == group:
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
            if int(fields[2]) != group:
                continue
            with open(f"/proc/{entry}/status") as status:
                for line in status:
                    if line.startswith("VmHWM:"):
                        peaks[int(entry)] = (int(fields[1]), int(line.split()[1]) / 1024)
        except (OSError, ValueError, IndexError):
            continue
    return peaks


class PeakWatcher(threading.Thread):
    """Polls the peak RSS (a high-water mark, so no peak between polls is lost) of every
    process of a process group until stopped."""

    def __init__(self, group: int) -> None:
        super().__init__(daemon=True)
        self.group = group
        self.peaks: dict[int, float] = {}
        self.parents: dict[int, int] = {}
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.wait(0.05):
            for pid, (parent, peak) in _group_peaks(self.group).items():
                self.parents[pid] = parent
                self.peaks[pid] = max(self.peaks.get(pid, 0.0), peak)

    def worker_peaks(self) -> list[float]:
        """The peaks of the processes that GNU time's child (qgis_process) started."""
        return [peak for pid, peak in self.peaks.items() if self.parents.get(pid) != self.group]


def parse_peak_mib(report: str) -> float:
    """'Maximum resident set size (kbytes): N' of GNU time -v, in MiB."""
    match = re.search(r"Maximum resident set size \(kbytes\): (\d+)", report)
    return int(match[1]) / 1024 if match else float("nan")


def run_measured(
    arguments: list[str], environment: dict[str, str], budget: float | None = None
) -> ProcessRun:
    """Run qgis_process under GNU time; raise on failure or when over ``budget`` seconds."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as report:
        command = [TIME_BINARY, "-v", "-o", report.name, qgis_process_binary(), *arguments]
        start = time.perf_counter()
        # own process group: on timeout, qgis_process goes too, not only GNU time
        process = subprocess.Popen(
            command,
            env=environment,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        watcher = PeakWatcher(process.pid)
        watcher.start()
        try:
            stdout, stderr = process.communicate(timeout=budget)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
            raise BudgetExceededError(f"> {budget:.0f} s (stopped)") from None
        finally:
            watcher.done.set()
            watcher.join()
        seconds = time.perf_counter() - start
        # qgis_process's own peak from GNU time (exact); the others are its workers
        peak = parse_peak_mib(Path(report.name).read_text())
        others = watcher.worker_peaks()
    if process.returncode != 0:
        raise RuntimeError(
            f"{' '.join(arguments[:3])} failed ({process.returncode}):\n"
            f"{stdout[-2000:]}\n{stderr[-2000:]}"
        )
    results = {}
    if "--json" in arguments:
        results = json.loads(stdout[stdout.index("{") :]).get("results", {})
    return ProcessRun(seconds, peak + sum(others), results, others)


def algorithm(name: str, **parameters: object) -> list[str]:
    return ["--json", "run", name, *(f"--{key}={value}" for key, value in parameters.items())]


def run(
    quick: bool = False, budget: float | None = DEFAULT_BUDGET, count: int | None = None
) -> list[Row]:
    """Rows of wall time and peak RSS per algorithm run (outputs in a folder removed after)."""
    output = Path(tempfile.mkdtemp(prefix="bsptri-bench-e2e-"))
    count = count or (QUICK_COUNT if quick else DEFAULT_COUNT)
    environment = qgis_environment(plugin_dir())
    enable_plugin(environment)
    try:
        rounds = 1 if quick else COMPARED_ROUNDS
        rows = measure_runs(output, count, budget, environment, rounds)
        footprints = FOOTPRINTS_PER_STAR * count
        return rows + footprint_rows(output, footprints, budget, environment)
    finally:
        shutil.rmtree(output, ignore_errors=True)


def measure_runs(
    output: Path, count: int, budget: float | None, environment: dict[str, str], rounds: int
) -> list[Row]:
    """Rows of wall time and peak RSS per algorithm run on ``count`` stars, outputs written to
    ``output``, qgis_process in ``environment`` (the plugin enabled). The ``COMPARED`` runs go
    in ``rounds`` alternated rounds (each once per round; its best time, its highest peak
    memory), the others once."""
    polygons, dem = ensure_stars(count)
    triangulate = {
        "INPUT": polygons,
        "ELEVATION_SOURCE": 3,
        "DEM": dem,
        "DEM_BAND": 1,
        "APEX_RULE": 0,
        "OUTPUT_MESH": output / "mesh.2dm",
    }
    cases = {
        STARTUP: ["--version"],
        "native:setzfromraster (drape, reference)": algorithm(
            "native:setzfromraster",
            INPUT=polygons,
            RASTER=dem,
            BAND=1,
            OUTPUT=output / "draped.gpkg",
        ),
        TESSELLATE: algorithm("3d:tessellate", INPUT=polygons, OUTPUT=output / "tessellated.gpkg"),
        SPLIT_TRIANGLES: algorithm(
            "native:multiparttosingleparts",
            INPUT=output / "tessellated.gpkg",
            OUTPUT=output / "single_triangles.gpkg",
        ),
        MESH_ONLY_2DM: algorithm("bsptriangulate:triangulate", **triangulate),
        MESH_ONLY_PLY: algorithm(
            "bsptriangulate:triangulate", **{**triangulate, "OUTPUT_MESH": output / "mesh.ply"}
        ),
        MESH_ONLY_PLY_ONE: algorithm(
            "bsptriangulate:triangulate",
            **{**triangulate, "OUTPUT_MESH": output / "mesh.ply"},
            WORKERS=1,
        ),
        MESH_ONLY_2DM_ONE: algorithm("bsptriangulate:triangulate", **triangulate, WORKERS=1),
        "bsptriangulate:triangulate DEM -> .2dm (+ triangles in memory)": algorithm(
            "bsptriangulate:triangulate", **triangulate, OUTPUT_TRIANGLES="TEMPORARY_OUTPUT"
        ),
        WITH_TRIANGLES: algorithm(
            "bsptriangulate:triangulate",
            **triangulate,
            OUTPUT_TRIANGLES=output / "triangles.gpkg",
        ),
        COPY_OURS: algorithm(
            "native:multiparttosingleparts",
            INPUT=output / "triangles.gpkg",
            OUTPUT=output / "triangles_copied.gpkg",
        ),
    }
    case = f"qgis_process, {count:,} stars with 1 island"
    best: dict[str, ProcessRun | str] = {}
    highest: dict[str, float] = {}  # peak memory: the highest of the rounds
    # the compared runs first, in alternated rounds, before the runs that write large
    # GeoPackages (whose write-back to disk would slow whichever run comes next)
    order = [STARTUP, *COMPARED * rounds, *(name for name in cases if name not in COMPARED)]
    for name in order:
        if isinstance(best.get(name), str):
            continue  # failed or stopped in an earlier round
        try:
            measured = run_measured(cases[name], environment, budget)
        except (BudgetExceededError, RuntimeError) as error:
            best[name] = str(error).splitlines()[0]
            continue
        highest[name] = max(highest.get(name, 0.0), measured.peak_mib)
        previous = best.get(name)
        if previous is None or measured.seconds < previous.seconds:
            best[name] = measured
    rows: list[Row] = []
    timings: dict[str, float] = {}
    for name in cases:
        measured = best[name]
        label = f"{name}: wall time"
        if name in COMPARED and rounds > 1:
            label += f" (best of {rounds} alternated rounds)"
        if isinstance(measured, str):
            rows.append(Row(case, label, measured))
            timings[name] = float("nan")
            continue
        timings[name] = measured.seconds
        counts = ", ".join(
            f"{key.lower()} {value:,}"
            for key, value in measured.results.items()
            if key.endswith("_COUNT") and isinstance(value, (int, float))
        )
        rows.append(Row(case, label, measured.seconds, "s", counts))
        workers = measured.worker_peaks_mib
        note = f"with {len(workers)} workers ({', '.join(f'{w:.0f}' for w in workers)} MiB)"
        rows.append(Row(case, f"{name}: peak RSS", highest[name], "MiB", note if workers else ""))
    tessellate = timings[TESSELLATE]
    for name, label in (
        (MESH_ONLY_PLY, "DEM, .ply mesh only"),
        (MESH_ONLY_2DM, "DEM, .2dm mesh only"),
        (MESH_ONLY_PLY_ONE, "DEM, .ply mesh only, one process"),
        (MESH_ONLY_2DM_ONE, "DEM, .2dm mesh only, one process"),
    ):
        rows.append(
            Row(case, f"ours ({label}) / 3d:tessellate wall time", timings[name] / tessellate, "x")
        )
    with_triangles = timings[WITH_TRIANGLES]
    rows.append(
        Row(
            case,
            "ours (DEM, .2dm + triangles gpkg) / 3d:tessellate wall time",
            with_triangles / tessellate,
            "x",
        )
    )
    # what the per-triangle GeoPackage adds to a mesh-only run, against QGIS writing the same
    # number of triangle features (splitting the tessellated multipolygons), start-up excluded
    startup = timings[STARTUP]
    added = with_triangles - timings[MESH_ONLY_2DM]
    qgis_writing = timings[SPLIT_TRIANGLES] - startup
    rows.append(
        Row(
            case,
            "per-triangle gpkg output: added time / QGIS's own writing of as many triangles",
            added / qgis_writing,
            "x",
            f"{added:.1f} s vs {qgis_writing:.1f} s",
        )
    )
    # the same features: our triangle layer's schema (source and tree attributes, areas,
    # angles) costs QGIS more to write than the bare split triangles
    copying = timings[COPY_OURS] - startup
    rows.append(
        Row(
            case,
            "per-triangle gpkg output: added time / QGIS copying the same triangle features",
            added / copying,
            "x",
            f"{added:.1f} s vs {copying:.1f} s",
        )
    )
    return rows


def footprint_rows(
    output: Path, count: int, budget: float | None, environment: dict[str, str]
) -> list[Row]:
    """A building layer (``count`` footprints, z from the geometry): mesh-only runs of ours
    against ``3d:tessellate``, alternated, best of three each."""
    layer = ensure_footprints(count)
    cases = {
        "3d:tessellate -> gpkg": algorithm(
            "3d:tessellate", INPUT=layer, OUTPUT=output / "footprints_tessellated.gpkg"
        ),
        "bsptriangulate:triangulate -> .ply mesh only": algorithm(
            "bsptriangulate:triangulate", INPUT=layer, OUTPUT_MESH=output / "footprints.ply"
        ),
        "bsptriangulate:triangulate -> .2dm mesh only": algorithm(
            "bsptriangulate:triangulate", INPUT=layer, OUTPUT_MESH=output / "footprints.2dm"
        ),
        "bsptriangulate:triangulate -> .ply mesh only, one process": algorithm(
            "bsptriangulate:triangulate",
            INPUT=layer,
            OUTPUT_MESH=output / "footprints.ply",
            WORKERS=1,
        ),
    }
    case = f"qgis_process, {count:,} building footprints (z from the geometry)"
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(3):
        for name, arguments in cases.items():
            best[name] = min(best[name], run_measured(arguments, environment, budget).seconds)
    rows = [
        Row(case, f"{name}: wall time (best of 3)", seconds, "s") for name, seconds in best.items()
    ]
    tessellate = best["3d:tessellate -> gpkg"]
    for name in list(cases)[1:]:
        label = name.split("-> ")[1]
        rows.append(
            Row(case, f"ours ({label}) / 3d:tessellate wall time", best[name] / tessellate, "x")
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5,000 instead of 50,000 polygons")
    parser.add_argument(
        "--budget", type=float, default=DEFAULT_BUDGET, help="seconds per run at most"
    )
    parser.add_argument("--count", type=int, help="number of star polygons (overrides --quick)")
    arguments = parser.parse_args()
    print(rows_table(run(arguments.quick, arguments.budget, arguments.count)))


if __name__ == "__main__":
    main()
