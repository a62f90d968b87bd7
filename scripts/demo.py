"""The demo: triangulate generated sample data with bsptriangulate:triangulate and render it.

1. writes a terrain GeoTIFF and a polygon GeoPackage (river with islands, lake, roofs);
2. runs ``bsptriangulate:triangulate`` through qgis_process with elevation from the DEM, the
   "delaunay" apex rule and a maximum vertical error (DEM cell centres inside the polygons are
   added as interior points until the mesh is within it of the DEM: the river and the lake lie
   on the terrain), writing a 2DM mesh and the per-triangle GeoPackage;
3. runs it again on the river and the lake alone, writing their surface as a GLB;
4. runs ``bsptriangulate:buildings`` on the roofs (roof Z of the geometry, ground from the DEM
   per vertex), writing the closed solids as a GLB and their triangles as a GeoPackage;
5. renders the triangles (the algorithm's default style) over the shaded terrain to a PNG:
   the whole area, the river close up with the DEM points added as dots, and the village, with
   a legend;
6. renders the terrain, the draped mesh and the solids in QGIS's 3D renderer to a second PNG
   (scripts/render_3d.py), when an X display or Xvfb is available;
7. prints the counts, the points added, the largest |mesh - DEM| at the cell centres inside the
   river and the lake (measured again on the triangles written), the output paths and the time.

Usage: python scripts/demo.py [--output-dir build/demo] [--update-docs] [--no-3d]
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
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import make_sample_data as sample
import numpy as np
import shapely

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from bsp_triangulate.terrain.refine import CellGrid, cells_inside, locate_cells

if TYPE_CHECKING:
    from qgis.core import QgsRectangle

ROOT = Path(__file__).resolve().parent.parent
STYLE = ROOT / "processing_provider" / "styles" / "triangles.qml"
DOCS_PNG = ROOT / "docs" / "demo.png"
DOCS_3D_PNG = ROOT / "docs" / "demo-3d.png"
ALGORITHM = "bsptriangulate:triangulate"
BUILDINGS = "bsptriangulate:buildings"
COUNTS = ("FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT", "EMPTY_COUNT", "POINTS_ADDED")
BUILDING_COUNTS = ("FEATURE_COUNT", "BUILT_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT", "EMPTY_COUNT")
DOCS_PNG_LIMIT = 300_000  # bytes
DOCS_3D_PNG_LIMIT = 400_000  # bytes
APEX_DELAUNAY = 2
# metres: the surface within this of the DEM at every cell centre inside a polygon. The demo
# DEM's valley rises a few metres from the river's middle to its banks and falls 48 m along it;
# 1 m keeps the mesh small (a few hundred points) and the water on the terrain in 3D.
MAX_VERTICAL_ERROR = 1.0
WATER_KINDS = ("river", "lake")
# the 2D picture's river close-up: centred on the middle island (local x, m), half-side (m)
RIVER_VIEW_X = 1850.0
RIVER_VIEW_HALF = 200.0


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


def run_algorithm(algorithm: str, parameters: dict, environment: dict[str, str]) -> dict:
    """Run a Processing algorithm through qgis_process; return its results."""
    output = qgis_process(
        ["--json", "run", algorithm, *(f"--{key}={value}" for key, value in parameters.items())],
        environment,
    )
    return json.loads(output[output.index("{") :])["results"]


def remove_stale(*paths: Path) -> None:
    for stale in paths:
        if stale.exists():
            stale.unlink()


def subset(polygons: Path, condition: str) -> str:
    """An OGR layer source of the sample features that match the condition."""
    return f"{polygons}|layername=features|subset={condition}"


def triangulate(
    polygons: Path, terrain: Path, output_dir: Path, environment: dict[str, str]
) -> tuple[dict, Path, Path]:
    """Run the algorithm with DEM elevation, the delaunay rule and the maximum vertical error;
    return its results."""
    mesh = output_dir / "mesh.2dm"
    triangles = output_dir / "triangles.gpkg"
    remove_stale(mesh, triangles)
    parameters = {
        "INPUT": polygons,
        "ELEVATION_SOURCE": 3,
        "DEM": terrain,
        "DEM_BAND": 1,
        "APEX_RULE": APEX_DELAUNAY,
        "MAX_VERTICAL_ERROR": MAX_VERTICAL_ERROR,
        "OUTPUT_MESH": mesh,
        "OUTPUT_TRIANGLES": triangles,
    }
    qgis_process(["plugins", "enable", "bsptriangulate"], environment)
    return run_algorithm(ALGORITHM, parameters, environment), mesh, triangles


def water_model(
    polygons: Path, terrain: Path, output_dir: Path, environment: dict[str, str]
) -> tuple[dict, Path]:
    """The river and the lake on the DEM (within the maximum vertical error), as a binary glTF
    model."""
    model = output_dir / "water.glb"
    remove_stale(model)
    parameters = {
        "INPUT": subset(polygons, "\"kind\" <> 'roof'"),
        "ELEVATION_SOURCE": 3,
        "DEM": terrain,
        "DEM_BAND": 1,
        "APEX_RULE": APEX_DELAUNAY,
        "MAX_VERTICAL_ERROR": MAX_VERTICAL_ERROR,
        "OUTPUT_MESH": model,
    }
    return run_algorithm(ALGORITHM, parameters, environment), model


def building_solids(
    polygons: Path, terrain: Path, output_dir: Path, environment: dict[str, str]
) -> tuple[dict, Path, Path]:
    """The roofs built into closed solids down to the DEM: a GLB and the solids' triangles."""
    model = output_dir / "buildings.glb"
    triangles = output_dir / "buildings.gpkg"
    remove_stale(model, triangles)
    parameters = {
        "INPUT": subset(polygons, "\"kind\" = 'roof'"),
        "HEIGHT_SOURCE": 1,  # the roof's own Z
        "GROUND": 1,  # the DEM under every vertex: walls follow the slope
        "DEM": terrain,
        "DEM_BAND": 1,
        "ROOF_PLANAR_TOLERANCE": 0.1,
        "OUTPUT_MESH": model,
        "OUTPUT_TRIANGLES": triangles,
    }
    return run_algorithm(BUILDINGS, parameters, environment), model, triangles


