"""One partition's work, as a Dask task runs it on a worker: its features' geometries to
packed polygons (WKB read in bulk by the engine's reader, invalid polygons repaired or failed
as the plugin does), elevation (the geometry's z, a column, or a DEM window), one
``triangulate_packed`` call, then its triangles as GeoParquet and its mesh as PLY.

Files are written under a temporary name and renamed, so a task that Dask runs again (its
worker died) writes the same files over whatever a lost attempt left.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

from .. import metrics
from ..api import triangulate_packed
from ..formats.mesh import merge_meshes, write_ply
from ..formats.wkb import polygon_table, polygons_from_wkb, triangles_to_multipolygon_wkb
from ..geometry.rings import working_axes
from ..geometry.rings_batch import ragged_index
from ..geometry.validity import proven_valid
from ..packed import PackedPolygons
from ..terrain.raster_sampling import fill_along_ring
from . import dem as dem_window

# the source id of every row, as the partitions carry it
SOURCE_ID = "__bsp_source_id"
TRIANGLE_COLUMNS = (
    ("part", "int32"),
    ("order", "int32"),
    ("parent", "int32"),
    ("depth", "int32"),
    ("side", "int8"),
    ("area_2d", "float64"),
    ("area_3d", "float64"),
    ("min_angle", "float64"),
    ("slope", "float64"),
    ("aspect", "float64"),
)
ELEVATIONS = ("geometry", "column", "dem", "none")
INVALID = ("repair", "fail", "as_given")
MESH_FORMATS = ("ply", "glb", "none")
_WKB_HEADER = 9  # a MultiPolygon's byte order, type and count before its parts


@dataclass(frozen=True)
class Settings:
    """Everything a partition task needs besides its rows (small: it travels with each task)."""

    out_dir: str
    rule: str = "first"
    invalid: str = "repair"
    planar_tolerance: float = 0.0
    elevation: str = "geometry"
    z_column: str | None = None
    dem: dem_window.DemInfo | None = None
    dem_method: str = "bilinear"
    # the layer's CRS where it differs from the DEM's (points are transformed to sample)
    dem_from_crs: str | None = None
    mesh_format: str = "ply"
    # the engine's working plane: "xy" for draped z (DEM, column, none), "auto" (steep faces
    # in their own plane) for the geometry's own z in metres, as the plugin chooses
    plane: str = "xy"
    # source column -> output column (clashing names prefixed with src_)
    attributes: tuple[tuple[str, str], ...] = field(default_factory=tuple)


@dataclass
class _Parts:
    """Candidate polygons of the partition: points, rings, parts and the row owning each."""

    points: np.ndarray
    ring_len: np.ndarray
    part_rings: np.ndarray
    part_owner: np.ndarray
    part_index: np.ndarray  # the part's position within its feature
    part_proven: np.ndarray


def part_name(number: int) -> str:
    return f"part.{number:05d}"


def _type_name(geometry) -> str:
    return geometry.geom_type if geometry is not None else "null"


def _polygonal(geometry) -> list:
    """The Polygon and MultiPolygon members of a geometry (collections searched)."""
    if geometry is None or geometry.is_empty:
        return []
    if geometry.geom_type in ("Polygon", "MultiPolygon"):
        return [geometry]
    if geometry.geom_type == "GeometryCollection":
        return [p for member in shapely.get_parts(geometry) for p in _polygonal(member)]
    return []


def _rings_of(geometries: list) -> list[list[np.ndarray]]:
    """Parts (lists of (n, 3) rings) of polygonal geometries, as the engine's reader reads
    their WKB."""
    parts: list[list[np.ndarray]] = []
    for geometry in geometries:
        wkb = shapely.to_wkb(geometry, output_dimension=3, flavor="iso", byte_order=1)
        polygons, _has_z = polygons_from_wkb(wkb)
        parts += [polygon for polygon in polygons if len(polygon) and len(polygon[0])]
    return parts


class _Reader:
    """Reads a partition's geometries into candidate parts; ``errors`` and ``repaired`` by
    row."""

    def __init__(self, geometries: np.ndarray, invalid: str, walls: bool = False) -> None:
        self.geometries = geometries
        self.invalid = invalid
        self.walls = walls
        count = len(geometries)
        self.errors: dict[int, str] = {}
        self.repaired = np.zeros(count, dtype=bool)
        self.has_z = np.zeros(count, dtype=bool)

    def read(self) -> _Parts:
        geometries = self.geometries
        count = len(geometries)
        wkbs = shapely.to_wkb(geometries, output_dimension=3, flavor="iso", byte_order=1)
        table = polygon_table([b"" if wkb is None else wkb for wkb in wkbs.tolist()])
        self.has_z = table.geometry_z.copy()
        part_owner = np.repeat(np.arange(count), table.geometry_parts)
        outer_filled = table.ring_len[table.part_ring0] > 0
        filled = np.bincount(part_owner[outer_filled], minlength=count) > 0
        if self.invalid == "as_given":
            proven = np.zeros(count, dtype=bool)
            checked = filled
        else:
            proven = proven_valid(table, filled)
            checked = proven.copy()
        use = filled.copy()
        extra: list[tuple[int, list[list[np.ndarray]]]] = []
        # GEOS judges the rest: those not proven valid, and what the bulk reader left
        for row in np.flatnonzero(~checked).tolist():
            geometry = geometries[row]
            if geometry is None or geometry.is_empty:
                use[row] = False
                continue
            if not table.parsed[row] or not filled[row]:
                use[row] = False
                members = _polygonal(geometry)
                if not members:
                    self.errors[row] = f"a {_type_name(geometry)} has no polygon"
                    continue
                self.has_z[row] = bool(shapely.has_z(geometry))
                parts = self._checked(row, geometry, _rings_of(members))
                if parts:
                    extra.append((row, parts))
                continue
            parts = self._checked(row, geometry, None)
            if parts is not None:
                use[row] = False
                if parts:
                    extra.append((row, parts))
        return self._combined(table, part_owner, use, proven, extra)

    def _checked(self, row: int, geometry, parts):
        """None where the table's parts of the row stand as read; else the parts to use
        instead (a repair, or the given ``parts``), [] for none (the row failed or is empty)."""
        if self.invalid == "as_given":
            return parts
        if self.walls and self.has_z[row] and parts is None:
            # GEOS judges in XY, where a wall has no area: walls are left to the engine
            wkb = shapely.to_wkb(geometry, output_dimension=3, flavor="iso", byte_order=1)
            polygons, _has_z = polygons_from_wkb(wkb)
            if any(len(p) and working_axes(p[0]) != (0, 1) for p in polygons):
                return None
        if shapely.is_valid(geometry):
            return parts
        if self.invalid == "fail":
            self.errors[row] = f"invalid polygon ({shapely.is_valid_reason(geometry)})"
            return []
        repaired = _polygonal(shapely.make_valid(geometry))
        if not repaired:
            reason = shapely.is_valid_reason(geometry)
            self.errors[row] = f"invalid polygon that could not be repaired ({reason})"
            return []
        self.repaired[row] = True
        return _rings_of(repaired)

    @staticmethod
    def _combined(table, part_owner, use, proven, extra) -> _Parts:
        """The table's parts of the rows in ``use`` and the ``extra`` parts, by row."""
        keep = use[part_owner]
        part_index = ragged_index(np.zeros(len(use), np.int64), table.geometry_parts)
        rings = ragged_index(table.part_ring0[keep], table.part_rings[keep])
        rows = ragged_index(table.ring_start[rings], table.ring_len[rings])
        points = [table.points[rows]]
        ring_len = [table.ring_len[rings]]
        part_rings = [table.part_rings[keep]]
        owners = [part_owner[keep]]
        indices = [part_index[keep]]
        for row, parts in extra:
            rings_of = [ring for part in parts for ring in part]
            points.append(np.concatenate(rings_of))
            ring_len.append(np.array([len(ring) for ring in rings_of], np.int64))
            part_rings.append(np.array([len(part) for part in parts], np.int64))
            owners.append(np.full(len(parts), row, np.int64))
            indices.append(np.arange(len(parts), dtype=np.int64))
        combined = _Parts(
            np.concatenate(points),
            np.concatenate(ring_len),
            np.concatenate(part_rings),
            np.concatenate(owners),
            np.concatenate(indices),
            np.zeros(0, bool),
        )
        combined.part_proven = proven[combined.part_owner] & use[combined.part_owner]
        if extra:  # the parts in row order (the extras were appended)
            combined = _select(combined, np.argsort(combined.part_owner, kind="stable"))
        return combined


