"""Fast conversion between WKB and numpy ring arrays (Polygon, MultiPolygon; PolygonZ out).

Reading accepts ISO WKB (type + 1000 for Z, + 2000 for M, + 3000 for ZM), EWKB-style flags
(0x80000000 Z, 0x40000000 M, 0x20000000 SRID, the SRID is skipped) and both byte orders.
M values are dropped. Writing produces little-endian ISO WKB.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

WKB_POLYGON = 3
WKB_MULTIPOLYGON = 6
WKB_POLYGON_Z = 1003
WKB_MULTIPOLYGON_Z = 1006

_EWKB_Z = 0x80000000
_EWKB_M = 0x40000000
_EWKB_SRID = 0x20000000

# One little-endian PolygonZ with a single closed ring of 4 points: 109 bytes, no padding.
_TRIANGLE_DTYPE = np.dtype(
    [
        ("byte_order", "u1"),
        ("wkb_type", "<u4"),
        ("num_rings", "<u4"),
        ("num_points", "<u4"),
        ("points", "<f8", (4, 3)),
    ]
)


class _Reader:
    """Cursor over a WKB buffer."""

    def __init__(self, data: bytes) -> None:
        self.data = memoryview(data)
        self.pos = 0

    def uint32(self, endian: str) -> int:
        if self.pos + 4 > len(self.data):
            raise ValueError("truncated WKB: missing a count")
        (value,) = struct.unpack_from(endian + "I", self.data, self.pos)
        self.pos += 4
        return value

    def header(self) -> tuple[str, int, tuple[bool, bool]]:
        """Read byte order and type; return (endian, base type, (has_z, has_m))."""
        if self.pos >= len(self.data):
            raise ValueError("truncated WKB: missing geometry header")
        order = self.data[self.pos]
        if order not in (0, 1):
            raise ValueError(f"invalid WKB byte order {order} at offset {self.pos}")
        self.pos += 1
        endian = "<" if order == 1 else ">"
        raw = self.uint32(endian)
        has_z = bool(raw & _EWKB_Z)
        has_m = bool(raw & _EWKB_M)
        if raw & _EWKB_SRID:
            self.uint32(endian)
        code = raw & 0x1FFFFFFF
        iso_dims, base = divmod(code, 1000)
        if iso_dims > 3:
            raise ValueError(f"unsupported WKB geometry type {raw}")
        has_z = has_z or iso_dims in (1, 3)
        has_m = has_m or iso_dims in (2, 3)
        return endian, base, (has_z, has_m)

    def rings(self, endian: str, dims: int, has_z: bool) -> list[np.ndarray]:
        """Read the rings of one polygon body as (n, 3) float64 arrays (z = 0 without Z).

        The rings are views of one native-endian copy per polygon: the WKB buffer is not
        kept alive by them, and a polygon costs one allocation, not one per ring.
        """
        count = self.uint32(endian)
        spans = []
        total = 0
        for _ in range(count):
            npoints = self.uint32(endian)
            nbytes = npoints * dims * 8
            if self.pos + nbytes > len(self.data):
                raise ValueError("truncated WKB: ring shorter than its point count")
            spans.append((self.pos, npoints))
            self.pos += nbytes
            total += npoints
        out = np.zeros((total, 3), dtype=np.float64)
        width = 3 if has_z and dims >= 3 else 2
        rings = []
        row = 0
        for offset, npoints in spans:
            coords = np.frombuffer(
                self.data, dtype=endian + "f8", count=npoints * dims, offset=offset
            ).reshape(npoints, dims)
            ring = out[row : row + npoints]
            ring[:, :width] = coords[:, :width]
            rings.append(ring)
            row += npoints
        return rings


def polygons_from_wkb(wkb: bytes) -> tuple[list[list[np.ndarray]], bool]:
    """Parse a Polygon or MultiPolygon WKB into its parts' rings.

    Returns ``(parts, has_z)``: ``parts`` holds, per non-empty polygon, its rings (outer ring
    first) as (n, 3) float64 arrays, closing point kept as stored, z = 0 when the input has no
    Z; ``has_z`` says whether the geometry carried Z. Raises ValueError for other types or
    malformed input.
    """
    reader = _Reader(bytes(wkb))
    endian, base, (has_z, has_m) = reader.header()
    dims = 2 + has_z + has_m
    if base == WKB_POLYGON:
        bodies = [reader.rings(endian, dims, has_z)]
    elif base == WKB_MULTIPOLYGON:
        bodies = []
        for _ in range(reader.uint32(endian)):
            part_endian, part_base, (part_z, part_m) = reader.header()
            if part_base != WKB_POLYGON:
                raise ValueError(f"MultiPolygon part of WKB type {part_base}, not a Polygon")
            bodies.append(reader.rings(part_endian, 2 + part_z + part_m, part_z))
            has_z = has_z or part_z
    else:
        raise ValueError(f"WKB geometry type {base} is not a Polygon or MultiPolygon")
    return [rings for rings in bodies if rings], has_z


@dataclass
class PolygonTable:
    """Polygon and MultiPolygon WKBs of many geometries, parsed at once into flat arrays.

    - ``points``: (N, 3) float64, every ring's points in order (z = 0 where a part has none).
    - ``ring_start``, ``ring_len``: each ring's rows of ``points``.
    - ``part_ring0``, ``part_rings``: first ring and ring count of each part that has rings.
    - ``geometry_part0``, ``geometry_parts``: first part and part count of each geometry.
    - ``geometry_empty_parts``: parts without rings of each geometry (not in the part arrays).
    - ``geometry_z``: the geometry's own header has Z (the part headers aside).
    - ``parsed``: the geometry was read here; the others (other types, big-endian, SRID,
      malformed, very many rings) are left to ``polygons_from_wkb`` and have no parts here.

    Parsed geometries read exactly as ``polygons_from_wkb`` reads them (``polygons``).
    """

    points: np.ndarray
    ring_start: np.ndarray
    ring_len: np.ndarray
    part_ring0: np.ndarray
    part_rings: np.ndarray
    geometry_part0: np.ndarray
    geometry_parts: np.ndarray
    geometry_empty_parts: np.ndarray
    geometry_z: np.ndarray
    parsed: np.ndarray

    def geometry_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(start, stop): the rows of ``points`` that hold each geometry's rings (0, 0 for a
        geometry without parts)."""
        start = np.zeros(len(self.parsed), dtype=np.int64)
        stop = np.zeros(len(self.parsed), dtype=np.int64)
        has = np.flatnonzero(self.geometry_parts > 0)
        first_ring = self.part_ring0[self.geometry_part0[has]]
        last_part = self.geometry_part0[has] + self.geometry_parts[has] - 1
        last_ring = self.part_ring0[last_part] + self.part_rings[last_part] - 1
        start[has] = self.ring_start[first_ring]
        stop[has] = self.ring_start[last_ring] + self.ring_len[last_ring]
        return start, stop

    def polygons(self) -> list[list[list[np.ndarray]] | None]:
        """Per geometry, its parts' rings as views of ``points`` (None where not parsed)."""
        points = self.points
        starts = self.ring_start.tolist()
        rings = [points[a:b] for a, b in zip(starts, (self.ring_start + self.ring_len).tolist())]
        parts = [
            rings[first : first + count]
            for first, count in zip(self.part_ring0.tolist(), self.part_rings.tolist())
        ]
        return [
            parts[first : first + count] if ok else None
            for ok, first, count in zip(
                self.parsed.tolist(), self.geometry_part0.tolist(), self.geometry_parts.tolist()
            )
        ]


