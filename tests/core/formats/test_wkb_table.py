"""The bulk WKB reader (``polygon_table``) against the one-geometry reader, case by case."""

from __future__ import annotations

import struct

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiPolygon, Polygon

from bsp_triangulate.formats.wkb import polygon_table, polygons_from_wkb
from tests.core.formats.test_wkb import SHARED_DATA, SQUARE_WITH_HOLE


def _ring(points: list[tuple[float, ...]], endian: str = "<") -> bytes:
    width = len(points[0]) if points else 2
    return struct.pack(endian + "I", len(points)) + b"".join(
        struct.pack(endian + f"{width}d", *point) for point in points
    )


def _polygon(rings: list[list[tuple[float, ...]]], code: int = 3, endian: str = "<") -> bytes:
    order = 1 if endian == "<" else 0
    header = struct.pack(endian.replace("<", "<B").replace(">", ">B") + "I", order, code)
    return (
        header + struct.pack(endian + "I", len(rings)) + b"".join(_ring(r, endian) for r in rings)
    )


def _multi(parts: list[bytes], code: int = 6) -> bytes:
    return struct.pack("<BII", 1, code, len(parts)) + b"".join(parts)


def _same_as_scalar(wkbs: list[bytes]) -> np.ndarray:
    """Every parsed geometry reads exactly as polygons_from_wkb; returns ``parsed``."""
    table = polygon_table(wkbs)
    polygons = table.polygons()
    assert len(polygons) == len(wkbs)
    for parts, start, stop in zip(polygons, *table.geometry_rows()):
        rings = [ring for part in parts or [] for ring in part]
        joined = np.concatenate(rings) if rings else np.zeros((0, 3))
        assert table.points[start:stop].tobytes() == joined.tobytes()
    for wkb, parts, geometry_z, parsed, empty_parts in zip(
        wkbs,
        polygons,
        table.geometry_z.tolist(),
        table.parsed.tolist(),
        table.geometry_empty_parts.tolist(),
    ):
        if not parsed:
            assert parts is None
            continue
        code = struct.unpack("<I", wkb[1:5])[0]
        declared = struct.unpack("<I", wkb[5:9])[0] if (code & 0x1FFFFFFF) % 1000 == 6 else 1
        assert len(parts) + empty_parts == declared
        expected, has_z = polygons_from_wkb(wkb)
        code = struct.unpack("<I", wkb[1:5])[0]
        assert geometry_z == bool(code & 0x80000000 or (code % 1000000) // 1000 in (1, 3))
        assert has_z >= geometry_z
        assert len(parts) == len(expected)
        for got_rings, rings in zip(parts, expected):
            assert len(got_rings) == len(rings)
            for got, ring in zip(got_rings, rings):
                assert got.shape == ring.shape and got.dtype == ring.dtype
                assert got.flags.c_contiguous
                assert got.tobytes() == ring.tobytes()
    return table.parsed


def test_polygons_of_every_dimension_and_multipolygons_read_like_the_scalar_reader():
    square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0), (0.0, 0.0)]
    hole = [(1.0, 1.0), (1.0, 2.0), (2.0, 2.0), (1.0, 1.0)]
    z = [(x, y, x + y) for x, y in square]
    zm = [(x, y, x * 2, -1.0) for x, y in square]
    m = [(x, y, 7.0) for x, y in square]
    wkbs = [
        _polygon([square, hole]),
        _polygon([z], 1003),
        _polygon([m], 2003),
        _polygon([zm], 3003),
        _polygon([z], 0x80000003),
        _polygon([]),
        _polygon([[]]),
        _polygon([[], hole]),
        _multi([_polygon([square, hole]), _polygon([]), _polygon([square])]),
        _multi([_polygon([z], 1003), _polygon([square])], 1006),
        _multi([]),
        _multi([_polygon([zm], 3003), _polygon([m], 2003), _polygon([z], 1003)], 3006),
        shapely.to_wkb(SQUARE_WITH_HOLE, output_dimension=3),
        shapely.to_wkb(MultiPolygon([SQUARE_WITH_HOLE, Polygon([(20, 0), (30, 0), (25, 5)])])),
    ]
    assert _same_as_scalar(wkbs).all()
    assert _same_as_scalar(wkbs[::-1]).all()
    for wkb in wkbs:
        assert _same_as_scalar([wkb]).all()