def _select(parts: _Parts, chosen: np.ndarray) -> _Parts:
    """The parts at positions ``chosen`` (in that order), their rings and points."""
    part_ring0 = np.cumsum(parts.part_rings) - parts.part_rings
    ring_start = np.cumsum(parts.ring_len) - parts.ring_len
    rings = ragged_index(part_ring0[chosen], parts.part_rings[chosen])
    rows = ragged_index(ring_start[rings], parts.ring_len[rings])
    return _Parts(
        parts.points[rows],
        parts.ring_len[rings],
        parts.part_rings[chosen],
        parts.part_owner[chosen],
        parts.part_index[chosen],
        parts.part_proven[chosen],
    )


def _ring_owner(parts: _Parts) -> np.ndarray:
    return np.repeat(parts.part_owner, parts.part_rings)


def _fill_rings(parts: _Parts, values: np.ndarray, errors: dict[int, str], no_value: str) -> None:
    """z = ``values`` at every point; a ring's missing values filled along it from its others,
    a ring without any fails its row with ``no_value``."""
    points = parts.points
    points[:, 2] = values
    missing = np.isnan(values)
    if not missing.any():
        return
    ring_of = np.repeat(np.arange(len(parts.ring_len)), parts.ring_len)
    counts = np.bincount(ring_of[missing], minlength=len(parts.ring_len))
    starts = np.cumsum(parts.ring_len) - parts.ring_len
    owners = _ring_owner(parts)
    for ring in np.flatnonzero(counts).tolist():
        row = int(owners[ring])
        if row in errors:
            continue
        if counts[ring] == parts.ring_len[ring]:
            errors[row] = no_value
            continue
        block = points[starts[ring] : starts[ring] + parts.ring_len[ring]]
        block[:, 2] = fill_along_ring(block[:, 2], block[:, :2])


