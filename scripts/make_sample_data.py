"""Generate the demo's sample data: a terrain GeoTIFF and a polygon GeoPackage.

Everything is computed from a fixed seed (no downloads): a 4 km x 3 km terrain of 10 m cells in
EPSG:32733 with hills and a winding valley, and a PolygonZ layer with the river of that valley
(three islands), a lake with an island and building roofs on tilted planes (small z noise, for
the planar tolerance).

Usage: python scripts/make_sample_data.py [OUTPUT_DIR]   (default build/demo)
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from osgeo import gdal, ogr, osr
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUTPUT = ROOT / "build" / "demo"
EPSG = 32733
ORIGIN_X, ORIGIN_Y = 300_000.0, 6_200_000.0  # lower-left corner, UTM 33S
COLUMNS, ROWS, CELL = 400, 300, 10.0
WIDTH, HEIGHT = COLUMNS * CELL, ROWS * CELL
SEED = 20240611
RIVER_HALF_WIDTH = 70.0
LAKE_CENTRE = (3050.0, 2450.0)
LAKE_RADIUS = 230.0
LAKE_LEVEL = 236.0
ROOF_CLEARANCE = 3.0  # metres: the lowest roof vertex above the terrain

gdal.UseExceptions()
ogr.UseExceptions()


@dataclass
class SampleFeature:
    """One polygon of the sample layer, in world coordinates with z."""

    name: str
    kind: str
    polygon: Polygon


def valley_centre(x: np.ndarray) -> np.ndarray:
    """y of the valley's centre line (local coordinates) at local x."""
    return 1350.0 + 420.0 * np.sin(2.0 * np.pi * x / 2600.0 + 0.4) + 0.08 * x


