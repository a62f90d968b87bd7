"""DEM points added until the mesh is within a vertical tolerance, against pydelatin.

On the Swellendam farms over the SRTM DEM: every farm's vertices get their z from the DEM,
then ``terrain/refine.py`` adds DEM cell centres inside the farms until |surface - DEM| is
within the tolerance at every cell centre inside. Reported per tolerance and rule: points
added, rounds, time, the largest error measured again independently (shapely's containment,
the final meshes built again), and pydelatin's vertices inside the farms at the same maximum
error over the whole DEM (its greedy Delaunay refinement of a height grid), with the ratio.
pydelatin is for this measurement only (``pip install pydelatin``).

With ``--qgis-process``: the whole layer through ``qgis_process`` (rule delaunay) without
points and with MAX_VERTICAL_ERROR, best of ``--repeat``; the time ratio, POINTS_ADDED against
pydelatin, and the largest |surface - DEM| over every cell centre inside a farm, measured on
the written PLY mesh.

Usage: python bench/bench_refine.py [--tolerances 5 10 2] [--rules delaunay first] [--quick]
       python bench/bench_refine.py --qgis-process [--tolerances 5] [--repeat 1]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import shapely
from bench_fidelity import DEM_PATH, FARMS, QUICK_FARMS, Dem, fidelity, polygon_rings, read_polygons
from bench_fidelity import evaluation_cells as inside_cells

import bsp_triangulate
from bsp_triangulate.terrain.refine import CellGrid, locate_cells, refine_many

_PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4",
              "uint": "<u4", "float": "<f4", "double": "<f8"}  # fmt: skip


def pydelatin_inside(dem: Dem, farms: list[shapely.Polygon], tolerance: float) -> tuple[int, float]:
    """pydelatin's vertices strictly inside the farms at ``tolerance``, and its time (s)."""
    from pydelatin import Delatin

    start = time.perf_counter()
    rows, columns = dem.values.shape
    tin = Delatin(dem.values, height=rows, width=columns, max_error=tolerance)
    seconds = time.perf_counter() - start
    # its vertices are grid positions (column, rows up from the last row): the cells' centres
    x = dem.centre_x(tin.vertices[:, 0])
    y = dem.centre_y(rows - 1 - tin.vertices[:, 1])
    tree = shapely.STRtree(farms)
    hits = tree.query(shapely.points(x, y), predicate="within")
    return len(np.unique(hits[0])), seconds


def run(tolerance: float, rule: str, farms: list, dem: Dem, grid: CellGrid) -> dict:
    polygons = [polygon_rings(farm, dem, None) for farm in farms]
    rounds_seen = []
    start = time.perf_counter()
    results = refine_many(
        polygons,
        [grid] * len(polygons),
        tolerance,
        10_000,
        engine=bsp_triangulate.triangulate_many,
        rule=rule,
        plane="xy",
        progress=lambda round_, active: rounds_seen.append((round_, active)),
    )
    seconds = time.perf_counter() - start
    meshes = bsp_triangulate.triangulate_many(
        polygons, points=[r.points for r in results], rule=rule, plane="xy", on_error="return"
    )
    measured = fidelity(
        [(m.vertices, m.triangles) if hasattr(m, "triangles") else (np.zeros((0, 3)),
          np.zeros((0, 3), np.int64)) for m in meshes],
        inside_cells(farms, dem),
        dem,
    )  # fmt: skip
    return {
        "added": sum(r.added for r in results),
        "rounds": len(rounds_seen),
        "seconds": seconds,
        "reported_max": max((r.max_error for r in results), default=0.0),
        "measured_max": measured.maximum,
        "uncovered": measured.uncovered,
        "not_within": sum(not r.within for r in results),
        "errors": sum(r.error is not None for r in results),
    }


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a binary PLY as ``formats.mesh.write_ply`` writes it."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    lines = data[:end].decode("utf-8").splitlines()
    vertex_count = face_count = 0
    face_fields = [("count", "u1"), ("indices", "<i4", (3,))]
    element = ""
    for line in lines:
        words = line.split()
        if words[:1] == ["element"]:
            element = words[1]
            if element == "vertex":
                vertex_count = int(words[2])
            else:
                face_count = int(words[2])
        elif words[:1] == ["property"] and element == "face" and words[1] != "list":
            face_fields.append((words[2], _PLY_TYPES[words[1]]))
    vertices = np.frombuffer(data, "<f8", vertex_count * 3, end).reshape(-1, 3)
    faces = np.frombuffer(data, np.dtype(face_fields), face_count, end + vertex_count * 24)
    return vertices, faces["indices"].astype(np.int64)


def mesh_error(path: Path, farms: list, dem: Dem) -> float:
    """max |surface - DEM| of the mesh at every cell centre strictly inside a farm."""
    vertices, faces = read_ply(path)
    inside = np.zeros(dem.values.size, bool)
    inside[inside_cells(farms, dem) % dem.values.size] = True
    _triangle, row, col, z = locate_cells(vertices[faces], [dem.grid])
    key = row * dem.values.shape[1] + col
    hit = inside[key]
    covered = np.zeros(dem.values.size, bool)
    covered[key[hit]] = True
    if (inside & ~covered).any():
        raise RuntimeError(f"{int((inside & ~covered).sum())} cells inside a farm are not meshed")
    return float(np.abs(z[hit] - dem.values.ravel()[key[hit]]).max())