def _elevation(
    parts: _Parts, frame, settings: Settings, has_z: np.ndarray, errors: dict[int, str]
) -> None:
    """z of every candidate point, in place; rows that get none fail in ``errors``."""
    points = parts.points
    point_owner = np.repeat(_ring_owner(parts), parts.ring_len)
    if settings.elevation == "none":
        points[:, 2] = 0.0
    elif settings.elevation == "geometry":
        z = np.where(has_z[point_owner], points[:, 2], 0.0)
        z = np.where(np.isfinite(z), z, np.nan)
        _fill_rings(parts, z, errors, "no vertex of a ring has a Z value")
    elif settings.elevation == "column":
        import pandas as pd

        column = pd.to_numeric(frame[settings.z_column], errors="coerce").to_numpy(float)
        for row in np.flatnonzero(~np.isfinite(column)).tolist():
            errors.setdefault(row, f"{settings.z_column} is null or not a finite number")
        points[:, 2] = column[point_owner]
    else:
        xs, ys = points[:, 0], points[:, 1]
        if settings.dem_from_crs:
            from pyproj import Transformer

            dem_crs = settings.dem.crs_wkt
            to_dem = Transformer.from_crs(settings.dem_from_crs, dem_crs, always_xy=True)
            xs, ys = to_dem.transform(xs, ys)
            xs, ys = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
        values = dem_window.sample(settings.dem, xs, ys, settings.dem_method)
        _fill_rings(parts, values, errors, "no vertex of a ring lies on a valid DEM cell")


def _without_failed(parts: _Parts, errors: dict[int, str]) -> _Parts:
    if not errors:
        return parts
    failed = np.zeros(int(parts.part_owner.max(initial=-1)) + 1, dtype=bool)
    rows = np.array([row for row in errors if row < len(failed)], dtype=np.int64)
    failed[rows] = True
    return _select(parts, np.flatnonzero(~failed[parts.part_owner]))