def terrain(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Terrain height in metres at local coordinates (metres from the lower-left corner)."""
    rng = np.random.default_rng(SEED)
    hills = np.zeros(np.broadcast(x, y).shape)
    for _ in range(14):
        hx, hy = rng.uniform(0, WIDTH), rng.uniform(0, HEIGHT)
        height, sigma = rng.uniform(40, 160), rng.uniform(250, 650)
        hills += height * np.exp(-((x - hx) ** 2 + (y - hy) ** 2) / (2 * sigma**2))
    distance = np.abs(y - valley_centre(x))
    floor = 180.0 - 0.012 * x
    slopes = (hills + 30.0 + 0.01 * y) * (1.0 - np.exp(-((distance / 380.0) ** 2)))
    z = floor + slopes
    # a basin holding the lake: flat at the lake level inside, blending out around it
    lake_distance = np.hypot(x - LAKE_CENTRE[0], y - LAKE_CENTRE[1])
    blend = np.clip((lake_distance - LAKE_RADIUS * 1.1) / 450.0, 0.0, 1.0)
    blend = blend * blend * (3.0 - 2.0 * blend)  # smoothstep: no rim around the basin
    return LAKE_LEVEL + blend * (z - LAKE_LEVEL)


def terrain_grid() -> np.ndarray:
    """The terrain sampled at the cell centres, north row first (GeoTIFF order), float32."""
    xs = (np.arange(COLUMNS) + 0.5) * CELL
    ys = HEIGHT - (np.arange(ROWS) + 0.5) * CELL
    gx, gy = np.meshgrid(xs, ys)
    return terrain(gx, gy).astype(np.float32)


def spatial_reference() -> osr.SpatialReference:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(EPSG)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


def write_terrain(path: Path) -> None:
    """Write the terrain as a single-band float32 GeoTIFF."""
    driver = gdal.GetDriverByName("GTiff")
    dataset = driver.Create(str(path), COLUMNS, ROWS, 1, gdal.GDT_Float32, ["COMPRESS=DEFLATE"])
    dataset.SetGeoTransform((ORIGIN_X, CELL, 0.0, ORIGIN_Y + HEIGHT, 0.0, -CELL))
    dataset.SetProjection(spatial_reference().ExportToWkt())
    band = dataset.GetRasterBand(1)
    band.WriteArray(terrain_grid())
    band.SetDescription("elevation")
    dataset.FlushCache()
    dataset = None


def with_terrain_z(polygon: Polygon, z_offset: float = 0.0) -> Polygon:
    """The polygon with z = terrain height (+ offset) at every vertex."""

    def lift(coords: np.ndarray) -> np.ndarray:
        z = terrain(coords[:, 0], coords[:, 1]) + z_offset
        return np.column_stack([coords[:, :2], z])

    return shapely.transform(shapely.force_3d(polygon), lift, include_z=True)


def river() -> Polygon:
    """The river along the valley floor, with three elongated islands."""
    xs = np.linspace(-50.0, WIDTH + 50.0, 220)
    centre = LineString(np.column_stack([xs, valley_centre(xs)]))
    channel = centre.buffer(RIVER_HALF_WIDTH, quad_segs=4).intersection(
        shapely.box(10.0, 10.0, WIDTH - 10.0, HEIGHT - 10.0)
    )
    islands = []
    for x, length, width in ((700.0, 110.0, 24.0), (1850.0, 150.0, 30.0), (3100.0, 90.0, 20.0)):
        y = float(valley_centre(np.array([x]))[0])
        slope = float(np.diff(valley_centre(np.array([x - 1.0, x + 1.0])))[0] / 2.0)
        ellipse = affinity.scale(Point(x, y).buffer(1.0, quad_segs=5), length / 2, width / 2)
        islands.append(affinity.rotate(ellipse, math.degrees(math.atan(slope)), origin=(x, y)))
    shape = Polygon(channel.exterior.coords, [island.exterior.coords for island in islands])
    return shapely.simplify(shape, 0.5)


def lake(rng: np.random.Generator) -> Polygon:
    """A lobed lake in the basin, with one island."""
    angles = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
    radius = LAKE_RADIUS * (1.0 + 0.12 * np.sin(3 * angles) + 0.02 * rng.standard_normal(48))
    cx, cy = LAKE_CENTRE
    outer = np.column_stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)])
    island_angles = np.linspace(0.0, 2 * np.pi, 9, endpoint=False)
    island_radius = 45.0 * (1.0 + 0.15 * rng.standard_normal(9))
    island = np.column_stack(
        [
            cx + 60.0 + island_radius * np.cos(island_angles),
            cy - 30.0 + 0.7 * island_radius * np.sin(island_angles),
        ]
    )
    return Polygon(outer, [island])


def roof_outline(rng: np.random.Generator, cx: float, cy: float) -> Polygon:
    """A rectangle or an L-shape footprint, rotated, centred near (cx, cy)."""
    length, depth = rng.uniform(14, 26), rng.uniform(9, 14)
    if rng.random() < 0.5:
        outline = shapely.box(-length / 2, -depth / 2, length / 2, depth / 2)
    else:
        wing = rng.uniform(8, 12)
        outline = Polygon(
            [
                (-length / 2, -depth / 2),
                (length / 2, -depth / 2),
                (length / 2, depth / 2 + wing),
                (length / 2 - wing, depth / 2 + wing),
                (length / 2 - wing, depth / 2),
                (-length / 2, depth / 2),
            ]
        )
    outline = affinity.rotate(outline, rng.uniform(0, 90), origin=(0, 0))
    return affinity.translate(outline, cx, cy)


def roof(rng: np.random.Generator, outline: Polygon, noise: float) -> Polygon:
    """The outline lifted onto a tilted plane above the terrain, with vertical noise."""
    cx, cy = outline.centroid.x, outline.centroid.y
    base = float(terrain(np.array([cx]), np.array([cy]))[0]) + rng.uniform(5.0, 9.0)
    gx, gy = rng.uniform(-0.35, 0.35, 2)

    def lift(coords: np.ndarray) -> np.ndarray:
        z = base + gx * (coords[:, 0] - cx) + gy * (coords[:, 1] - cy)
        z = z + rng.uniform(-noise, noise, len(coords))
        return np.column_stack([coords[:, :2], z])

    lifted = shapely.transform(shapely.force_3d(outline), lift, include_z=True)
    # every roof vertex at least ROOF_CLEARANCE above the terrain, so the roof makes a solid
    coords = shapely.get_coordinates(lifted, include_z=True)
    clearance = float((coords[:, 2] - terrain(coords[:, 0], coords[:, 1])).min())
    return affinity.translate(lifted, zoff=max(ROOF_CLEARANCE - clearance, 0.0))


def buildings(rng: np.random.Generator, avoid: Polygon, count: int = 9) -> list[Polygon]:
    """Roofs of a small village west of the lake, clear of the river and the lake."""
    roofs: list[Polygon] = []
    taken = avoid.buffer(20.0)
    for _attempt in range(10_000):
        if len(roofs) == count:
            break
        cx, cy = rng.uniform(2400, 2600), rng.uniform(2400, 2570)
        outline = roof_outline(rng, cx, cy)
        if outline.intersects(taken):
            continue
        taken = taken.union(outline.buffer(8.0))
        roofs.append(roof(rng, outline, noise=0.04))
    if len(roofs) < count:
        raise RuntimeError(f"only {len(roofs)} of {count} roofs fit in the village")
    return roofs


def to_world(polygon: Polygon) -> Polygon:
    return affinity.translate(polygon, ORIGIN_X, ORIGIN_Y)


def sample_features() -> list[SampleFeature]:
    """All polygons of the sample layer, valid, in world coordinates."""
    rng = np.random.default_rng(SEED)
    water = river()
    lake_shape = lake(rng)
    features = [
        SampleFeature("Sine river", "river", with_terrain_z(water)),
        SampleFeature("Basin lake", "lake", with_terrain_z(lake_shape)),
    ]
    for number, shape in enumerate(buildings(rng, water.union(lake_shape)), start=1):
        features.append(SampleFeature(f"Building {number}", "roof", shape))
    for feature in features:
        feature.polygon = to_world(feature.polygon)
        if not feature.polygon.is_valid:
            raise RuntimeError(f"generated an invalid polygon: {feature.name}")
        if not np.isfinite(shapely.get_coordinates(feature.polygon, include_z=True)).all():
            raise RuntimeError(f"generated a polygon without z: {feature.name}")
    return features


def write_polygons(path: Path, features: list[SampleFeature], layer_name: str = "features") -> None:
    """Write the features as a PolygonZ GeoPackage layer with name and kind attributes."""
    if path.exists():
        path.unlink()
    dataset = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    layer = dataset.CreateLayer(layer_name, spatial_reference(), ogr.wkbPolygon25D)
    for field_name in ("name", "kind"):
        layer.CreateField(ogr.FieldDefn(field_name, ogr.OFTString))
    for feature in features:
        ogr_feature = ogr.Feature(layer.GetLayerDefn())
        ogr_feature.SetField("name", feature.name)
        ogr_feature.SetField("kind", feature.kind)
        wkb = shapely.to_wkb(feature.polygon, output_dimension=3, flavor="iso")
        ogr_feature.SetGeometry(ogr.CreateGeometryFromWkb(wkb))
        layer.CreateFeature(ogr_feature)
    dataset = None


def make_sample_data(output_dir: Path = DEFAULT_OUTPUT) -> tuple[Path, Path]:
    """Write terrain.tif and polygons.gpkg into output_dir; return their paths."""
    output_dir.mkdir(parents=True, exist_ok=True)
    terrain_path = output_dir / "terrain.tif"
    polygons_path = output_dir / "polygons.gpkg"
    write_terrain(terrain_path)
    write_polygons(polygons_path, sample_features())
    return terrain_path, polygons_path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output_dir", nargs="?", type=Path, default=DEFAULT_OUTPUT)
    arguments = parser.parse_args()
    for path in make_sample_data(arguments.output_dir):
        print(path)


if __name__ == "__main__":
    main()
