"""DEM points added until the mesh is within a vertical tolerance, against pydelatin.

On the Swellendam farms over the SRTM DEM: every farm's vertices get their z from the DEM,
then ``terrain/refine.py`` adds DEM cell centres inside the farms until |surface - DEM| is
within the tolerance at every cell centre inside. Reported per tolerance and rule: points
added, rounds, time, the largest error measured again independently (shapely's containment,
the final meshes built again), and pydelatin's vertices inside the farms at the same maximum
error over the whole DEM (its greedy Delaunay refinement of a height grid), with the ratio.
pydelatin is for this measurement only (``pip install pydelatin``).

Usage: python bench/bench_refine.py [--tolerances 5 10 2] [--rules delaunay first] [--quick]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import shapely
from bench_fidelity import DEM_PATH, FARMS, QUICK_FARMS, Dem, fidelity, polygon_rings, read_polygons
from bench_fidelity import evaluation_cells as inside_cells

import bsp_triangulate
from bsp_triangulate.terrain.refine import CellGrid, refine_many


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerances", type=float, nargs="+", default=[5.0, 10.0, 2.0])
    parser.add_argument("--rules", nargs="+", default=["delaunay", "first", "elevation"])
    parser.add_argument("--quick", action="store_true", help=f"first {QUICK_FARMS} farms only")
    arguments = parser.parse_args()
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
