"""Input features to numpy rings: WKB in bulk, curves segmentized, the invalid-polygon policy."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np
from qgis.core import Qgis, QgsFeature, QgsFeedback, QgsGeometry, QgsWkbTypes

from ..bsp_triangulate.formats.wkb import polygon_table, polygons_from_wkb
from ..bsp_triangulate.geometry.rings import working_axes
from ..bsp_triangulate.geometry.validity import proven_valid
from .qgis_compat import GeometryType, WkbType

INVALID_REPAIR = 0
INVALID_FAIL = 1
INVALID_AS_GIVEN = 2

# Features whose WKB is parsed together: bounded by count and by bytes (large polygons).
READ_FEATURES = 4096
READ_BYTES = 8 << 20

Ring = np.ndarray
Polygon = list  # list of rings, outer ring first


class FeatureRings:
    """One input feature as polygons of (n, 3) float64 rings, or the reason it is not usable.

    ``block``: when not None, ``(points, start, stop)``: the rings are the rows
    ``points[start:stop]``, one after another in order (as the bulk reader makes them), so
    their z can be read and written as one slice. Assigning ``parts`` clears it; the lists
    of parts and rings are not to be changed in place.
    """

    __slots__ = ("_parts", "block", "error", "feature", "has_z", "proven", "repaired")

    def __init__(
        self,
        feature: QgsFeature,
        parts: list[Polygon] | None = None,
        error: str | None = None,
        repaired: bool = False,
        has_z: bool = False,
    ) -> None:
        self.feature = feature
        self._parts: list[Polygon] = [] if parts is None else parts
        self.error = error
        self.repaired = repaired
        self.has_z = has_z
        self.block: tuple[np.ndarray, int, int] | None = None
        # the parts as read were proven valid (validity.proven_valid)
        self.proven = False

    @property
    def parts(self) -> list[Polygon]:
        return self._parts

    @parts.setter
    def parts(self, parts: list[Polygon]) -> None:
        self._parts = parts
        self.block = None
        self.proven = False

    @property
    def fid(self) -> int:
        return self.feature.id()

    @property
    def ok(self) -> bool:
        return self.error is None and bool(self._parts)

    @property
    def is_empty(self) -> bool:
        return self.error is None and not self._parts

    def vertex_count(self) -> int:
        if self.block is not None:
            return self.block[2] - self.block[1]
        return sum(len(ring) for part in self._parts for ring in part)


def _as_xyz(ring) -> np.ndarray:
    """A ring as an (n, 3) float64 array; z is 0 where the input has none."""
    array = np.asarray(ring, dtype=np.float64)
    if array.ndim != 2 or len(array) == 0:
        return np.zeros((0, 3))
    if array.shape[1] == 3:
        return np.ascontiguousarray(array)
    out = np.zeros((len(array), 3))
    width = min(array.shape[1], 3)
    out[:, :width] = array[:, :width]
    return out


def _polygon_parts(geometry: QgsGeometry) -> list[Polygon]:
    """Every polygon in ``geometry`` (collections filtered to their polygons) as lists of rings."""
    flat = QgsWkbTypes.flatType(geometry.wkbType())
    if flat == WkbType.GeometryCollection:
        parts: list[Polygon] = []
        for member in geometry.asGeometryCollection():
            if member.type() == GeometryType.Polygon:
                parts.extend(_polygon_parts(member))
        return parts
    if geometry.type() != GeometryType.Polygon:
        return []
    polygons, _has_z = polygons_from_wkb(bytes(geometry.asWkb()))
    return [[_as_xyz(ring) for ring in polygon] for polygon in polygons if len(polygon)]


def read_feature(feature: QgsFeature, invalid_policy: int, walls: bool = False) -> FeatureRings:
    """Convert one feature: segmentize curves, apply the invalid-polygon policy, read WKB.
    ``walls``: the engine may work steep faces in their own plane (see ``_checked``)."""
    item = FeatureRings(feature)
    geometry = feature.geometry()
    if geometry is None or geometry.isNull() or geometry.isEmpty():
        return item
    item.has_z = QgsWkbTypes.hasZ(geometry.wkbType())
    if QgsWkbTypes.isCurvedType(geometry.wkbType()):
        geometry = QgsGeometry(geometry.constGet().segmentize())
    try:
        parts = _polygon_parts(geometry)
    except (ValueError, IndexError) as error:
        item.error = f"unreadable geometry: {error}"
        return item
    return _checked(item, geometry, parts, invalid_policy, walls)


def _checked(
    item: FeatureRings,
    geometry: QgsGeometry,
    parts: list[Polygon],
    invalid_policy: int,
    walls: bool = False,
) -> FeatureRings:
    """``item`` with ``parts`` read from ``geometry``, or its repair, or the reason it fails."""
    # GEOS judges validity in XY, where a wall (a near-vertical face) has no area: where the
    # engine works walls in their own plane (``walls``), they are left to it (it fails bad
    # ones); elsewhere every polygon is worked in XY and judged there.
    if (
        invalid_policy != INVALID_AS_GIVEN
        and not (walls and item.has_z and _has_wall(parts))
        and not geometry.isGeosValid()
    ):
        if invalid_policy == INVALID_FAIL:
            item.error = f"invalid polygon ({_validity_message(geometry)})"
            return item
        repaired = geometry.makeValid()
        if repaired.isNull():
            reason = repaired.lastError() or _validity_message(geometry)
            item.error = f"invalid polygon that could not be repaired ({reason})"
            return item
        item.repaired = True
        try:
            parts = _polygon_parts(repaired)
        except (ValueError, IndexError) as error:
            item.error = f"unreadable geometry: {error}"
            return item
    item.parts = parts
    return item


def read_features(
    features: Iterable[QgsFeature],
    invalid_policy: int,
    feedback: QgsFeedback | None = None,
    walls: bool = False,
) -> Iterator[FeatureRings]:
    """``read_feature`` of every feature, in order; the WKB of many features parsed at once."""
    chunk: list[QgsFeature] = []
    wkbs: list[bytes] = []
    size = 0
    for feature in features:
        if feedback is not None and feedback.isCanceled():
            break
        wkb = feature.geometry().asWkb().data()
        chunk.append(feature)
        wkbs.append(wkb)
        size += len(wkb)
        if len(chunk) >= READ_FEATURES or size >= READ_BYTES:
            yield from _read_chunk(chunk, wkbs, invalid_policy, walls)
            chunk, wkbs, size = [], [], 0
    if chunk:
        yield from _read_chunk(chunk, wkbs, invalid_policy, walls)


def _read_chunk(
    chunk: list[QgsFeature], wkbs: list[bytes], invalid_policy: int, walls: bool = False
) -> list[FeatureRings]:
    """Features whose WKB the bulk reader takes (non-empty Polygon and MultiPolygon) are read
    from it; every other one goes through ``read_feature``."""
    table = polygon_table(wkbs)
    # QGIS calls a (multi)polygon empty when no part has a point in its outer ring: those
    # (and null geometries, which are not parsed) take the one-feature path
    part_geometry = np.repeat(np.arange(len(chunk)), table.geometry_parts)
    outer_filled = table.ring_len[table.part_ring0] > 0
    filled = np.bincount(part_geometry[outer_filled], minlength=len(chunk)) > 0
    # a cheap exact proof of validity spares GEOS most valid polygons (identical decisions);
    # the rings of a proven polygon, or of any polygon kept as given, are used as read
    if invalid_policy == INVALID_AS_GIVEN:
        proven, as_read = np.zeros(len(chunk), dtype=bool), filled
    else:
        proven = as_read = proven_valid(table, filled)
    points = table.points
    starts, stops = table.geometry_rows()
    items = []
    for feature, parts, has_z, usable, known, valid, start, stop in zip(
        chunk,
        table.polygons(),
        table.geometry_z.tolist(),
        filled.tolist(),
        as_read.tolist(),
        proven.tolist(),
        starts.tolist(),
        stops.tolist(),
    ):
        if parts is None or not usable:
            items.append(read_feature(feature, invalid_policy, walls))
            continue
        if known:
            item = FeatureRings(feature, parts, has_z=has_z)
            item.proven = valid
        else:
            item = FeatureRings(feature, has_z=has_z)
            item = _checked(item, feature.geometry(), parts, invalid_policy, walls)
        if item.parts is parts:
            item.block = (points, start, stop)
        items.append(item)
    return items


def _has_wall(parts: list[Polygon]) -> bool:
    """Some part's outer ring is worked on in a vertical plane by the engine."""
    return any(part and working_axes(part[0]) != (0, 1) for part in parts)


def _validity_message(geometry: QgsGeometry) -> str:
    errors = geometry.validateGeometry(Qgis.GeometryValidationEngine.Geos)
    return "; ".join(error.what() for error in errors[:3]) or "not valid"


def feature_batches(
    features: Iterable[QgsFeature],
    invalid_policy: int,
    max_features: int = 2000,
    max_vertices: int = 200_000,
    feedback: QgsFeedback | None = None,
    walls: bool = False,
) -> Iterator[list[FeatureRings]]:
    """Group converted features in batches bounded by feature and vertex counts (streaming)."""
    batch: list[FeatureRings] = []
    vertices = 0
    for item in read_features(features, invalid_policy, feedback, walls):
        batch.append(item)
        vertices += item.vertex_count()
        if len(batch) >= max_features or vertices >= max_vertices:
            yield batch
            batch, vertices = [], 0
    if batch:
        yield batch