# Past this many steps, when at most _FEW_LEFT geometries are still being read, those are left
# to the scalar reader: a step costs the same for one geometry as for thousands.
_MANY_STEPS = 32
_FEW_LEFT = 8


def _uint32_at(data: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Little-endian unsigned 32-bit integers at byte offsets of ``data`` (as int64)."""
    octets = data[positions[:, None] + np.arange(4)]
    return octets.view("<u4").ravel().astype(np.int64)


def _decode_types(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(base type, has Z, has M, readable here) of WKB type codes (ISO and EWKB flags)."""
    iso_dims, base = np.divmod(raw & 0x1FFFFFFF, 1000)
    has_z = ((raw & _EWKB_Z) != 0) | (iso_dims == 1) | (iso_dims == 3)
    has_m = ((raw & _EWKB_M) != 0) | (iso_dims == 2) | (iso_dims == 3)
    readable = ((raw & _EWKB_SRID) == 0) & (iso_dims <= 3)
    return base, has_z, has_m, readable


def polygon_table(wkbs: Sequence[bytes]) -> PolygonTable:
    """Parse many little-endian Polygon and MultiPolygon WKBs with array operations.

    One step reads, for every geometry still being read, either its next ring or its next
    part header, so the number of steps is the largest count of rings and parts of one
    geometry; the last few geometries of a long run are left to the scalar reader. Geometries
    that are anything else, or malformed, are marked not parsed.
    """
    count = len(wkbs)
    lengths = np.fromiter((len(wkb) for wkb in wkbs), dtype=np.int64, count=count)
    end = np.cumsum(lengths)
    start = end - lengths
    # padding: a header can be read at any offset up to the end of the last geometry
    data = np.frombuffer(b"".join(wkbs) + bytes(16), dtype=np.uint8)
    reading = lengths >= 9
    geometry_z = np.zeros(count, dtype=bool)
    first = np.flatnonzero(reading)
    base, has_z, has_m, readable = _decode_types(_uint32_at(data, start[first] + 1))
    readable &= (data[start[first]] == 1) & ((base == WKB_POLYGON) | (base == WKB_MULTIPOLYGON))
    reading[first[~readable]] = False
    geometry_z[first] = has_z
    is_polygon = np.zeros(count, dtype=bool)
    is_polygon[first] = base == WKB_POLYGON
    counted = np.zeros(count, dtype=np.int64)
    counted[first] = _uint32_at(data, start[first] + 5)
    position = start + 9
    rings_left = np.where(is_polygon, counted, 0)
    parts_left = np.where(is_polygon, 0, counted)
    dims = np.zeros(count, dtype=np.int64)
    part_z = np.zeros(count, dtype=bool)
    part_id = np.full(count, -1, dtype=np.int64)
    # a Polygon is its own single part, opened before the first step
    polygons = np.flatnonzero(reading & is_polygon)
    dims[first] = 2 + has_z + has_m
    part_z[first] = has_z
    part_id[polygons] = np.arange(len(polygons))
    next_part = len(polygons)
    part_records = [(polygons, part_id[polygons])]
    ring_records = []
    step = 0
    while True:
        rings = np.flatnonzero(reading & (rings_left > 0))
        parts = np.flatnonzero(reading & (rings_left == 0) & (parts_left > 0))
        if not len(rings) and not len(parts):
            break
        step += 1
        if step > _MANY_STEPS and len(rings) + len(parts) <= _FEW_LEFT:
            reading[rings] = False
            reading[parts] = False
            break
        if len(rings):
            at = position[rings]
            fits = at + 4 <= end[rings]
            reading[rings[~fits]] = False
            rings, at = rings[fits], at[fits]
            points = _uint32_at(data, at)
            size = points * dims[rings] * 8
            fits = at + 4 + size <= end[rings]
            reading[rings[~fits]] = False
            rings, at, points, size = rings[fits], at[fits], points[fits], size[fits]
            ring_records.append((rings, part_id[rings], at + 4, points, dims[rings], part_z[rings]))
            position[rings] = at + 4 + size
            rings_left[rings] -= 1
        if len(parts):
            at = position[parts]
            fits = at + 9 <= end[parts]
            reading[parts[~fits]] = False
            parts, at = parts[fits], at[fits]
            base, has_z, has_m, readable = _decode_types(_uint32_at(data, at + 1))
            readable &= (data[at] == 1) & (base == WKB_POLYGON)
            reading[parts[~readable]] = False
            parts, at = parts[readable], at[readable]
            has_z, has_m = has_z[readable], has_m[readable]
            dims[parts] = 2 + has_z + has_m
            part_z[parts] = has_z
            rings_left[parts] = _uint32_at(data, at + 5)
            parts_left[parts] -= 1
            position[parts] = at + 9
            part_id[parts] = np.arange(next_part, next_part + len(parts))
            next_part += len(parts)
            part_records.append((parts, part_id[parts]))
    return _table(data, reading, geometry_z, next_part, part_records, ring_records)


def _table(
    data: np.ndarray,
    parsed: np.ndarray,
    geometry_z: np.ndarray,
    part_total: int,
    part_records: list[tuple[np.ndarray, ...]],
    ring_records: list[tuple[np.ndarray, ...]],
) -> PolygonTable:
    """Gather the rings of the parsed geometries (in step order in the records) into a table."""
    count = len(parsed)
    empty = np.zeros(0, dtype=np.int64)
    columns = list(zip(*ring_records)) if ring_records else [[empty]] * 6
    geometry, part, offset, length, dims, has_z = (np.concatenate(c) for c in columns)
    keep = parsed[geometry]
    # within a geometry the steps follow its bytes: a stable sort by geometry is buffer order
    order = np.argsort(geometry[keep], kind="stable")
    geometry, part, offset, length, dims, has_z = (
        column[keep][order] for column in (geometry, part, offset, length, dims, has_z)
    )
    # parts in geometry order; parts whose rings all were empty lists (no ring) drop out
    part_geometry = np.concatenate([records[0] for records in part_records])
    part_ids = np.concatenate([records[1] for records in part_records])
    ring_count = np.bincount(part, minlength=part_total)
    empty = ring_count[part_ids] == 0
    geometry_empty_parts = np.bincount(part_geometry[empty], minlength=count).astype(np.int64)
    kept = parsed[part_geometry] & ~empty
    part_geometry, part_ids = part_geometry[kept], part_ids[kept]
    order = np.argsort(part_geometry, kind="stable")
    part_geometry, part_ids = part_geometry[order], part_ids[order]
    part_rings = ring_count[part_ids]
    part_ring0 = np.cumsum(part_rings) - part_rings
    geometry_parts = np.bincount(part_geometry, minlength=count).astype(np.int64)
    geometry_part0 = np.cumsum(geometry_parts) - geometry_parts
    points = _gather_points(data, offset, length, dims, has_z)
    ring_start = np.cumsum(length) - length
    return PolygonTable(
        points=points,
        ring_start=ring_start,
        ring_len=length,
        part_ring0=part_ring0,
        part_rings=part_rings,
        geometry_part0=geometry_part0,
        geometry_parts=geometry_parts,
        geometry_empty_parts=geometry_empty_parts,
        geometry_z=geometry_z,
        parsed=parsed,
    )


def _gather_points(
    data: np.ndarray, offset: np.ndarray, length: np.ndarray, dims: np.ndarray, has_z: np.ndarray
) -> np.ndarray:
    """The rings' points, in ring order, as one (N, 3) float64 array (z = 0 without Z)."""
    total = int(length.sum())
    points = np.zeros((total, 3), dtype=np.float64)
    if total == 0:
        return points
    size = length * dims * 8
    # the coordinate bytes of every ring, in buffer order, with the headers between them cut
    gaps = offset - np.concatenate([[0], offset[:-1] + size[:-1]])
    runs = np.empty(2 * len(offset) + 1, dtype=np.int64)
    runs[0:-1:2] = gaps
    runs[1::2] = size
    runs[-1] = len(data) - (offset[-1] + size[-1])
    chosen = np.repeat(np.tile(np.array([False, True]), len(offset) + 1)[:-1], runs)
    values = data[chosen].view("<f8")
    if (dims == dims[0]).all():
        table = values.reshape(total, int(dims[0]))
        points[:, :2] = table[:, :2]
        if has_z.all():
            points[:, 2] = table[:, 2]
        elif has_z.any():
            rows = np.repeat(has_z, length)
            points[rows, 2] = table[rows, 2]
        return points
    # mixed dimensions: each point's first value from its ring's start and width
    value_start = np.cumsum(length * dims) - length * dims
    ring_of = np.repeat(np.arange(len(length)), length)
    within = np.arange(total) - np.repeat(np.cumsum(length) - length, length)
    at = value_start[ring_of] + within * dims[ring_of]
    points[:, 0] = values[at]
    points[:, 1] = values[at + 1]
    rows = np.flatnonzero(has_z[ring_of])
    points[rows, 2] = values[at[rows] + 2]
    return points


def _triangle_records(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if vertices.ndim != 2 or vertices.shape[1] not in (2, 3):
        raise ValueError("vertices must be an (N, 2) or (N, 3) array")
    xyz = np.zeros((len(vertices), 3), dtype=np.float64)
    xyz[:, : vertices.shape[1]] = vertices
    records = np.empty(len(triangles), dtype=_TRIANGLE_DTYPE)
    records["byte_order"] = 1
    records["wkb_type"] = WKB_POLYGON_Z
    records["num_rings"] = 1
    records["num_points"] = 4
    records["points"][:, :3] = xyz[triangles]
    records["points"][:, 3] = records["points"][:, 0]
    return records


def triangles_to_wkb(vertices: np.ndarray, triangles: np.ndarray) -> list[bytes]:
    """One little-endian ISO PolygonZ (type 1003) WKB per triangle, ring closed.

    Built as one structured array and sliced, so it costs about one bytes copy per triangle.
    """
    buffer = _triangle_records(vertices, triangles).tobytes()
    size = _TRIANGLE_DTYPE.itemsize
    return [buffer[start : start + size] for start in range(0, len(buffer), size)]


def triangles_to_multipolygon_wkb(vertices: np.ndarray, triangles: np.ndarray) -> bytes:
    """All triangles as one little-endian ISO MultiPolygonZ (type 1006) WKB."""
    records = _triangle_records(vertices, triangles)
    header = np.array([(1, WKB_MULTIPOLYGON_Z, len(records))], dtype="u1,<u4,<u4").tobytes()
    return header + records.tobytes()