@dataclass
class WaterCheck:
    """One water kind's mesh against the DEM: ``cells`` whose centres lie strictly inside its
    polygons, ``max_error`` the largest |mesh - DEM| over them (the written triangles,
    interpolated at the centres), ``added`` (k, 2) the mesh's vertices off the polygons' rings:
    the DEM points added."""

    cells: int
    max_error: float
    added: np.ndarray


def read_geometries(path: Path, layer_name: str, kind: str) -> list[shapely.Geometry]:
    """The geometries (with z) of one kind of a GeoPackage layer."""
    from osgeo import ogr

    source = ogr.Open(str(path))
    layer = source.GetLayer(layer_name)
    layer.SetAttributeFilter(f"kind = '{kind}'")
    return [shapely.from_wkb(bytes(item.GetGeometryRef().ExportToIsoWkb())) for item in layer]


def check_water(triangles: Path, polygons: Path, terrain: Path) -> dict[str, WaterCheck]:
    """The river's and the lake's meshes measured again against the DEM (WaterCheck)."""
    from osgeo import gdal

    dataset = gdal.Open(str(terrain))
    grid = CellGrid.from_array(dataset.ReadAsArray().astype(np.float64), dataset.GetGeoTransform())
    checks: dict[str, WaterCheck] = {}
    for kind in WATER_KINDS:
        inside = np.zeros(grid.values.size, bool)
        ring_vertices: set[tuple[float, float]] = set()
        for polygon in read_geometries(polygons, "features", kind):
            rings = [np.asarray(polygon.exterior.coords)]
            rings += [np.asarray(ring.coords) for ring in polygon.interiors]
            rows, cols = cells_inside(rings, grid)
            inside[rows * grid.shape[1] + cols] = True
            ring_vertices.update(map(tuple, np.concatenate(rings)[:, :2].tolist()))
        corners = np.array(
            [
                shapely.get_coordinates(triangle, include_z=True)[:3]
                for triangle in read_geometries(triangles, "triangles", kind)
            ]
        ).reshape(-1, 3, 3)
        _triangle, rows, cols, z = locate_cells(corners, [grid])
        key = rows * grid.shape[1] + cols
        hit = inside[key]
        difference = np.abs(z[hit] - grid.values.ravel()[key[hit]])
        vertices = np.unique(corners.reshape(-1, 3)[:, :2], axis=0)
        added = np.array([xy for xy in vertices.tolist() if tuple(xy) not in ring_vertices])
        checks[kind] = WaterCheck(
            int(inside.sum()),
            float(difference.max()) if hit.any() else 0.0,
            added.reshape(-1, 2),
        )
    return checks