def write_layer(polygons: list, path: Path) -> Path:
    """The polygons as a GeoPackage layer in EPSG:32733."""
    from osgeo import ogr, osr

    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32733)
    dataset = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    layer = dataset.CreateLayer("farms", srs, ogr.wkbPolygon)
    for polygon in polygons:
        feature = ogr.Feature(layer.GetLayerDefn())
        feature.SetGeometry(ogr.CreateGeometryFromWkb(shapely.to_wkb(polygon)))
        layer.CreateFeature(feature)
    dataset = None
    return path


def qgis_process_run(layer: Path, tolerance: float, mesh: Path) -> tuple[float, dict]:
    """Seconds and JSON results of one qgis_process run on the farms (rule delaunay)."""
    binary = "qgis_process.bin" if Path("/usr/bin/qgis_process.bin").exists() else "qgis_process"
    arguments = [binary, "--json", "run", "bsptriangulate:triangulate", "--",
                 f"INPUT={layer}", f"DEM={DEM_PATH}", "APEX_RULE=2", f"OUTPUT_MESH={mesh}",
                 f"MAX_VERTICAL_ERROR={tolerance}"]  # fmt: skip
    start = time.perf_counter()
    answer = subprocess.run(arguments, capture_output=True, text=True, check=True)
    seconds = time.perf_counter() - start
    return seconds, json.loads(answer.stdout[answer.stdout.index("{") :])["results"]


def qgis_process_table(tolerances: list[float], repeat: int, limit: int | None) -> None:
    """The farms (the first ``limit`` parts) through qgis_process, without points and with
    each tolerance."""
    if "QGIS_PLUGINPATH" not in os.environ:
        raise SystemExit("set QGIS_PLUGINPATH to a folder holding this tree as bsptriangulate")
    dem = Dem.read(DEM_PATH)
    farms = read_polygons(FARMS, limit=limit)
    folder = Path(tempfile.mkdtemp(prefix="bench-refine-"))
    layer = FARMS if limit is None else write_layer(farms, folder / "farms.gpkg")
    print(f"{len(farms)} farms")
    base = min(qgis_process_run(layer, 0.0, folder / "base.ply")[0] for _ in range(repeat))
    print(f"no points: {base:.1f} s")
    print("| tolerance (m) | time (s) | ratio to no points | POINTS_ADDED | pydelatin inside "
          "| ratio | max error on the mesh (m) | features | failed |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for tolerance in tolerances:
        mesh = folder / f"farms_{tolerance:g}.ply"
        runs = [qgis_process_run(layer, tolerance, mesh) for _ in range(repeat)]
        seconds = min(run_[0] for run_ in runs)
        results = runs[-1][1]
        theirs, _ = pydelatin_inside(dem, farms, tolerance)
        added = int(results["POINTS_ADDED"])
        print(
            f"| {tolerance:g} | {seconds:.1f} | {seconds / base:.1f} | {added:,} | {theirs:,} | "
            f"{added / theirs:.2f} | {mesh_error(mesh, farms, dem):.3f} | "
            f"{results['FEATURE_COUNT']} | {results['FAILED_COUNT']} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerances", type=float, nargs="+", default=[5.0, 10.0, 2.0])
    parser.add_argument("--rules", nargs="+", default=["delaunay", "first", "elevation"])
    parser.add_argument("--quick", action="store_true", help=f"first {QUICK_FARMS} farms only")
    parser.add_argument("--qgis-process", action="store_true", help="the farms via qgis_process")
    parser.add_argument("--repeat", type=int, default=1, help="qgis_process runs, best taken")
    parser.add_argument("--limit", type=int, default=None, help="qgis_process: first N farms")
    arguments = parser.parse_args()
    if arguments.qgis_process:
        qgis_process_table(arguments.tolerances, arguments.repeat, arguments.limit)
        return
    dem = Dem.read(DEM_PATH)
    grid = CellGrid.from_array(dem.values, dem.geotransform)
    farms = read_polygons(FARMS, limit=QUICK_FARMS if arguments.quick else None)
    print(f"{len(farms)} farms, {len(inside_cells(farms, dem)):,} DEM cells inside")
    print("| tolerance (m) | rule | points added | pydelatin inside | ratio | rounds | time (s) "
          "| pydelatin (s) | max error (m) | cells not covered | over tolerance |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for tolerance in arguments.tolerances:
        theirs, their_seconds = pydelatin_inside(dem, farms, tolerance)
        for rule in arguments.rules:
            ours = run(tolerance, rule, farms, dem, grid)
            print(
                f"| {tolerance:g} | {rule} | {ours['added']:,} | {theirs:,} | "
                f"{ours['added'] / max(theirs, 1):.2f} | {ours['rounds']} | "
                f"{ours['seconds']:.1f} | "
                f"{their_seconds:.2f} | {ours['measured_max']:.2f} | {ours['uncovered']} | "
                f"{ours['not_within']} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
