"""WKB reading and writing against shapely's WKB writer and reader."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiPolygon, Polygon

from bsp_triangulate.formats.wkb import (
    polygons_from_wkb,
    triangles_to_multipolygon_wkb,
    triangles_to_wkb,
)

SHARED_DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data"
SQUARE_WITH_HOLE = Polygon(
    [(0, 0, 1), (10, 0, 2), (10, 10, 3), (0, 10, 4)],
    [[(2, 2, 5), (2, 4, 6), (4, 4, 7), (4, 2, 8)]],
)


def _rings_of(polygon: Polygon) -> list[np.ndarray]:
    return [np.asarray(polygon.exterior.coords)] + [
        np.asarray(ring.coords) for ring in polygon.interiors
    ]


@pytest.mark.parametrize("byte_order", [0, 1])
def test_polygon_z_with_hole_round_trips_in_both_byte_orders(byte_order):
    wkb = shapely.to_wkb(SQUARE_WITH_HOLE, byte_order=byte_order, output_dimension=3)
    parts, has_z = polygons_from_wkb(wkb)
    assert has_z
    assert len(parts) == 1
    for got, expected in zip(parts[0], _rings_of(SQUARE_WITH_HOLE)):
        np.testing.assert_array_equal(got, expected)


def test_polygon_2d_gets_zero_z_and_no_z_flag():
    polygon = Polygon([(0, 0), (3, 0), (0, 4)])
    parts, has_z = polygons_from_wkb(shapely.to_wkb(polygon, output_dimension=2))
    assert not has_z
    assert parts[0][0].shape == (4, 3)
    np.testing.assert_array_equal(parts[0][0][:, 2], 0.0)
    np.testing.assert_array_equal(parts[0][0][:, :2], np.asarray(polygon.exterior.coords))


def test_ewkb_z_flag_with_srid_is_read_like_iso():
    ewkb = shapely.to_wkb(SQUARE_WITH_HOLE, flavor="extended", include_srid=True)
    assert struct.unpack("<I", ewkb[1:5])[0] & 0x80000000
    parts, has_z = polygons_from_wkb(ewkb)
    assert has_z
    np.testing.assert_array_equal(parts[0][1], _rings_of(SQUARE_WITH_HOLE)[1])


def test_iso_polygon_zm_and_m_drop_the_measure():
    ring = [(0.0, 0.0, 5.0, 100.0), (4.0, 0.0, 6.0, 101.0), (0.0, 3.0, 7.0, 102.0)]
    ring.append(ring[0])
    body = struct.pack("<I", 1) + struct.pack("<I", len(ring))
    body += b"".join(struct.pack("<4d", *point) for point in ring)
    parts, has_z = polygons_from_wkb(struct.pack("<BI", 1, 3003) + body)
    assert has_z
    np.testing.assert_array_equal(parts[0][0], np.asarray(ring)[:, :3])

    ring_m = [(x, y, m) for x, y, _, m in ring]
    body_m = struct.pack(">I", 1) + struct.pack(">I", len(ring_m))
    body_m += b"".join(struct.pack(">3d", *point) for point in ring_m)
    parts, has_z = polygons_from_wkb(struct.pack(">BI", 0, 2003) + body_m)
    assert not has_z
    np.testing.assert_array_equal(parts[0][0][:, :2], np.asarray(ring)[:, :2])
    np.testing.assert_array_equal(parts[0][0][:, 2], 0.0)


def test_multipolygon_parts_keep_order_and_empty_polygon_is_no_part():
    second = Polygon([(20, 0, 9), (30, 0, 9), (25, 5, 9)])
    multi = MultiPolygon([SQUARE_WITH_HOLE, second])
    parts, has_z = polygons_from_wkb(shapely.to_wkb(multi))
    assert has_z
    assert [len(rings) for rings in parts] == [2, 1]
    np.testing.assert_array_equal(parts[1][0], np.asarray(second.exterior.coords))
    assert polygons_from_wkb(shapely.to_wkb(Polygon())) == ([], False)


def test_real_swellendam_farms_match_shapely():
    from osgeo import ogr

    path = SHARED_DATA / "swellendam" / "farms_33S.shp"
    dataset = ogr.Open(str(path))
    layer = dataset.GetLayer(0)
    checked = 0
    for feature in layer:
        wkb = bytes(feature.GetGeometryRef().ExportToIsoWkb())
        geometry = shapely.from_wkb(wkb)
        polygons = list(geometry.geoms) if geometry.geom_type == "MultiPolygon" else [geometry]
        parts, _ = polygons_from_wkb(wkb)
        assert len(parts) == len(polygons)
        for rings, polygon in zip(parts, polygons):
            for got, expected in zip(rings, _rings_of(polygon)):
                np.testing.assert_array_equal(got[:, :2], expected[:, :2])
        checked += 1
    assert checked == layer.GetFeatureCount() > 2000


def test_non_polygon_and_truncated_wkb_raise():
    with pytest.raises(ValueError, match="not a Polygon"):
        polygons_from_wkb(shapely.to_wkb(shapely.Point(1, 2)))
    with pytest.raises(ValueError, match="truncated"):
        polygons_from_wkb(shapely.to_wkb(SQUARE_WITH_HOLE)[:-9])


def test_triangles_to_wkb_reads_back_as_closed_polygon_z():
    rng = np.random.default_rng(3)
    vertices = rng.uniform(-1e5, 1e5, size=(50, 3))
    triangles = rng.integers(0, 50, size=(40, 3))
    blobs = triangles_to_wkb(vertices, triangles)
    assert len(blobs) == 40
    geometries = shapely.from_wkb(blobs)
    assert all(g.geom_type == "Polygon" and g.has_z for g in geometries)
    for geometry, triangle in zip(geometries, triangles):
        coords = np.asarray(geometry.exterior.coords)
        np.testing.assert_array_equal(coords, vertices[np.r_[triangle, triangle[0]]])
    assert struct.unpack("<I", blobs[0][1:5])[0] == 1003


def test_triangles_to_multipolygon_wkb_holds_every_triangle():
    vertices = np.array([[0, 0, 1], [1, 0, 2], [1, 1, 3], [0, 1, 4]], dtype=float)
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    geometry = shapely.from_wkb(triangles_to_multipolygon_wkb(vertices, triangles))
    assert geometry.geom_type == "MultiPolygon" and geometry.has_z
    assert geometry.area == pytest.approx(1.0)
    assert [len(g.exterior.coords) for g in geometry.geoms] == [4, 4]
    empty = shapely.from_wkb(triangles_to_multipolygon_wkb(vertices, np.empty((0, 3), int)))
    assert empty.is_empty