def square_around(extent: QgsRectangle, margin: float) -> QgsRectangle:
    """A square rectangle centred on the extent, covering it plus the margin."""
    from render import QgsRectangle  # imports QGIS: only after the qgis_process run

    half = max(extent.width(), extent.height()) / 2 + margin
    centre = extent.center()
    return QgsRectangle(centre.x() - half, centre.y() - half, centre.x() + half, centre.y() + half)


def river_window(x: float, half: float) -> QgsRectangle:
    """A square of half-side ``half`` centred on the river's centre line at local ``x``."""
    from render import QgsRectangle

    centre_x = sample.ORIGIN_X + x
    centre_y = sample.ORIGIN_Y + float(sample.valley_centre(np.array([x]))[0])
    return QgsRectangle(centre_x - half, centre_y - half, centre_x + half, centre_y + half)


def feature_extent(polygons: Path, kind: str) -> QgsRectangle:
    """The extent of the sample features of one kind (lake, roof, river)."""
    import render

    layer = render.vector_layer(str(polygons))
    layer.setSubsetString(f"\"kind\" = '{kind}'")
    return layer.extent()


def render_views(
    terrain: Path, polygons: Path, triangles: Path, added: np.ndarray, output: Path
) -> Path:
    """The whole area, a close-up of the river with the DEM points ``added`` (x, y) as dots and
    the village, side by side, with the default style, and a legend below them. The whole area
    has no labels: its triangles are too small for them."""
    import render

    render.start_qgis()
    style = STYLE if STYLE.exists() else None
    if style is None:
        print(f"warning: {STYLE.relative_to(ROOT)} not found, default symbols used")
    terrain_layers = list(reversed(render.terrain_layers(terrain)))
    labelled = render.vector_layer(str(triangles), style)
    unlabelled = render.vector_layer(str(triangles), style)
    unlabelled.setLabelsEnabled(False)
    dots = render.point_layer(added.tolist(), labelled.crs().authid(), "DEM points added")
    whole = [unlabelled, *terrain_layers]
    views = [
        (
            f"Whole area, 4 x 3 km; water within {MAX_VERTICAL_ERROR:g} m of the DEM",
            whole,
            render.parse_extent(None, whole),
            (720, 540),
        ),
        (
            "River around its middle island: DEM points added",
            [dots, labelled, *terrain_layers],
            river_window(RIVER_VIEW_X, RIVER_VIEW_HALF),
            (540, 540),
        ),
        (
            "Village roofs",
            [labelled, *terrain_layers],
            square_around(feature_extent(polygons, "roof"), 15),
            (540, 540),
        ),
    ]
    work = Path(tempfile.mkdtemp(prefix="bsptri-demo-render-"))
    panels = [
        render.render(layers, work / f"view{number}.png", extent, size, title)
        for number, (title, layers, extent, size) in enumerate(views)
    ]
    width = sum(size[0] for *_rest, size in views) + 6 * (len(views) - 1)
    classes = render.graduated_classes(labelled)
    legend = render.legend_strip(
        width,
        "Colour: depth in the BSP tree",
        classes,
        "Numbers: the triangle's order (pre-order index in the BSP tree).  "
        "Red dots: DEM points added",
    )
    keep = [*(colour for _label, colour in classes), render.QColor(render.POINT_COLOUR)]
    return render.side_by_side(panels, output, palette=True, legend=legend, keep=keep)


