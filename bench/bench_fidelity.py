"""Terrain fidelity of the meshes on real data (Swellendam farms and buffered rivers, SRTM DEM).

Every polygon vertex gets its z from the DEM (bilinear). Each triangulation's surface is then
compared with the DEM at the centres of the DEM cells inside the polygon: the point's
containing triangle is found and its z interpolated barycentrically. One table per layer, a
row per method: rules "first", "elevation" and "delaunay", mapbox_earcut and GEOS constrained
Delaunay on the boundary vertices alone; rule "delaunay" with DEM cell centres added inside by
``terrain/refine.py`` until every cell is within 10, 5 and 2 m; pydelatin's greedy mesh of the
whole DEM at the same tolerances (its vertices inside the polygons counted, its surface
measured inside them). Columns: RMS and max |surface - DEM|, points added, triangles, median
of the triangles' smallest angles, share of triangles under 5 degrees, time. A refined mesh
over its tolerance prints a FAIL line. Then, for the farms' final 5 m rings and points, our
engine against the compiled triangulator ``triangle`` (``bench_cdt.py``).

pydelatin and triangle are benchmark-only (``pip install pydelatin triangle``); their rows are
skipped, saying so, when they are missing.

Usage: python bench/bench_fidelity.py [--quick] [--densify 100] [--no-compiled]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import bench_cdt
import mapbox_earcut
import numpy as np
import shapely
from common import SHARED_DATA, BudgetExceededError, Row, markdown_table, timed, within
from osgeo import gdal, ogr
from real_data import layer_geometries

from bsp_triangulate import triangulate_many
from bsp_triangulate.terrain.densify import densify_rings
from bsp_triangulate.terrain.raster_sampling import fill_along_ring, sample_grid
from bsp_triangulate.terrain.refine import CellGrid, locate_cells, refine_many

SWELLENDAM = SHARED_DATA / "swellendam"
DEM_PATH = SWELLENDAM / "srtm_41_19.tif"
FARMS = SWELLENDAM / "farms_33S.shp"
RIVERS = SWELLENDAM / "rivers.shp"
RIVER_BUFFER = 50.0
QUICK_FARMS = 300
DEFAULT_BUDGET = 1_800.0  # seconds per method and layer before it is abandoned
TOLERANCES = (10.0, 5.0, 2.0)  # metres, the refinements' and pydelatin's
MAX_POINTS = 1_000_000  # per polygon: no cap in practice, so every cell can be met
SLIVER_DEGREES = 5.0
TOLERANCE_SLACK = 1e-6  # metres of rounding allowed over a tolerance
REPEAT = 3  # calls of the boundary-only methods and pydelatin: the best time
CDT_METHOD = 'rule "delaunay" + DEM points, 5 m'
CDT_CASE = "farms, final rings and points of the 5 m refinement: ours against triangle"

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

    @property
    def grid(self) -> CellGrid:
        return CellGrid.from_array(self.values, self.geotransform)

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
    geometries = layer_geometries(path)
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
    """(cell keys, surface z) of every DEM cell centre covered by a triangle of each mesh
    (``terrain.refine.locate_cells``; a centre on a shared edge keeps its first hit)."""
    columns = dem.values.shape[1]
    cells = dem.values.size
    corners, owners = [], []
    for number, (vertices, triangles) in enumerate(meshes):
        if len(triangles):
            corners.append(vertices[triangles])
            owners.append(np.full(len(triangles), number, np.int64))
    if not corners:
        return np.zeros(0, np.int64), np.zeros(0)
    owner = np.concatenate(owners)
    triangle, row, col, z = locate_cells(np.concatenate(corners), [dem.grid])
    keys, first = np.unique(owner[triangle] * cells + row * columns + col, return_index=True)
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
    return fidelity_at(keys, surface, cells, dem, sum(len(triangles) for _, triangles in meshes))


def fidelity_at(
    keys: np.ndarray, surface: np.ndarray, cells: np.ndarray, dem: Dem, triangles: int
) -> Fidelity:
    """Fidelity at ``cells`` given the surface's sorted cell ``keys`` and heights."""
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
        triangles,
    )