def test_other_types_byte_orders_srids_and_malformed_input_are_left_to_the_scalar_reader():
    square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 0.0)]
    good = _polygon([square])
    wkbs = [
        good,
        b"",
        good[:8],
        good[:-1],
        good[:13],
        _polygon([square], endian=">"),
        shapely.to_wkb(
            shapely.set_srid(SQUARE_WITH_HOLE, 32733), flavor="extended", include_srid=True
        ),
        shapely.to_wkb(shapely.Point(1, 2)),
        shapely.to_wkb(shapely.LineString([(0, 0), (1, 1)])),
        _polygon([square], 4003),
        _multi([_polygon([square], endian=">")]),
        _multi([shapely.to_wkb(shapely.Point(1, 2))]),
        _multi([good, good])[:-3],
        struct.pack("<BII", 1, 3, 1) + struct.pack("<I", 2**32 - 1),
        good,
    ]
    parsed = _same_as_scalar(wkbs)
    assert parsed.tolist() == [True] + [False] * (len(wkbs) - 2) + [True]


def test_a_few_geometries_with_many_rings_are_left_to_the_scalar_reader():
    triangle = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.0, 0.0)]
    many = _polygon([triangle] * 600)
    parsed = _same_as_scalar([_polygon([triangle]), many, _polygon([triangle] * 3)])
    assert parsed.tolist() == [True, False, True]
    # many rings in many geometries are read here, a long tail of one geometry is not
    parsed = _same_as_scalar([_polygon([triangle] * 40)] * 9 + [_multi([many] * 2)])
    assert parsed.tolist() == [True] * 9 + [False]


def test_random_batches_match_the_scalar_reader():
    rng = np.random.default_rng(11)
    for _trial in range(30):
        wkbs = []
        for _ in range(int(rng.integers(1, 40))):

            def polygon() -> bytes:
                code = int(rng.choice([3, 1003, 2003, 3003, 0x80000003]))
                width = 2 + (code in (1003, 2003, 0x80000003)) + 2 * (code == 3003)
                rings = [
                    [tuple(rng.normal(size=width)) for _ in range(int(rng.integers(0, 9)))]
                    for _ in range(int(rng.integers(0, 4)))
                ]
                return _polygon(rings, code)

            if rng.random() < 0.4:
                wkbs.append(_multi([polygon() for _ in range(int(rng.integers(0, 4)))]))
            else:
                wkbs.append(polygon())
        assert _same_as_scalar(wkbs).all()


def test_real_swellendam_polygons_read_like_the_scalar_reader():
    from osgeo import ogr

    for name in ("farms_33S.shp", "water_33S.shp", "protected_areas.shp", "urban_33S.shp"):
        dataset = ogr.Open(str(SHARED_DATA / "swellendam" / name))
        layer = dataset.GetLayer(0)
        wkbs = [bytes(feature.GetGeometryRef().ExportToIsoWkb()) for feature in layer]
        parsed = _same_as_scalar(wkbs)
        assert parsed.mean() > (0.99 if len(wkbs) > 1000 else 0)


def test_empty_input():
    table = polygon_table([])
    assert table.polygons() == []
    assert table.points.shape == (0, 3)


@pytest.mark.parametrize("count", [1, 7])
def test_nan_and_signed_zero_coordinates_keep_their_bits(count):
    ring = [(np.nan, -0.0, 1.0), (np.inf, 2.0, -0.0), (0.0, -np.inf, np.nan), (np.nan, -0.0, 1.0)]
    assert _same_as_scalar([_polygon([ring], 1003)] * count).all()
