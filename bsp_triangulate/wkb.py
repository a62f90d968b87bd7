"""Fast conversion between WKB and numpy ring arrays (Polygon, MultiPolygon; PolygonZ out).

Reading accepts ISO WKB (type + 1000 for Z, + 2000 for M, + 3000 for ZM), EWKB-style flags
(0x80000000 Z, 0x40000000 M, 0x20000000 SRID, the SRID is skipped) and both byte orders.
M values are dropped. Writing produces little-endian ISO WKB.
"""

from __future__ import annotations

import struct

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