def _triangulate(parts: _Parts, settings: Settings, errors: dict[int, str]):
    """``triangulate_packed`` of all parts; a failed part fails its row (the first one named)."""
    polygons = PackedPolygons(parts.points, parts.ring_len, parts.part_rings)
    engine_invalid = "as_given" if settings.invalid == "as_given" else "fail"
    outcome = triangulate_packed(
        polygons,
        rule=settings.rule,
        planar_tolerance=settings.planar_tolerance,
        on_error="return",
        invalid=engine_invalid,
        proven=parts.part_proven,
        plane=settings.plane,
    )
    parts_of = np.bincount(parts.part_owner, minlength=int(parts.part_owner.max(initial=-1)) + 1)
    for part in sorted(outcome.errors):
        row = int(parts.part_owner[part])
        if row in errors:
            continue
        where = f" (part {int(parts.part_index[part])})" if parts_of[row] > 1 else ""
        errors[row] = f"cannot be triangulated{where}: {outcome.errors[part]}"
    return outcome


def _write_atomic(path: Path, write) -> None:
    """``write(temporary path)``, then the file renamed to ``path``."""
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        write(temporary)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _geo_metadata(crs, bbox: list[float] | None) -> bytes:
    """The GeoParquet 1.0 ``geo`` metadata of a WKB PolygonZ column named geometry."""
    column = {
        "encoding": "WKB",
        "geometry_types": ["Polygon Z"],
        "crs": crs.to_json_dict() if crs is not None else None,
        "orientation": "counterclockwise",
    }
    if bbox is not None:
        column["bbox"] = bbox
    document = {"version": "1.0.0", "primary_column": "geometry", "columns": {"geometry": column}}
    return json.dumps(document).encode("utf-8")


def _wkb_column(vertices: np.ndarray, triangles: np.ndarray):
    """One WKB PolygonZ per triangle as an arrow binary column, on the engine's buffer."""
    import pyarrow as pa

    buffer = triangles_to_multipolygon_wkb(vertices, triangles)
    size = (len(buffer) - _WKB_HEADER) // max(len(triangles), 1)
    large = len(buffer) >= 2**31
    offsets = _WKB_HEADER + np.arange(len(triangles) + 1, dtype=np.int64) * size
    kind = pa.large_binary() if large else pa.binary()
    offsets = offsets if large else offsets.astype(np.int32)
    return pa.Array.from_buffers(
        kind, len(triangles), [None, pa.py_buffer(offsets), pa.py_buffer(buffer)]
    )


def _triangle_table(frame, settings: Settings, ids, mesh: dict):
    """The arrow table of the triangles: source id and attributes, tree, metrics, geometry."""
    import pyarrow as pa

    rows = mesh["owner"]
    table = pa.table({"feature_id": pa.array(ids[rows])})
    source = [name for name, _out in settings.attributes]
    if source:
        attributes = frame[source].iloc[rows].reset_index(drop=True)
        attributes.columns = [out for _name, out in settings.attributes]
        converted = pa.Table.from_pandas(attributes, preserve_index=False)
        for name, column in zip(converted.column_names, converted.columns):
            table = table.append_column(name, column)
    values = metrics.triangle_metrics(mesh["vertices"], mesh["triangles"])
    for name, dtype in TRIANGLE_COLUMNS:
        column = mesh[name] if name in mesh else values[name]
        table = table.append_column(name, pa.array(np.asarray(column).astype(dtype, copy=False)))
    table = table.append_column("geometry", _wkb_column(mesh["vertices"], mesh["triangles"]))
    return table


