"""The benchmark data set: generated, seeded, cached in build/bench/.

- ``stars_<count>.gpkg``: ``count`` concave star-shaped polygons, each with one island, 20 to 60
  vertices per polygon (40 on average: 2,000,000 vertices for the default 50,000 polygons),
  one per cell of a 100 m grid in EPSG:32733, plus ``stars_<count>_dem.tif`` covering them.
- ``islands_<vertices>.gpkg``: one large concave polygon with ``vertices`` vertices in all, of
  which a fifth in ``vertices / 100`` star-shaped islands (the scaling test: 10,000 and 100,000).

Usage: python bench/generate.py [--count N] [--force]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import shapely
from osgeo import gdal, ogr, osr

ROOT = Path(__file__).resolve().parent.parent
BENCH_DIR = ROOT / "build" / "bench"
EPSG = 32733
ORIGIN_X, ORIGIN_Y = 500_000.0, 6_000_000.0
SPACING = 100.0  # metres between the centres of neighbouring star polygons
DEM_CELL = 25.0
SEED = 7_2024
DEFAULT_COUNT = 50_000
ISLAND_VERTICES = 20  # per island of the large polygons

gdal.UseExceptions()
ogr.UseExceptions()

Rings = list[np.ndarray]


def spatial_reference() -> osr.SpatialReference:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(EPSG)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


def star_ring(
    rng: np.random.Generator,
    centre: tuple[float, float],
    count: int,
    outer: float,
    inner: float,
    jitter: float,
    phase: float = 0.0,
) -> np.ndarray:
    """A counter-clockwise star-shaped ring: radii alternate between outer and inner tips."""
    angles = phase + 2.0 * np.pi * np.arange(count) / count
    radii = np.where(np.arange(count) % 2 == 0, outer, inner)
    radii = radii * (1.0 + rng.uniform(-jitter, jitter, count))
    return np.column_stack([centre[0] + radii * np.cos(angles), centre[1] + radii * np.sin(angles)])


def star_polygons(count: int = DEFAULT_COUNT, seed: int = SEED) -> list[Rings]:
    """``count`` star polygons with one island each, on a square grid (row-major)."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(count))
    totals = rng.integers(20, 61, count)
    polygons: list[Rings] = []
    for index, total in enumerate(totals):
        row, column = divmod(index, side)
        centre = (ORIGIN_X + (column + 0.5) * SPACING, ORIGIN_Y + (row + 0.5) * SPACING)
        island_count = max(3, int(total) // 5)
        outer = star_ring(
            rng, centre, int(total) - island_count, 45.0, 26.0, 0.12, rng.uniform(0, np.pi)
        )
        # island: clockwise (as OGC wants), well inside the star's inner radius
        island = star_ring(rng, centre, island_count, 11.0, 7.0, 0.1, rng.uniform(0, np.pi))
        polygons.append([outer, island[::-1].copy()])
    return polygons


# orthogonal building outlines in a unit square, counter-clockwise: rectangle, L, T, U
FOOTPRINT_SHAPES = (
    [(0, 0), (1, 0), (1, 1), (0, 1)],
    [(0, 0), (1, 0), (1, 0.45), (0.5, 0.45), (0.5, 1), (0, 1)],
    [(0.3, 0), (0.7, 0), (0.7, 0.6), (1, 0.6), (1, 1), (0, 1), (0, 0.6), (0.3, 0.6)],
    [(0, 0), (1, 0), (1, 1), (0.7, 1), (0.7, 0.4), (0.3, 0.4), (0.3, 1), (0, 1)],
)


def footprint_polygons(count: int, seed: int = SEED) -> list[Rings]:
    """``count`` building footprints (rectangles, L, T and U shapes of 4 to 8 vertices, 8 to
    30 m, rotated at random) on a 40 m grid; a tenth of them have a rectangular courtyard."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(count))
    polygons: list[Rings] = []
    for index in range(count):
        row, column = divmod(index, side)
        shape = np.asarray(FOOTPRINT_SHAPES[int(rng.integers(len(FOOTPRINT_SHAPES)))], float)
        size = rng.uniform(8.0, 30.0, 2)
        angle = rng.uniform(0.0, np.pi)
        rotation = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        centre = np.array([ORIGIN_X + column * 40.0, ORIGIN_Y + row * 40.0])
        rings = [(shape - 0.5) * size @ rotation + centre]
        if len(shape) == 4 and rng.random() < 0.4:  # a courtyard, clockwise
            court = np.array([(0.3, 0.3), (0.3, 0.7), (0.7, 0.7), (0.7, 0.3)])
            rings.append((court - 0.5) * size @ rotation + centre)
        polygons.append(rings)
    return polygons


def densified_rectangles(count: int, per_side: int = 60, seed: int = SEED) -> list[Rings]:
    """``count`` rectangles of 20 to 100 m, rotated at random, with ``per_side`` vertices on
    each side (points interpolated along the straight edges, as densifying for a reprojection
    leaves them), on a 150 m grid."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(count))
    t = (np.arange(per_side) / per_side)[:, None]
    polygons: list[Rings] = []
    for index in range(count):
        row, column = divmod(index, side)
        width, height = rng.uniform(20.0, 100.0, 2)
        angle = rng.uniform(0.0, np.pi)
        rotation = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        corners = np.array([(0.0, 0.0), (width, 0.0), (width, height), (0.0, height)])
        corners = (corners - (width / 2, height / 2)) @ rotation
        corners += (ORIGIN_X + column * 150.0, ORIGIN_Y + row * 150.0)
        edges = [corners[k] + t * (corners[(k + 1) % 4] - corners[k]) for k in range(4)]
        polygons.append([np.concatenate(edges)])
    return polygons


def mid_size_polygons(count: int, seed: int = SEED) -> list[Rings]:
    """``count`` concave star polygons of 260 to 600 vertices with a 12-vertex island each
    (parcels with detailed boundaries), on a 300 m grid."""
    rng = np.random.default_rng(seed)
    polygons: list[Rings] = []
    for index in range(count):
        row, column = divmod(index, 40)
        centre = (ORIGIN_X + column * 300.0, ORIGIN_Y + row * 300.0)
        vertices = int(rng.integers(260, 601))
        outer = star_ring(rng, centre, vertices, 140.0, 90.0, 0.15, rng.uniform(0, np.pi))
        island = star_ring(rng, centre, 12, 20.0, 14.0, 0.1)
        polygons.append([outer, island[::-1].copy()])
    return polygons


def polygon_with_islands(vertices: int, seed: int = SEED) -> Rings:
    """One concave polygon of ``vertices`` vertices in all, ``vertices // 100`` islands."""
    rng = np.random.default_rng(seed + vertices)
    islands_wanted = vertices // 100
    island_vertices = islands_wanted * ISLAND_VERTICES
    # the islands sit on a square grid inside a disc well within the outer ring
    radius = 1000.0 * math.sqrt(vertices / 10_000)
    spacing = math.sqrt(math.pi * (0.8 * radius) ** 2 / islands_wanted) * 0.95
    steps = np.arange(-radius, radius + spacing, spacing)
    grid_x, grid_y = np.meshgrid(steps, steps)
    centres = np.column_stack([grid_x.ravel(), grid_y.ravel()])
    centres = centres[np.hypot(centres[:, 0], centres[:, 1]) < 0.8 * radius]
    centres = centres[np.argsort(np.hypot(centres[:, 0], centres[:, 1]), kind="stable")]
    centres = centres[:islands_wanted]
    if len(centres) < islands_wanted:
        raise RuntimeError("island grid too small")
    outer_count = vertices - island_vertices
    angles = 2.0 * np.pi * np.arange(outer_count) / outer_count
    # concave: a coastline of bays (a slow wave) and small teeth (alternating radii)
    radii = radius * (
        1.0
        + 0.06 * np.sin(37.0 * angles)
        + np.where(np.arange(outer_count) % 2 == 0, 0.01, -0.01)
        + rng.uniform(-0.005, 0.005, outer_count)
    )
    outer = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    origin = np.array([ORIGIN_X, ORIGIN_Y])
    rings = [outer + origin]
    for cx, cy in centres:
        island = star_ring(
            rng, (cx, cy), ISLAND_VERTICES, 0.3 * spacing, 0.18 * spacing, 0.1, rng.uniform(0, 1)
        )
        rings.append(island[::-1] + origin)
    return rings


def radial_polygons(count: int, seed: int = SEED) -> list[Rings]:
    """``count`` random radial polygons of 260 to 600 vertices (every vertex's radius 100 m
    +-45 %), each with one 8-vertex island, on a 300 m grid."""
    rng = np.random.default_rng(seed + 1)
    polygons: list[Rings] = []
    for index in range(count):
        row, column = divmod(index, 40)
        cx, cy = ORIGIN_X + column * 300.0, ORIGIN_Y + row * 300.0
        vertices = int(rng.integers(260, 601))
        angles = 2.0 * np.pi * np.arange(vertices) / vertices
        radii = 100.0 * rng.uniform(0.55, 1.45, vertices)
        outer = np.column_stack([cx + radii * np.cos(angles), cy + radii * np.sin(angles)])
        island = star_ring(rng, (cx, cy), 8, 30.0, 20.0, 0.1)
        polygons.append([outer, island[::-1].copy()])
    return polygons


def wavy_polygon(vertices: int, islands: int, seed: int = SEED) -> Rings:
    """One wavy polygon of ``vertices`` outer vertices with ``islands`` square islands on a
    grid inside it (the shell a circle whose radius waves, the squares rotated at random)."""
    rng = np.random.default_rng(seed + 2)
    radius = 1000.0 * math.sqrt(islands / 1000)
    angles = 2.0 * np.pi * np.arange(vertices) / vertices
    radii = radius * (1.0 + 0.08 * np.sin(50.0 * angles) + 0.02 * np.sin(977.0 * angles))
    outer = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    spacing = math.sqrt(math.pi * (0.8 * radius) ** 2 / islands) * 0.95
    steps = np.arange(-radius, radius + spacing, spacing)
    grid_x, grid_y = np.meshgrid(steps, steps)
    centres = np.column_stack([grid_x.ravel(), grid_y.ravel()])
    centres = centres[np.hypot(centres[:, 0], centres[:, 1]) < 0.8 * radius]
    centres = centres[np.argsort(np.hypot(centres[:, 0], centres[:, 1]), kind="stable")][:islands]
    if len(centres) < islands:
        raise RuntimeError("island grid too small")
    origin = np.array([ORIGIN_X, ORIGIN_Y])
    rings = [outer + origin]
    square = np.array([(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)])  # clockwise
    for (cx, cy), angle in zip(centres, rng.uniform(0, np.pi / 2, len(centres))):
        turn = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        half = spacing * rng.uniform(0.1, 0.3)
        rings.append(square * half @ turn + (cx, cy) + origin)
    return rings


def river_polygon(vertices: int, islands: int, seed: int = SEED) -> Rings:
    """A long thin shell of ``vertices`` vertices (a meandering band 40 times as long as
    wide) with ``islands`` islands
    of varied size (4 to 40 vertices, radii spread over 20x), packed close to each other and
    to the shell: a stand-in for a real water body with many islands."""
    rng = np.random.default_rng(seed + 3)
    half = vertices // 2
    length = 40_000.0 * math.sqrt(islands / 1000)
    width = length / 40.0
    t = np.linspace(0.0, 1.0, half)
    mid_x = length * t
    mid_y = 0.1 * length * np.sin(2 * np.pi * 3 * t)
    # unit normal of the centre line
    dx, dy = np.gradient(mid_x), np.gradient(mid_y)
    norm = np.hypot(dx, dy)
    nx, ny = -dy / norm, dx / norm
    wiggle = 1.0 + 0.05 * rng.uniform(-1, 1, (2, half))
    left = np.column_stack([mid_x + nx * width / 2 * wiggle[0], mid_y + ny * width / 2 * wiggle[0]])
    right = np.column_stack(
        [mid_x - nx * width / 2 * wiggle[1], mid_y - ny * width / 2 * wiggle[1]]
    )
    outer = np.concatenate([right, left[::-1]])  # counter-clockwise
    placed: list[tuple[float, float, float]] = []
    cells: dict[tuple[int, int], list[int]] = {}
    cell = width  # more than twice the largest island radius
    rings = [outer]
    tries = 0
    while len(placed) < islands and tries < islands * 200:
        tries += 1
        size = width * 0.02 * 20.0 ** rng.uniform(0, 1) ** 3
        at = rng.uniform(0.01, 0.99)
        index = min(int(at * (half - 1)), half - 2)
        offset = rng.uniform(-1, 1) * (width / 2 * 0.95 - size - width * 0.003)
        if offset <= -width / 2 or abs(offset) + size > width / 2 * 0.93:
            continue
        cx, cy = mid_x[index] + nx[index] * offset, mid_y[index] + ny[index] * offset
        key = (int(cx // cell), int(cy // cell))
        near = [
            placed[k]
            for i in (-1, 0, 1)
            for j in (-1, 0, 1)
            for k in cells.get((key[0] + i, key[1] + j), ())
        ]
        gap = width * 0.003
        if any(math.hypot(cx - px, cy - py) < 1.1 * (size + ps) + gap for px, py, ps in near):
            continue
        cells.setdefault(key, []).append(len(placed))
        placed.append((cx, cy, size))
        count = int(rng.integers(4, 41))
        island = star_ring(rng, (cx, cy), count, size, size * 0.8, 0.05, rng.uniform(0, 1))
        rings.append(island[::-1].copy())
    origin = np.array([ORIGIN_X, ORIGIN_Y])
    return [ring + origin for ring in rings]


def to_shapely(rings: Rings) -> shapely.Polygon:
    return shapely.Polygon(rings[0], rings[1:])


def write_gpkg(path: Path, polygons: list[Rings], layer_name: str) -> None:
    """Write 2D polygons (with an ``id`` field) to a GeoPackage layer, in one transaction."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".partial.gpkg")
    if partial.exists():
        partial.unlink()
    dataset = ogr.GetDriverByName("GPKG").CreateDataSource(str(partial))
    layer = dataset.CreateLayer(layer_name, spatial_reference(), ogr.wkbPolygon)
    layer.CreateField(ogr.FieldDefn("id", ogr.OFTInteger))
    definition = layer.GetLayerDefn()
    wkbs = shapely.to_wkb([to_shapely(rings) for rings in polygons], flavor="iso")
    layer.StartTransaction()
    for index, wkb in enumerate(wkbs):
        feature = ogr.Feature(definition)
        feature.SetField("id", index)
        feature.SetGeometry(ogr.CreateGeometryFromWkb(wkb))
        layer.CreateFeature(feature)
    layer.CommitTransaction()
    dataset = None
    partial.rename(path)


def dem_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rolling terrain for the benchmark DEM (metres)."""
    return (
        300.0
        + 120.0 * np.sin(x / 1700.0) * np.cos(y / 2300.0)
        + 40.0 * np.sin((x + y) / 450.0)
        + 8.0 * np.cos(x / 90.0) * np.sin(y / 110.0)
    )


def write_dem(path: Path, xmin: float, ymin: float, xmax: float, ymax: float) -> None:
    """A float32 GeoTIFF with ``DEM_CELL`` cells covering the box with one cell of margin."""
    columns = math.ceil((xmax - xmin) / DEM_CELL) + 2
    rows = math.ceil((ymax - ymin) / DEM_CELL) + 2
    left, top = xmin - DEM_CELL, ymin - DEM_CELL + rows * DEM_CELL
    xs = left + (np.arange(columns) + 0.5) * DEM_CELL
    ys = top - (np.arange(rows) + 0.5) * DEM_CELL
    grid_x, grid_y = np.meshgrid(xs, ys)
    partial = path.with_suffix(".partial.tif")
    dataset = gdal.GetDriverByName("GTiff").Create(
        str(partial), columns, rows, 1, gdal.GDT_Float32, ["COMPRESS=DEFLATE", "TILED=YES"]
    )
    dataset.SetGeoTransform((left, DEM_CELL, 0.0, top, 0.0, -DEM_CELL))
    dataset.SetProjection(spatial_reference().ExportToWkt())
    dataset.GetRasterBand(1).WriteArray(dem_height(grid_x, grid_y).astype(np.float32))
    dataset = None
    partial.rename(path)


def stars_paths(count: int) -> tuple[Path, Path]:
    return BENCH_DIR / f"stars_{count}.gpkg", BENCH_DIR / f"stars_{count}_dem.tif"


def islands_path(vertices: int) -> Path:
    return BENCH_DIR / f"islands_{vertices}.gpkg"


def ensure_stars(count: int = DEFAULT_COUNT, force: bool = False) -> tuple[Path, Path]:
    """The star polygons' GeoPackage and DEM, generated unless already cached."""
    gpkg, dem = stars_paths(count)
    if force or not gpkg.exists():
        write_gpkg(gpkg, star_polygons(count), "stars")
    if force or not dem.exists():
        side = math.ceil(math.sqrt(count))
        rows = math.ceil(count / side)
        write_dem(dem, ORIGIN_X, ORIGIN_Y, ORIGIN_X + side * SPACING, ORIGIN_Y + rows * SPACING)
    return gpkg, dem


def ensure_footprints(count: int, force: bool = False) -> Path:
    """The building footprints' GeoPackage, generated unless already cached."""
    path = BENCH_DIR / f"footprints_{count}.gpkg"
    if force or not path.exists():
        write_gpkg(path, footprint_polygons(count), "footprints")
    return path


def ensure_islands(vertices: int, force: bool = False) -> Path:
    """The large polygon's GeoPackage, generated unless already cached."""
    path = islands_path(vertices)
    if force or not path.exists():
        write_gpkg(path, [polygon_with_islands(vertices)], "islands")
    return path


def read_rings(path: Path) -> list[Rings]:
    """Every polygon of the GeoPackage's first layer as a list of (n, 2) float64 rings.

    Rings keep the GeoPackage's orientation; the closing point is dropped.
    """
    dataset = ogr.Open(str(path))
    layer = dataset.GetLayer(0)
    wkbs = [bytes(feature.GetGeometryRef().ExportToIsoWkb()) for feature in layer]
    polygons: list[Rings] = []
    for geometry in shapely.from_wkb(wkbs):
        parts = shapely.get_parts(geometry)
        for part in parts:
            rings = [part.exterior, *part.interiors]
            polygons.append([shapely.get_coordinates(ring)[:-1] for ring in rings])
    return polygons


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=DEFAULT_COUNT)
    parser.add_argument("--force", action="store_true", help="regenerate even when cached")
    arguments = parser.parse_args()
    for path in ensure_stars(arguments.count, arguments.force):
        print(path)
    for vertices in (10_000, 100_000):
        print(ensure_islands(vertices, arguments.force))


if __name__ == "__main__":
    main()