def minimum_angles(corners: np.ndarray) -> np.ndarray:
    """The smallest angle (degrees, in XY) of each triangle of ``corners`` (t, 3, >=2)."""
    xy = np.asarray(corners, dtype=np.float64)[:, :, :2]
    sides = np.roll(xy, -1, axis=1) - xy  # side i runs from corner i to corner i + 1
    lengths = np.linalg.norm(sides, axis=2)
    angles = []
    for i in range(3):
        u, v = sides[:, i], -sides[:, i - 1]  # both leave corner i
        cross = np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
        dot = (u * v).sum(1)
        angles.append(np.degrees(np.arctan2(cross, dot)))
    smallest = np.min(angles, axis=0)
    return np.where(lengths.min(1) > 0, smallest, 0.0)


def mesh_angles(meshes: list[Mesh]) -> np.ndarray:
    corners = [vertices[triangles] for vertices, triangles in meshes if len(triangles)]
    return minimum_angles(np.concatenate(corners)) if corners else np.zeros(0)


@dataclass
class Outcome:
    """One method on one layer: its fidelity, the points it added, the smallest angle of each
    triangle, its time (s) and, for the refinements, what the refinement itself reported."""

    fidelity: Fidelity
    added: int
    angles: np.ndarray
    seconds: float
    note: str = ""
    points: list[np.ndarray] | None = None  # the refinements' interior points per polygon

    @property
    def median_angle(self) -> float:
        return float(np.median(self.angles)) if len(self.angles) else float("nan")

    @property
    def slivers(self) -> float:
        """Share of the triangles whose smallest angle is under SLIVER_DEGREES."""
        return float((self.angles < SLIVER_DEGREES).mean()) if len(self.angles) else float("nan")


@dataclass
class Layer:
    """A data set: its polygons, their rings with z from the DEM, the cells inside them."""

    name: str
    shapes: list[shapely.Polygon]
    polygons: list[Rings]
    cells: np.ndarray

    @property
    def label(self) -> str:
        vertices = sum(len(ring) for rings in self.polygons for ring in rings)
        return (
            f"{self.name}: {len(self.shapes):,} polygons, {vertices:,} vertices, "
            f"{len(self.cells):,} DEM cells inside"
        )