def _mesh(parts: _Parts, outcome, errors: dict[int, str]) -> dict:
    """The triangles of the parts whose rows did not fail, one after another."""
    failed = np.zeros(len(outcome), dtype=bool)
    if errors:
        failed_rows = np.zeros(int(parts.part_owner.max(initial=-1)) + 1, dtype=bool)
        failed_rows[[row for row in errors if row < len(failed_rows)]] = True
        failed = failed_rows[parts.part_owner]
    chosen = np.flatnonzero(~failed & (outcome.triangle_count > 0))
    kept = outcome.take(chosen)
    counts = kept.triangle_count
    shift = np.cumsum(kept.vertex_count) - kept.vertex_count
    triangles = kept.triangles + np.repeat(shift, counts)[:, None]
    first = np.cumsum(counts) - counts
    return {
        "vertices": kept.vertices,
        "triangles": triangles,
        "owner": np.repeat(parts.part_owner[chosen], counts),
        "part": np.repeat(parts.part_index[chosen], counts),
        "order": np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(first, counts),
        "parent": kept.parent,
        "depth": kept.depth,
        "side": kept.side,
    }


def _json_value(value):
    return value.item() if isinstance(value, np.generic) else value


def run_partition(frame, number: int, settings: Settings) -> dict:
    """Triangulate one partition (a GeoDataFrame with the ``SOURCE_ID`` column) and write its
    files; returns its index entry with its counts and failures."""
    started = time.perf_counter()
    out_dir = Path(settings.out_dir)
    geometries = np.asarray(frame.geometry.array, dtype=object)
    ids = frame[SOURCE_ID].to_numpy()
    count = len(frame)
    reader = _Reader(geometries, settings.invalid, walls=settings.plane == "auto")
    parts = reader.read()
    errors = reader.errors
    _elevation(parts, frame, settings, reader.has_z, errors)
    parts = _without_failed(parts, errors)
    read_done = time.perf_counter()
    outcome = _triangulate(parts, settings, errors)
    engine_done = time.perf_counter()
    mesh = _mesh(parts, outcome, errors)
    with_triangles = np.zeros(count, dtype=bool)
    with_triangles[mesh["owner"]] = True
    bounds = shapely.total_bounds(geometries) if count else np.full(4, np.nan)
    extent = [float(v) for v in bounds] if np.isfinite(bounds).all() else None
    name = part_name(number)
    fmt = settings.mesh_format
    entry = {
        "partition": number,
        "triangles_file": f"triangles/{name}.parquet",
        "mesh_file": None if fmt == "none" else f"meshes/{name}.{fmt}",
        "extent": extent,
        "read": count,
        "triangulated": int(with_triangles.sum()),
        "failed": len(errors),
        "empty": int(count - with_triangles.sum() - len(errors)),
        "repaired": int(reader.repaired.sum()),
        "triangles": len(mesh["triangles"]),
        "failures": [[_json_value(ids[row]), errors[row]] for row in sorted(errors)],
    }
    crs = getattr(frame, "crs", None)
    table = _triangle_table(frame, settings, ids, mesh)
    vertices = mesh["vertices"]
    bbox = None
    if len(vertices):
        low, high = vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)
        bbox = [float(low[0]), float(low[1]), float(high[0]), float(high[1])]
    table = table.replace_schema_metadata({b"geo": _geo_metadata(crs, bbox)})

    def write_parquet(path: Path) -> None:
        import pyarrow.parquet as pq

        pq.write_table(table, path)

    _write_atomic(out_dir / entry["triangles_file"], write_parquet)
    if fmt != "none":
        datasets = {"depth": mesh["depth"]}
        if ids.dtype.kind in "iu":
            datasets = {"feature_id": ids[mesh["owner"]], **datasets}
        crs_wkt = crs.to_wkt() if crs is not None else None
        if fmt == "ply":  # identical vertices shared, as the plugin's meshes
            merged, faces, _part = merge_meshes([(vertices, mesh["triangles"])])
            writer = write_ply
        else:  # glTF gives each face its own vertices anyway
            from ..formats.gltf import write_glb

            merged, faces, writer = vertices, mesh["triangles"], write_glb
        _write_atomic(
            out_dir / entry["mesh_file"],
            lambda path: writer(path, merged, faces, datasets, crs_wkt=crs_wkt),
        )
        entry["mesh_vertices"] = len(merged)
    done = time.perf_counter()
    entry["seconds"] = {
        "read": read_done - started,
        "triangulate": engine_done - read_done,
        "write": done - engine_done,
    }
    try:
        from distributed import get_worker

        entry["worker"] = get_worker().address
    except (ImportError, ValueError):
        entry["worker"] = None
    return entry