def render_3d(output_dir: Path, picture: Path) -> Path | None:
    """The 3D picture through scripts/render_3d.py: on the X display, else under xvfb-run;
    None (with a message) when neither is available or the renderer fails."""
    command = [
        sys.executable,
        str(ROOT / "scripts" / "render_3d.py"),
        str(output_dir),
        str(picture),
    ]
    if not os.environ.get("DISPLAY"):
        xvfb = shutil.which("xvfb-run")
        if xvfb is None:
            print("3D picture skipped: no X display and no xvfb-run (apt-get install xvfb)")
            return None
        command = [xvfb, "-a", "-s", "-screen 0 1280x1024x24", *command]
    environment = dict(os.environ)
    environment["QT_QPA_PLATFORM"] = "xcb"  # the 3D renderer needs OpenGL: not offscreen
    process = subprocess.run(command, env=environment, capture_output=True, text=True)
    if process.returncode != 0 or not picture.exists():
        print(f"3D picture skipped: the renderer failed ({process.returncode}):")
        print(process.stdout[-2000:], process.stderr[-2000:])
        return None
    return picture


def copy_to_docs(picture: Path, target: Path, limit: int) -> None:
    shutil.copyfile(picture, target)
    size = target.stat().st_size
    print(f"  {'docs picture':15} {target} ({size / 1000:.0f} kB)")
    if size > limit:
        sys.exit(f"{target} is larger than {limit / 1000:.0f} kB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=sample.DEFAULT_OUTPUT)
    parser.add_argument(
        "--update-docs",
        action="store_true",
        help=f"copy the PNGs to {DOCS_PNG.relative_to(ROOT)} and {DOCS_3D_PNG.relative_to(ROOT)}",
    )
    parser.add_argument("--no-3d", action="store_true", help="skip the 3D picture")
    arguments = parser.parse_args()
    start = time.perf_counter()
    output_dir = arguments.output_dir.resolve()
    terrain, polygons = sample.make_sample_data(output_dir)
    work = Path(tempfile.mkdtemp(prefix="bsptri-demo-"))
    environment = qgis_environment(work)
    results, mesh, triangles = triangulate(polygons, terrain, output_dir, environment)
    _water_results, water = water_model(polygons, terrain, output_dir, environment)
    solids, buildings, building_triangles = building_solids(
        polygons, terrain, output_dir, environment
    )
    triangulated = time.perf_counter()
    checks = check_water(triangles, polygons, terrain)
    added = np.concatenate([check.added for check in checks.values()])
    picture = render_views(terrain, polygons, triangles, added, output_dir / "triangles.png")
    picture_3d = None
    if not arguments.no_3d:
        picture_3d = render_3d(output_dir, output_dir / "demo-3d.png")
    elapsed = time.perf_counter() - start

    print("BSP Triangulate demo")
    for key in COUNTS:
        print(f"  {key.lower().replace('_', ' '):15} {results.get(key, 'n/a')}")
    print(f"  largest |mesh - DEM| at the cell centres inside (bound {MAX_VERTICAL_ERROR:g} m):")
    for kind, check in checks.items():
        print(
            f"    {kind:13} {check.max_error:.2f} m over {check.cells} cells, "
            f"{len(check.added)} points added"
        )
    print("  buildings:")
    for key in BUILDING_COUNTS:
        print(f"    {key.lower().replace('_', ' '):13} {solids.get(key, 'n/a')}")
    for label, path in (
        ("terrain", terrain),
        ("polygons", polygons),
        ("mesh", mesh),
        ("triangles", triangles),
        ("water model", water),
        ("building model", buildings),
        ("building faces", building_triangles),
        ("picture", picture),
        ("3D picture", picture_3d),
    ):
        print(f"  {label:15} {path if path is not None else 'not made'}")
    print(f"  {'time':15} {elapsed:.1f} s ({triangulated - start:.1f} s data + qgis_process)")
    if arguments.update_docs:
        copy_to_docs(picture, DOCS_PNG, DOCS_PNG_LIMIT)
        if picture_3d is not None:
            copy_to_docs(picture_3d, DOCS_3D_PNG, DOCS_3D_PNG_LIMIT)


if __name__ == "__main__":
    main()
