"""Triangulate a layer on a Dask cluster.

Usage: python -m bsp_triangulate.distributed INPUT OUT_DIR [--dem DEM] [--scheduler ADDRESS]

Without --scheduler a LocalCluster of --workers processes runs on this machine; with it, the
same run goes to that cluster's scheduler (its workers need bsp_triangulate importable, and
INPUT, OUT_DIR and DEM at the same paths).
"""

from __future__ import annotations

import argparse
import sys

from .dataset import PARTITION_ROWS, PARTITIONING, triangulate_dataset
from .partition import ELEVATIONS, INVALID, MESH_FORMATS


def parser() -> argparse.ArgumentParser:
    parse = argparse.ArgumentParser(
        prog="python -m bsp_triangulate.distributed",
        description=__doc__.splitlines()[0],
    )
    parse.add_argument("input", help="GeoParquet file or folder, or GeoPackage")
    parse.add_argument("out_dir", help="output folder (triangles/, meshes/, index, summary)")
    parse.add_argument("--dem", help="DEM raster (GDAL) for the vertices' z")
    parse.add_argument("--dem-band", type=int, default=1)
    parse.add_argument("--scheduler", help="address of a Dask scheduler (default: a LocalCluster)")
    parse.add_argument("--workers", type=int, help="LocalCluster worker processes (default: cores)")
    parse.add_argument("--rule", default="first", help="apex rule: first or elevation")
    parse.add_argument("--elevation", choices=ELEVATIONS, help="z source (default: from options)")
    parse.add_argument("--z-column", help="attribute giving each feature's z")
    parse.add_argument("--id-column", help="attribute giving the source id")
    parse.add_argument("--invalid", choices=INVALID, default="repair")
    parse.add_argument("--mesh-format", choices=MESH_FORMATS, default="ply")
    parse.add_argument("--partitioning", choices=PARTITIONING, default="hilbert")
    parse.add_argument("--partitions", type=int, help="partitions after the Hilbert shuffle")
    parse.add_argument("--partition-rows", type=int, default=PARTITION_ROWS)
    parse.add_argument("--layer", help="layer of a multi-layer GeoPackage")
    parse.add_argument("--quiet", action="store_true", help="no progress bar")
    return parse


def main(argv: list[str] | None = None) -> int:
    arguments = parser().parse_args(argv)
    client = None
    if arguments.scheduler:
        from distributed import Client

        client = Client(arguments.scheduler)
    try:
        summary = triangulate_dataset(
            arguments.input,
            arguments.out_dir,
            rule=arguments.rule,
            elevation=arguments.elevation,
            dem=arguments.dem,
            dem_band=arguments.dem_band,
            z_column=arguments.z_column,
            id_column=arguments.id_column,
            invalid=arguments.invalid,
            mesh_format=arguments.mesh_format,
            partitioning=arguments.partitioning,
            npartitions=arguments.partitions,
            partition_rows=arguments.partition_rows,
            layer=arguments.layer,
            client=client,
            workers=arguments.workers,
            show_progress=not arguments.quiet,
        )
    finally:
        if client is not None:
            client.close()
    failures = summary["failures"]
    print()
    print(
        f"{summary['read']} read: {summary['triangulated']} triangulated, "
        f"{summary['failed']} failed, {summary['empty']} empty; {summary['triangles']} "
        f"triangles in {summary['partitions']} partitions, {summary['seconds']['total']:.1f} s"
    )
    for failure in failures[:10]:
        print(f"  failed {failure['feature_id']}: {failure['reason']}")
    if len(failures) > 10:
        print(f"  ... and {len(failures) - 10} more (summary.json)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
