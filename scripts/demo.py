"""The demo: triangulate generated sample data with bsptriangulate:triangulate and render it.

1. writes a terrain GeoTIFF and a polygon GeoPackage (river with islands, lake, roofs);
2. runs ``bsptriangulate:triangulate`` through qgis_process with elevation from the DEM and the
   "elevation" apex rule, writing a 2DM mesh and the per-triangle GeoPackage;
3. renders the triangles (the algorithm's default style) over the shaded terrain to a PNG;
4. prints the counts, the output paths and the time.

Usage: python scripts/demo.py [--output-dir build/demo] [--update-docs]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

import make_sample_data as sample

if TYPE_CHECKING:
    from qgis.core import QgsRectangle

ROOT = Path(__file__).resolve().parent.parent
STYLE = ROOT / "processing_provider" / "styles" / "triangles.qml"
DOCS_PNG = ROOT / "docs" / "demo.png"
ALGORITHM = "bsptriangulate:triangulate"
COUNTS = ("FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT", "EMPTY_COUNT")
DOCS_PNG_LIMIT = 300_000  # bytes


def qgis_process_binary() -> str:
    """``/usr/bin/qgis_process.bin`` if present (the wrapper script is broken on Debian 12)."""
    if Path("/usr/bin/qgis_process.bin").exists():
        return "/usr/bin/qgis_process.bin"
    found = shutil.which("qgis_process")
    if found is None:
        sys.exit("qgis_process not found: install QGIS (make demo does)")
    return found


def qgis_environment(work: Path) -> dict[str, str]:
    """Offscreen, a throwaway profile and the repository as plugin ``bsptriangulate``."""
    plugins = work / "plugins"
    plugins.mkdir()
    (plugins / "bsptriangulate").symlink_to(ROOT, target_is_directory=True)
    environment = dict(os.environ)
    environment["QT_QPA_PLATFORM"] = "offscreen"
    environment["QGIS_CUSTOM_CONFIG_PATH"] = str(work / "profile")
    environment["QGIS_PLUGINPATH"] = str(plugins)
    return environment


def qgis_process(arguments: list[str], environment: dict[str, str]) -> str:
    """Run qgis_process; exit with its output when it fails."""
    process = subprocess.run(
        [qgis_process_binary(), *arguments], env=environment, capture_output=True, text=True
    )
    if process.returncode != 0:
        sys.exit(
            f"qgis_process {' '.join(arguments[:3])} failed ({process.returncode}):\n"
            f"{process.stdout[-3000:]}\n{process.stderr[-3000:]}"
        )
    return process.stdout


def triangulate(
    polygons: Path, terrain: Path, output_dir: Path, environment: dict[str, str]
) -> tuple[dict, Path, Path]:
    """Run the algorithm with DEM elevation and the elevation rule; return its results."""
    mesh = output_dir / "mesh.2dm"
    triangles = output_dir / "triangles.gpkg"
    for stale in (mesh, triangles):
        if stale.exists():
            stale.unlink()
    parameters = {
        "INPUT": polygons,
        "ELEVATION_SOURCE": 3,
        "DEM": terrain,
        "DEM_BAND": 1,
        "APEX_RULE": 1,
        "OUTPUT_MESH": mesh,
        "OUTPUT_TRIANGLES": triangles,
    }
    qgis_process(["plugins", "enable", "bsptriangulate"], environment)
    output = qgis_process(
        ["--json", "run", ALGORITHM, *(f"--{key}={value}" for key, value in parameters.items())],
        environment,
    )
    results = json.loads(output[output.index("{") :])["results"]
    return results, mesh, triangles


def square_around(extent: QgsRectangle, margin: float) -> QgsRectangle:
    """A square rectangle centred on the extent, covering it plus the margin."""
    from render import QgsRectangle  # imports QGIS: only after the qgis_process run

    half = max(extent.width(), extent.height()) / 2 + margin
    centre = extent.center()
    return QgsRectangle(centre.x() - half, centre.y() - half, centre.x() + half, centre.y() + half)


def feature_extent(polygons: Path, kind: str) -> QgsRectangle:
    """The extent of the sample features of one kind (lake, roof, river)."""
    import render

    layer = render.vector_layer(str(polygons))
    layer.setSubsetString(f"\"kind\" = '{kind}'")
    return layer.extent()


def render_views(terrain: Path, polygons: Path, triangles: Path, output: Path) -> Path:
    """The whole area, the lake and the village, side by side, with the default style."""
    import render

    render.start_qgis()
    style = STYLE if STYLE.exists() else None
    if style is None:
        print(f"warning: {STYLE.relative_to(ROOT)} not found, default symbols used")
    layers = [render.vector_layer(str(triangles), style), *reversed(render.terrain_layers(terrain))]
    views = [
        ("Whole area, 4 x 3 km", render.parse_extent(None, layers), (720, 540)),
        ("Lake with an island", square_around(feature_extent(polygons, "lake"), 30), (540, 540)),
        ("Village roofs", square_around(feature_extent(polygons, "roof"), 15), (540, 540)),
    ]
    work = Path(tempfile.mkdtemp(prefix="bsptri-demo-render-"))
    panels = [
        render.render(layers, work / f"view{number}.png", extent, size, title)
        for number, (title, extent, size) in enumerate(views)
    ]
    return render.side_by_side(panels, output, palette=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=sample.DEFAULT_OUTPUT)
    parser.add_argument(
        "--update-docs", action="store_true", help=f"copy the PNG to {DOCS_PNG.relative_to(ROOT)}"
    )
    arguments = parser.parse_args()
    start = time.perf_counter()
    output_dir = arguments.output_dir.resolve()
    terrain, polygons = sample.make_sample_data(output_dir)
    work = Path(tempfile.mkdtemp(prefix="bsptri-demo-"))
    results, mesh, triangles = triangulate(polygons, terrain, output_dir, qgis_environment(work))
    triangulated = time.perf_counter()
    picture = render_views(terrain, polygons, triangles, output_dir / "triangles.png")
    elapsed = time.perf_counter() - start

    print("BSP Triangulate demo")
    for key in COUNTS:
        print(f"  {key.lower().replace('_', ' '):15} {results.get(key, 'n/a')}")
    for label, path in (
        ("terrain", terrain),
        ("polygons", polygons),
        ("mesh", mesh),
        ("triangles", triangles),
        ("picture", picture),
    ):
        print(f"  {label:15} {path}")
    print(f"  {'time':15} {elapsed:.1f} s ({triangulated - start:.1f} s data + qgis_process)")
    if arguments.update_docs:
        shutil.copyfile(picture, DOCS_PNG)
        size = DOCS_PNG.stat().st_size
        print(f"  {'docs picture':15} {DOCS_PNG} ({size / 1000:.0f} kB)")
        if size > DOCS_PNG_LIMIT:
            sys.exit(f"{DOCS_PNG} is larger than {DOCS_PNG_LIMIT / 1000:.0f} kB")


if __name__ == "__main__":
    main()
