"""Terrain fidelity of the meshes on real data (Swellendam farms and buffered rivers, SRTM DEM).

Every polygon vertex gets its z from the DEM (bilinear). Each triangulation's surface is then
compared with the DEM at the centres of the DEM cells inside the polygon: the point's
containing triangle is found and its z interpolated barycentrically. Reported: RMS and maximum
of |surface - DEM| for rule "first", rule "elevation", mapbox_earcut and GEOS constrained
Delaunay, all on the same vertices; then the same after densifying the boundaries (segments of
at most 100 m, new points' z from the DEM).

Usage: python bench/bench_fidelity.py [--quick]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mapbox_earcut
import numpy as np
import shapely
from common import SHARED_DATA, BudgetExceededError, Row, markdown_table, within
from osgeo import gdal, ogr, osr

from bsp_triangulate import triangulate_many
from bsp_triangulate.terrain.densify import densify_rings
from bsp_triangulate.terrain.raster_sampling import fill_along_ring, sample_grid

SWELLENDAM = SHARED_DATA / "swellendam"
DEM_PATH = SWELLENDAM / "srtm_41_19.tif"
FARMS = SWELLENDAM / "farms_33S.shp"
RIVERS = SWELLENDAM / "rivers.shp"
RIVER_BUFFER = 50.0
DENSIFY = 100.0
QUICK_FARMS = 300
DEFAULT_BUDGET = 1_800.0  # seconds per triangulation run before it is abandoned
CHUNK = 2_000_000  # candidate (triangle, cell) pairs per numpy batch

gdal.UseExceptions()
ogr.UseExceptions()

Rings = list[np.ndarray]
Mesh = tuple[np.ndarray, np.ndarray]  # vertices (n, 3), triangles (m, 3)


@dataclass
class Dem:
    """The DEM's cells as float64, its geotransform (north-up) and the cell centres' axes."""

    values: np.ndarray
    geotransform: tuple[float, ...]

    @classmethod
    def read(cls, path: Path) -> Dem:
        dataset = gdal.Open(str(path))
        geotransform = dataset.GetGeoTransform()
        if geotransform[2] or geotransform[4]:
            raise ValueError("only north-up DEMs are supported")
        return cls(dataset.GetRasterBand(1).ReadAsArray().astype(np.float64), geotransform)

    def z(self, xy: np.ndarray) -> np.ndarray:
        """Bilinear heights along a ring; vertices just off the DEM take their neighbours'."""
        values = sample_grid(self.values, self.geotransform, xy[:, 0], xy[:, 1], "bilinear")
        return fill_along_ring(values, xy)

    def box(self) -> shapely.Polygon:
        """The area within which every point has four cell centres around it."""
        x0, width, _, y0, _, height = self.geotransform
        rows, columns = self.values.shape
        return shapely.box(
            x0 + width / 2,
            y0 + (rows - 0.5) * height,
            x0 + (columns - 0.5) * width,
            y0 + height / 2,
        )

    def centre_x(self, columns: np.ndarray) -> np.ndarray:
        return self.geotransform[0] + (columns + 0.5) * self.geotransform[1]

    def centre_y(self, rows: np.ndarray) -> np.ndarray:
        return self.geotransform[3] + (rows + 0.5) * self.geotransform[5]

    def column_range(self, xmin: np.ndarray, xmax: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last column whose centre lies in [xmin, xmax] (empty when first > last)."""
        x0, width = self.geotransform[0], self.geotransform[1]
        first = np.ceil((xmin - x0) / width - 0.5).astype(np.int64)
        last = np.floor((xmax - x0) / width - 0.5).astype(np.int64)
        return np.maximum(first, 0), np.minimum(last, self.values.shape[1] - 1)

    def row_range(self, ymin: np.ndarray, ymax: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last row whose centre lies in [ymin, ymax] (rows go south)."""
        y0, height = self.geotransform[3], self.geotransform[5]
        first = np.ceil((ymax - y0) / height - 0.5).astype(np.int64)
        last = np.floor((ymin - y0) / height - 0.5).astype(np.int64)
        return np.maximum(first, 0), np.minimum(last, self.values.shape[0] - 1)


def read_polygons(
    path: Path, buffer: float = 0.0, limit: int | None = None, clip: shapely.Polygon | None = None
) -> list:
    """Valid polygons of a layer in EPSG:32733 (lines buffered, clipped), multi-parts split."""
    dataset = ogr.Open(str(path))
    layer = dataset.GetLayer(0)
    target = osr.SpatialReference()
    target.ImportFromEPSG(32733)
    target.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    source = layer.GetSpatialRef()
    source.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    transform = None if source.IsSame(target) else osr.CoordinateTransformation(source, target)
    geometries = []
    # a corrupt record must not stop the layer (GDAL reports it and returns no geometry)
    raised = ogr.GetUseExceptions()
    ogr.DontUseExceptions()
    try:
        for feature in layer:
            geometry = feature.GetGeometryRef()
            if geometry is None:
                continue
            geometry = geometry.Clone()
            if transform is not None:
                geometry.Transform(transform)
            geometries.append(shapely.from_wkb(bytes(geometry.ExportToIsoWkb())))
    finally:
        if raised:
            ogr.UseExceptions()
    geometries = shapely.force_2d(np.array(geometries))
    if buffer:
        geometries = shapely.buffer(geometries, buffer, quad_segs=4)
    if clip is not None:
        geometries = shapely.intersection(geometries, clip)
    parts = shapely.get_parts(geometries)
    parts = parts[shapely.get_type_id(parts) == 3]
    parts = parts[shapely.is_valid(parts) & (shapely.area(parts) > 0)]
    return list(parts[:limit] if limit else parts)


def polygon_rings(polygon: shapely.Polygon, dem: Dem, densify: float | None) -> Rings:
    """Rings without the closing point, optionally densified, with z from the DEM."""
    rings = [shapely.get_coordinates(polygon.exterior)[:-1]]
    rings += [shapely.get_coordinates(ring)[:-1] for ring in polygon.interiors]
    if densify:
        rings = densify_rings(rings, densify)
    return [np.column_stack([ring[:, :2], dem.z(ring)]) for ring in rings]


def meshes_ours(polygons: list[Rings], rule: str) -> list[Mesh]:
    # a polygon the engine rejects gets an empty mesh: its cells count as uncovered
    results = triangulate_many(polygons, rule=rule, on_error="return")
    return [
        (result.vertices, result.triangles)
        if hasattr(result, "triangles")
        else (np.zeros((0, 3)), np.zeros((0, 3), np.int64))
        for result in results
    ]


def meshes_earcut(polygons: list[Rings]) -> list[Mesh]:
    meshes = []
    for rings in polygons:
        vertices = np.vstack(rings)
        ends = np.cumsum([len(ring) for ring in rings]).astype(np.uint32)
        indices = mapbox_earcut.triangulate_float64(np.ascontiguousarray(vertices[:, :2]), ends)
        meshes.append((vertices, indices.reshape(-1, 3).astype(np.int64)))
    return meshes


def meshes_geos(polygons: list[Rings]) -> list[Mesh]:
    """GEOS's triangles, their corners matched back to the input vertices (and their z) by XY."""
    shapes = [
        shapely.Polygon(rings[0][:, :2], [ring[:, :2] for ring in rings[1:]]) for rings in polygons
    ]
    collections = shapely.constrained_delaunay_triangles(np.array(shapes))
    meshes = []
    for rings, collection in zip(polygons, collections):
        vertices = np.vstack(rings)
        triangles = shapely.get_parts(collection)
        corners = shapely.get_coordinates(shapely.get_exterior_ring(triangles))
        corners = corners.reshape(len(triangles), 4, 2)[:, :3].reshape(-1, 2)
        keys = np.ascontiguousarray(vertices[:, :2]).view([("x", "f8"), ("y", "f8")]).ravel()
        order = np.argsort(keys, kind="stable")
        wanted = np.ascontiguousarray(corners).view([("x", "f8"), ("y", "f8")]).ravel()
        position = np.searchsorted(keys[order], wanted)
        index = order[np.minimum(position, len(order) - 1)]
        if not np.array_equal(keys[index], wanted):
            raise RuntimeError("GEOS returned a vertex that is not an input vertex")
        meshes.append((vertices, index.reshape(-1, 3)))
    return meshes


def evaluation_cells(polygons: list[shapely.Polygon], dem: Dem) -> np.ndarray:
    """Keys (polygon * cells + row * columns + column) of the DEM cells centred inside each."""
    columns = dem.values.shape[1]
    cells = dem.values.size
    keys = []
    for number, polygon in enumerate(polygons):
        xmin, ymin, xmax, ymax = polygon.bounds
        c0, c1 = dem.column_range(np.array(xmin), np.array(xmax))
        r0, r1 = dem.row_range(np.array(ymin), np.array(ymax))
        if c1 < c0 or r1 < r0:
            continue
        cols, rows = np.meshgrid(np.arange(c0, c1 + 1), np.arange(r0, r1 + 1))
        cols, rows = cols.ravel(), rows.ravel()
        inside = shapely.contains_xy(polygon, dem.centre_x(cols), dem.centre_y(rows))
        keys.append(number * cells + rows[inside] * columns + cols[inside])
    return np.concatenate(keys) if keys else np.zeros(0, np.int64)


def surface_at_cells(meshes: list[Mesh], dem: Dem) -> tuple[np.ndarray, np.ndarray]:
    """(cell keys, surface z) of every DEM cell centre covered by a triangle of each mesh.

    Each triangle enumerates the cell centres of its bounding box; barycentric coordinates
    decide containment (with a tiny tolerance, so shared edges count for both triangles and the
    first hit is kept) and give the interpolated z.
    """
    columns = dem.values.shape[1]
    cells = dem.values.size
    corners, owners = [], []
    for number, (vertices, triangles) in enumerate(meshes):
        if len(triangles):
            corners.append(vertices[triangles])
            owners.append(np.full(len(triangles), number, np.int64))
    if not corners:
        return np.zeros(0, np.int64), np.zeros(0)
    xyz = np.concatenate(corners)  # (t, 3, 3)
    owner = np.concatenate(owners)
    c0, c1 = dem.column_range(xyz[:, :, 0].min(1), xyz[:, :, 0].max(1))
    r0, r1 = dem.row_range(xyz[:, :, 1].min(1), xyz[:, :, 1].max(1))
    width = np.maximum(c1 - c0 + 1, 0)
    height = np.maximum(r1 - r0 + 1, 0)
    counts = width * height
    all_keys, all_z = [], []
    starts = np.concatenate([[0], np.cumsum(counts)])
    batch_start = 0
    while batch_start < len(counts):
        batch_end = int(np.searchsorted(starts, starts[batch_start] + CHUNK, side="right")) - 1
        batch_end = max(batch_end, batch_start + 1)
        batch = np.arange(batch_start, min(batch_end, len(counts)))
        triangle = np.repeat(batch, counts[batch])
        offset = np.arange(len(triangle)) - np.repeat(
            starts[batch] - starts[batch[0]], counts[batch]
        )
        col = c0[triangle] + offset % width[triangle]
        row = r0[triangle] + offset // np.maximum(width[triangle], 1)
        px, py = dem.centre_x(col), dem.centre_y(row)
        a, b, c = xyz[triangle, 0], xyz[triangle, 1], xyz[triangle, 2]
        det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        with np.errstate(invalid="ignore", divide="ignore"):
            wb = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / det
            wc = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
            wa = 1.0 - wb - wc
            z = wa * a[:, 2] + wb * b[:, 2] + wc * c[:, 2]
        tolerance = -1e-9
        hit = (det != 0) & (wa >= tolerance) & (wb >= tolerance) & (wc >= tolerance)
        all_keys.append(owner[triangle[hit]] * cells + row[hit] * columns + col[hit])
        all_z.append(z[hit])
        batch_start = batch_end
    keys = np.concatenate(all_keys)
    z = np.concatenate(all_z)
    keys, first = np.unique(keys, return_index=True)
    return keys, z[first]


@dataclass
class Fidelity:
    """RMS and maximum |surface - DEM| (m) over the evaluated cells, and coverage."""

    rms: float
    maximum: float
    evaluated: int
    uncovered: int
    triangles: int


def fidelity(meshes: list[Mesh], cells: np.ndarray, dem: Dem) -> Fidelity:
    keys, surface = surface_at_cells(meshes, dem)
    position = np.searchsorted(keys, cells)
    position = np.minimum(position, max(len(keys) - 1, 0))
    covered = (keys[position] == cells) if len(keys) else np.zeros(len(cells), bool)
    cell_index = cells[covered] % dem.values.size
    difference = surface[position[covered]] - dem.values.ravel()[cell_index]
    return Fidelity(
        float(np.sqrt(np.mean(difference**2))) if len(difference) else float("nan"),
        float(np.abs(difference).max()) if len(difference) else float("nan"),
        int(covered.sum()),
        int((~covered).sum()),
        sum(len(triangles) for _, triangles in meshes),
    )


METHODS: dict[str, Callable[[list[Rings]], list[Mesh]]] = {
    'bsp_triangulate rule "first"': lambda polygons: meshes_ours(polygons, "first"),
    'bsp_triangulate rule "elevation"': lambda polygons: meshes_ours(polygons, "elevation"),
    "mapbox_earcut": meshes_earcut,
    "GEOS constrained Delaunay": meshes_geos,
}


def layer_results(
    name: str, shapes: list[shapely.Polygon], dem: Dem, budget: float | None
) -> list[tuple[str, str, Fidelity | str]]:
    cells = evaluation_cells(shapes, dem)
    results = []
    for densify in (None, DENSIFY):
        polygons = [polygon_rings(shape, dem, densify) for shape in shapes]
        vertices = sum(len(ring) for rings in polygons for ring in rings)
        label = f"{name}, {len(shapes):,} polygons, {vertices:,} vertices"
        label += f", densified to {DENSIFY:.0f} m" if densify else ""
        for method, build in METHODS.items():
            try:
                meshes = within(lambda build=build, polygons=polygons: build(polygons), budget)
            except BudgetExceededError:
                results.append((label, method, f"> {budget:.0f} s (stopped)"))
                continue
            except RuntimeError as error:
                results.append((label, method, f"failed: {error}"))
                continue
            results.append((label, method, fidelity(meshes, cells, dem)))
    return results


def run_table(quick: bool = False, budget: float | None = DEFAULT_BUDGET) -> tuple[str, list[Row]]:
    """The Markdown table of fidelity figures and the same as rows for run_all."""
    dem = Dem.read(DEM_PATH)
    layers = {
        "farms": read_polygons(FARMS, limit=QUICK_FARMS if quick else None),
        f"rivers buffered {RIVER_BUFFER:.0f} m": read_polygons(
            RIVERS, buffer=RIVER_BUFFER, clip=dem.box()
        ),
    }
    results = []
    for name, shapes in layers.items():
        results += layer_results(name, shapes, dem, budget)
    table = markdown_table(
        ["data", "triangulation", "RMS (m)", "max (m)", "cells", "uncovered", "triangles"],
        [
            (label, method, f, "", "", "", "")
            if isinstance(f, str)
            else (label, method, f.rms, f.maximum, f.evaluated, f.uncovered, f.triangles)
            for label, method, f in results
        ],
    )
    rows = []
    for label, method, f in results:
        if isinstance(f, str):
            rows.append(Row(label, f"{method}: RMS of surface - DEM", f))
            continue
        note = f"max {f.maximum:.1f} m over {f.evaluated:,} DEM cells, {f.uncovered:,} uncovered"
        rows.append(Row(label, f"{method}: RMS of surface - DEM", f.rms, "m", note))
    return table, rows


def run(
    quick: bool = False, budget: float | None = DEFAULT_BUDGET, count: int | None = None
) -> list[Row]:
    """Fidelity rows (``count`` is not used: the data set is fixed)."""
    return run_table(quick, budget)[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"first {QUICK_FARMS} farms only")
    parser.add_argument(
        "--budget", type=float, default=DEFAULT_BUDGET, help="seconds per triangulation at most"
    )
    arguments = parser.parse_args()
    print(run_table(arguments.quick, arguments.budget)[0])


if __name__ == "__main__":
    main()