def rebuilt(polygons: list[Rings], rule: str, points: list[np.ndarray] | None = None) -> list[Mesh]:
    """The meshes of ``triangulate_many``; a polygon the engine rejects gets an empty mesh
    (its cells then count as uncovered)."""
    results = triangulate_many(polygons, rule=rule, points=points, plane="xy", on_error="return")
    empty = (np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    return [
        (result.vertices, result.triangles) if hasattr(result, "triangles") else empty
        for result in results
    ]


def meshes_ours(polygons: list[Rings], rule: str) -> list[Mesh]:
    return rebuilt(polygons, rule)


def boundary_method(build: Callable[[list[Rings]], list[Mesh]]) -> Callable[..., Outcome]:
    """A method on the boundary vertices alone: best of ``REPEAT`` calls."""

    def measure(layer: Layer, dem: Dem) -> Outcome:
        seconds, meshes = timed(lambda: build(layer.polygons), REPEAT)
        return Outcome(fidelity(meshes, layer.cells, dem), 0, mesh_angles(meshes), seconds)

    return measure


def refined(tolerance: float) -> Callable[..., Outcome]:
    """Rule "delaunay" with DEM points added by ``refine_many`` until within ``tolerance``.

    The time is ``refine_many``'s (its rounds of triangulation and error measurement, the
    last round triangulating with every point); the mesh is then built again to measure it.
    """

    def measure(layer: Layer, dem: Dem) -> Outcome:
        grid = dem.grid
        start = time.perf_counter()
        results = refine_many(
            layer.polygons,
            [grid] * len(layer.polygons),
            tolerance,
            MAX_POINTS,
            engine=triangulate_many,
            rule="delaunay",
            plane="xy",
        )
        seconds = time.perf_counter() - start
        points = [result.points for result in results]
        meshes = rebuilt(layer.polygons, "delaunay", points)
        capped = sum(result.capped for result in results)
        failed = sum(result.error is not None for result in results)
        outside = sum(not result.within for result in results)
        note = f"{max(result.rounds for result in results)} rounds, reported max "
        note += f"{max(result.max_error for result in results):.2f} m"
        note += f", {outside} not within" if outside else ""
        note += f", {capped} capped" if capped else ""
        note += f", {failed} failed" if failed else ""
        return Outcome(
            fidelity(meshes, layer.cells, dem),
            sum(result.added for result in results),
            mesh_angles(meshes),
            seconds,
            note,
            points,
        )

    return measure


def pydelatin_method(tolerance: float) -> Callable[..., Outcome]:
    """pydelatin's greedy mesh of the whole DEM at ``tolerance``, seen inside the polygons.

    Points: its vertices strictly inside a polygon, counted once per polygon holding them, as
    each polygon's mesh has its own points (the farm layer covers its area twice over);
    fidelity: its surface at the cells inside the polygons; angles: its triangles whose
    centroid is inside one; time: the whole DEM.
    """

    def measure(layer: Layer, dem: Dem) -> Outcome:
        from pydelatin import Delatin

        rows, columns = dem.values.shape
        heights = dem.values.astype(np.float32)
        seconds, tin = timed(
            lambda: Delatin(heights, height=rows, width=columns, max_error=tolerance), REPEAT
        )
        # its vertices are (column, rows up from the last row): the cells' centres
        column = tin.vertices[:, 0].astype(np.int64)
        row = rows - 1 - tin.vertices[:, 1].astype(np.int64)
        vertices = np.column_stack([dem.centre_x(column), dem.centre_y(row), tin.vertices[:, 2]])
        triangles = np.asarray(tin.triangles, np.int64)
        keys, surface = surface_at_cells([(vertices, triangles)], dem)
        whole = fidelity_at(keys, surface, np.arange(dem.values.size), dem, len(triangles))
        measured = fidelity_at(keys, surface, layer.cells % dem.values.size, dem, 0)
        tree = shapely.STRtree(layer.shapes)
        # (vertex, polygon) pairs: a vertex inside two overlapping polygons counts in both
        inside_pairs = tree.query(shapely.points(vertices[:, :2]), predicate="within")[0]
        centroids = shapely.points(vertices[triangles, :2].mean(1))
        kept = np.unique(tree.query(centroids, predicate="within")[0])
        measured.triangles = len(kept)
        note = f"{len(vertices):,} vertices and max {whole.maximum:.2f} m over the whole DEM"
        return Outcome(
            measured,
            len(inside_pairs),
            minimum_angles(vertices[triangles[kept]]),
            seconds,
            note,
        )

    return measure


def methods(
    densify: float | None, boundary_only: bool = False
) -> dict[str, Callable[[Layer, Dem], Outcome]]:
    """The compared methods by label; the refinements and pydelatin only without densify
    and without ``boundary_only``."""
    chosen: dict[str, Callable[[Layer, Dem], Outcome]] = {
        f'rule "{rule}"': boundary_method(lambda polygons, rule=rule: meshes_ours(polygons, rule))
        for rule in ("first", "elevation", "delaunay")
    }
    chosen["mapbox_earcut"] = boundary_method(meshes_earcut)
    chosen["GEOS constrained Delaunay"] = boundary_method(meshes_geos)
    if densify or boundary_only:
        return chosen
    for tolerance in TOLERANCES:
        chosen[f'rule "delaunay" + DEM points, {tolerance:g} m'] = refined(tolerance)
    if importlib.util.find_spec("pydelatin") is None:
        print("pydelatin is not installed (pip install pydelatin): its rows are skipped")
    else:
        for tolerance in TOLERANCES:
            chosen[f"pydelatin (whole DEM), {tolerance:g} m"] = pydelatin_method(tolerance)
    return chosen


def tolerance_of(method: str) -> float | None:
    """The tolerance a refined method must meet (None for the others)."""
    if "+ DEM points" not in method and not method.startswith("pydelatin"):
        return None
    return float(method.rsplit(", ", 1)[1].removesuffix(" m"))


def load_layers(
    dem: Dem, quick: bool, densify: float | None, farms: int | None = None
) -> list[Layer]:
    """The farms (the first ``farms``, or QUICK_FARMS with ``quick``) and the buffered rivers."""
    shapes = {
        "farms": read_polygons(FARMS, limit=farms or (QUICK_FARMS if quick else None)),
        f"rivers buffered {RIVER_BUFFER:.0f} m": read_polygons(
            RIVERS, buffer=RIVER_BUFFER, clip=dem.box()
        ),
    }
    layers = []
    for name, polygons in shapes.items():
        name += f", boundaries densified to {densify:g} m" if densify else ""
        rings = [polygon_rings(shape, dem, densify) for shape in polygons]
        layers.append(Layer(name, polygons, rings, evaluation_cells(polygons, dem)))
    return layers


def layer_results(
    layer: Layer,
    dem: Dem,
    budget: float | None,
    densify: float | None = None,
    boundary_only: bool = False,
) -> list[tuple[str, Outcome | str]]:
    """(method, outcome or why it has none) of every method on one layer, each method in a
    forked child stopped after ``budget`` seconds."""
    results: list[tuple[str, Outcome | str]] = []
    for method, measure in methods(densify, boundary_only).items():
        try:
            outcome = within(lambda measure=measure: measure(layer, dem), budget)
        except BudgetExceededError:
            outcome = f"> {budget:.0f} s (stopped)"
        except RuntimeError as error:
            outcome = f"failed: {error}"
        print(f"  {layer.name}: {method} done", file=sys.stderr, flush=True)
        results.append((method, outcome))
    return results


def failures(layer: Layer, results: list[tuple[str, Outcome | str]]) -> list[str]:
    """FAIL lines: a refined mesh or pydelatin's over its tolerance, or cells uncovered."""
    lines = []
    for method, outcome in results:
        tolerance = tolerance_of(method)
        if tolerance is None:
            continue
        if isinstance(outcome, str):
            lines.append(f"FAIL: {layer.name}, {method}: {outcome}")
            continue
        f = outcome.fidelity
        if not f.maximum <= tolerance + TOLERANCE_SLACK:
            lines.append(f"FAIL: {layer.name}, {method}: max {f.maximum:.3f} m > {tolerance:g} m")
        if f.uncovered:
            lines.append(f"FAIL: {layer.name}, {method}: {f.uncovered:,} cells uncovered")
    return lines


POINTS_TARGET = 1.3  # our points added at most this many times pydelatin's


def point_ratios(layer: Layer, results: list[tuple[str, Outcome | str]]) -> list[Row]:
    """Per tolerance: our points added over pydelatin's vertices inside the polygons."""
    outcomes = {method: outcome for method, outcome in results if isinstance(outcome, Outcome)}
    rows = []
    for tolerance in TOLERANCES:
        ours = outcomes.get(f'rule "delaunay" + DEM points, {tolerance:g} m')
        theirs = outcomes.get(f"pydelatin (whole DEM), {tolerance:g} m")
        if ours is None or theirs is None or not theirs.added:
            continue
        ratio = ours.added / theirs.added
        verdict = "met" if ratio <= POINTS_TARGET else "missed"
        note = f"{ours.added:,} / {theirs.added:,}; target at most {POINTS_TARGET:g}x: {verdict}"
        rows.append(
            Row(layer.label, f"points added / pydelatin's, {tolerance:g} m", ratio, "x", note)
        )
    return rows


HEADERS = (
    "triangulation",
    "RMS (m)",
    "max (m)",
    "points added",
    "triangles",
    "median min angle (°)",
    "under 5°",
    "time (s)",
)


def layer_table(results: list[tuple[str, Outcome | str]]) -> str:
    rows = []
    for method, outcome in results:
        if isinstance(outcome, str):
            rows.append((method, outcome, "", "", "", "", "", ""))
            continue
        f = outcome.fidelity
        maximum = f"{f.maximum:.2f}" + (f" ({f.uncovered:,} uncovered)" if f.uncovered else "")
        rows.append(
            (
                method,
                f"{f.rms:.2f}",
                maximum,
                f"{outcome.added:,}",
                f"{f.triangles:,}",
                f"{outcome.median_angle:.1f}",
                f"{outcome.slivers:.1%}",
                outcome.seconds,
            )
        )
    return markdown_table(HEADERS, rows)


def result_rows(layer: Layer, results: list[tuple[str, Outcome | str]]) -> list[Row]:
    rows = []
    for method, outcome in results:
        if isinstance(outcome, str):
            rows.append(Row(layer.label, f"{method}: RMS of surface - DEM", outcome))
            continue
        f = outcome.fidelity
        note = (
            f"max {f.maximum:.2f} m, {outcome.added:,} points added, {f.triangles:,} triangles, "
            f"median min angle {outcome.median_angle:.1f}°, {outcome.slivers:.1%} under 5°, "
            f"{outcome.seconds:.2f} s"
        )
        note += f", {f.uncovered:,} cells uncovered" if f.uncovered else ""
        note += f"; {outcome.note}" if outcome.note else ""
        rows.append(Row(layer.label, f"{method}: RMS of surface - DEM", f.rms, "m", note))
    return rows


def run_tables(
    quick: bool = False,
    budget: float | None = DEFAULT_BUDGET,
    densify: float | None = None,
    compiled: bool = True,
    farms: int | None = None,
    boundary_only: bool = False,
) -> tuple[str, list[Row]]:
    """The Markdown tables (one per layer, then the FAIL lines and the compiled-CDT ratio)
    and the same as rows for run_all."""
    dem = Dem.read(DEM_PATH)
    text, rows, failed = [], [], []
    cdt_input = None
    for layer in load_layers(dem, quick, densify, farms):
        results = layer_results(layer, dem, budget, densify, boundary_only)
        text += [f"**{layer.label}**", "", layer_table(results), ""]
        ratios = point_ratios(layer, results)
        if ratios:
            text += [
                "Points added / pydelatin's vertices inside: "
                + "; ".join(
                    f"{r.measure.rsplit(', ', 1)[1]} {r.value:.2f}x ({r.note})" for r in ratios
                ),
                "",
            ]
        rows += result_rows(layer, results) + ratios
        failed += failures(layer, results)
        outcome = dict(results).get(CDT_METHOD)
        if layer.name == "farms" and isinstance(outcome, Outcome):
            cdt_input = (layer.polygons, outcome.points)
    text += failed or ["All refined meshes are within their tolerance."]
    rows += [Row("fidelity check", "FAIL", line) for line in failed]
    if compiled and cdt_input is not None:
        table, cdt_rows = bench_cdt.compare(*cdt_input, budget, rounds=1 if quick else 5)
        text += ["", f"**{CDT_CASE}**", "", table]
        rows += [Row(CDT_CASE, row.measure, row.value, row.unit, row.note) for row in cdt_rows]
    return "\n".join(text), rows


def run_table(quick: bool = False, budget: float | None = DEFAULT_BUDGET) -> tuple[str, list[Row]]:
    """The Markdown tables and the rows (as ``run_tables`` with its defaults)."""
    return run_tables(quick, budget)


def run(
    quick: bool = False,
    budget: float | None = DEFAULT_BUDGET,
    count: int | None = None,
    farms: int | None = None,
) -> list[Row]:
    """Fidelity rows (``count`` is not used: the data set is fixed; ``farms``: the first
    farms only)."""
    tables, rows = run_tables(quick, budget, farms=farms)
    print(tables, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"first {QUICK_FARMS} farms only")
    parser.add_argument(
        "--budget", type=float, default=DEFAULT_BUDGET, help="seconds per method at most"
    )
    parser.add_argument(
        "--densify",
        type=float,
        help="densify the boundaries to segments of at most this length (m) first "
        "(boundary-only methods then)",
    )
    parser.add_argument("--farms", type=int, help="the first N farms only (overrides --quick)")
    parser.add_argument(
        "--no-compiled", action="store_true", help="skip the compiled constrained-Delaunay ratio"
    )
    parser.add_argument(
        "--boundary-only",
        action="store_true",
        help="the boundary-only methods (no DEM points, no pydelatin): the whole layers in minutes",
    )
    arguments = parser.parse_args()
    tables, _rows = run_tables(
        arguments.quick,
        arguments.budget,
        arguments.densify,
        not arguments.no_compiled,
        arguments.farms,
        arguments.boundary_only,
    )
    print(tables)


if __name__ == "__main__":
    main()
