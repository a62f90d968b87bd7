"""Scale runs of the robustness issue: they must finish, within 1 GiB of peak memory.

1. One polygon with one million vertices (a star-shaped concave ring), through the core.
   With ``--islands``: the benchmark's coast polygon (bench/generate.py: a ring of bays and
   teeth around a grid of star islands, one island per 100 vertices) of that size instead.
2. A layer of one million small polygons (L-shaped footprints), through
   `qgis_process run bsptriangulate:triangulate` with a mesh and a GeoPackage of triangles.

Prints wall time, counts and peak memory (ru_maxrss of this process, or of qgis_process under
`/usr/bin/time -v`). Minutes long: not part of the test suite.

    .venv/bin/python bench/scale_run.py [--polygon [--islands] [--rule R]] [--layer]
        [--vertices N] [--features N]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
BUILD = ROOT / "build" / "scale"


def star_ring(vertices: int, seed: int = 1) -> np.ndarray:
    """A star-shaped concave ring: radius alternating between two random bands."""
    rng = np.random.default_rng(seed)
    angles = np.linspace(0.0, 2 * np.pi, vertices, endpoint=False)
    radii = np.where(np.arange(vertices) % 2 == 0, 1000.0, 600.0) + rng.uniform(0, 200, vertices)
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


def run_polygon(vertices: int, islands: bool = False, rule: str = "first") -> None:
    from bsp_triangulate import triangulate

    if islands:
        from generate import polygon_with_islands

        rings = polygon_with_islands(vertices)
    else:
        rings = [star_ring(vertices)]
    holes = len(rings) - 1
    start = time.perf_counter()
    result = triangulate(rings, rule=rule)
    elapsed = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"one polygon, {vertices:,} vertices, {holes:,} islands, rule {rule}: "
        f"{len(result):,} triangles "
        f"(expected {vertices + 2 * holes - 2:,}) in {elapsed:.1f} s, peak {peak:,.0f} MiB"
    )


def write_layer(path: Path, features: int) -> None:
    """L-shaped footprints (6 vertices, 4 triangles each) on a grid, EPSG:32733."""
    from osgeo import ogr, osr

    ogr.UseExceptions()
    if path.exists():
        return
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32733)
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    layer = ds.CreateLayer("footprints", srs, ogr.wkbPolygon)
    definition = layer.GetLayerDefn()
    side = int(np.ceil(np.sqrt(features)))
    layer.StartTransaction()
    for index in range(features):
        x0, y0 = 300000 + 30.0 * (index % side), 6200000 + 30.0 * (index // side)
        wkt = (
            f"POLYGON(({x0} {y0},{x0 + 20} {y0},{x0 + 20} {y0 + 8},{x0 + 8} {y0 + 8},"
            f"{x0 + 8} {y0 + 20},{x0} {y0 + 20},{x0} {y0}))"
        )
        feature = ogr.Feature(definition)
        feature.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
        layer.CreateFeature(feature)
    layer.CommitTransaction()
    ds = None


def run_layer(features: int) -> None:
    BUILD.mkdir(parents=True, exist_ok=True)
    source = BUILD / f"footprints_{features}.gpkg"
    write_layer(source, features)
    binary = "/usr/bin/qgis_process.bin"
    if not Path(binary).exists():
        binary = "qgis_process"
    with tempfile.TemporaryDirectory() as tmp:
        plugins = Path(tmp) / "plugins"
        plugins.mkdir()
        (plugins / "bsptriangulate").symlink_to(ROOT)
        env = dict(
            os.environ,
            QT_QPA_PLATFORM="offscreen",
            QGIS_CUSTOM_CONFIG_PATH=str(Path(tmp) / "profile"),
            QGIS_PLUGINPATH=str(plugins),
        )
        subprocess.run(
            [binary, "plugins", "enable", "bsptriangulate"],
            env=env,
            check=True,
            capture_output=True,
        )
        mesh, triangles = Path(tmp) / "mesh.2dm", Path(tmp) / "triangles.gpkg"
        command = [
            "/usr/bin/time", "-v", binary, "--json", "run", "bsptriangulate:triangulate", "--",
            f"INPUT={source}", "ELEVATION_SOURCE=0", f"OUTPUT_MESH={mesh}",
            f"OUTPUT_TRIANGLES={triangles}",
        ]  # fmt: skip
        start = time.perf_counter()
        proc = subprocess.run(command, env=env, capture_output=True, text=True)
        elapsed = time.perf_counter() - start
    peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    peak_mib = int(peak.group(1)) / 1024 if peak else float("nan")
    try:
        results = json.loads(proc.stdout[proc.stdout.index("{") :])["results"]
    except (ValueError, KeyError):
        print(proc.stdout[-2000:], proc.stderr[-2000:])
        raise SystemExit(f"qgis_process failed with code {proc.returncode}") from None
    counts = {k: results.get(k) for k in ("FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT")}
    print(f"layer of {features:,} polygons: {counts} in {elapsed:.0f} s, peak {peak_mib:,.0f} MiB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--polygon", action="store_true", help="only the one large polygon")
    parser.add_argument("--layer", action="store_true", help="only the layer of small polygons")
    parser.add_argument(
        "--islands", action="store_true", help="the coast polygon with islands, not the star"
    )
    parser.add_argument("--rule", default="first", help="apex rule of the polygon run")
    parser.add_argument("--vertices", type=int, default=1_000_000)
    parser.add_argument("--features", type=int, default=1_000_000)
    args = parser.parse_args()
    both = not (args.polygon or args.layer)
    if args.polygon or both:
        run_polygon(args.vertices, args.islands, args.rule)
    if args.layer or both:
        run_layer(args.features)


if __name__ == "__main__":
    main()
