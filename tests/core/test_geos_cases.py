"""GEOS's polygon triangulation test cases (PolygonTriangulator, ConstrainedDelaunay, HoleJoiner).

GEOS's exact expected triangles come from other algorithms, so they are not compared; what
every case must satisfy is GEOS's own weaker check: the union of the triangles equals the input.
Here that is checked twice: exactly (checks.py: the triangles tile each valid part, count
2V - B - 2 + 2h) and with shapely (symmetric difference of the union and the input).

Input handling, since the core API takes rings of points:
- MultiPolygon and GeometryCollection: each polygonal part is triangulated on its own
  (``triangulate_many``), empty parts give empty results;
- POLYGON EMPTY and points: passed as a ring of their (zero to one) points: empty result;
- POLYGON ZM: Z is passed on and must come back unchanged; M is dropped;
- CURVEPOLYGON: shapely cannot read curves, so GDAL/OGR linearises it (default arc stepping)
  and the linear ring is triangulated (GEOS itself rejects curved input);
- LINESTRING: not a polygon; closing it into a ring would invent an area, so it is not passed
  to the core (the Processing algorithm only accepts polygon layers).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from osgeo import ogr

from bsp_triangulate import triangulate, triangulate_many

from .checks import check_triangulation, used_rings

CASES = json.loads(
    (
        Path(__file__).resolve().parents[3] / "shared" / "data" / "geos" / "test_cases.json"
    ).read_text()
)


def case_id(case: dict) -> str:
    label = case.get("label") or "unlabelled"
    return f"{case['file'].removesuffix('.cpp')}-{case['test']}-{label}"


def read(wkt: str) -> shapely.Geometry:
    if wkt.upper().startswith("CURVEPOLYGON"):
        wkt = ogr.CreateGeometryFromWkt(wkt).GetLinearGeometry().ExportToIsoWkt()
    return shapely.from_wkt(wkt)


def polygon_parts(geometry: shapely.Geometry) -> list[list[list[tuple]]]:
    """Rings of every polygonal part, with z where the input has it."""
    if geometry.geom_type == "Polygon":
        if geometry.is_empty:
            return [[[]]]
        return [[_coords(geometry.exterior), *(_coords(r) for r in geometry.interiors)]]
    if geometry.geom_type in ("MultiPolygon", "GeometryCollection"):
        return [part for g in geometry.geoms for part in polygon_parts(g)]
    if geometry.geom_type in ("Point", "MultiPoint"):
        return [[_coords(geometry)]]
    return []


def _coords(geometry: shapely.Geometry) -> list[tuple]:
    return [tuple(p) for p in shapely.get_coordinates(geometry, include_z=geometry.has_z)]


def union_of(results: list) -> shapely.Geometry:
    triangles = [
        shapely.Polygon(r.vertices[t][:, :2]) for r in results for t in np.asarray(r.triangles)
    ]
    return shapely.union_all(triangles) if triangles else shapely.Polygon()


POLYGONAL = [c for c in CASES if not c["input_wkt"].upper().startswith("LINESTRING")]


@pytest.mark.parametrize("case", POLYGONAL, ids=[case_id(c) for c in POLYGONAL])
def test_union_of_triangles_equals_geos_input(case: dict) -> None:
    geometry = read(case["input_wkt"])
    parts = polygon_parts(geometry)
    results = triangulate_many(parts)
    assert len(results) == len(parts)
    for rings, result in zip(parts, results):
        single = triangulate(rings)
        np.testing.assert_array_equal(result.triangles, single.triangles)
        kept = used_rings(rings)
        valid = bool(kept) and shapely.Polygon(kept[0], kept[1:]).is_valid
        check_triangulation(rings, result, valid=valid)
    area = shapely.area(geometry)
    if area == 0:
        assert all(r.is_empty for r in results)
        return
    union = union_of(results)
    mismatch = shapely.area(shapely.symmetric_difference(union, shapely.force_2d(geometry)))
    assert mismatch <= 1e-12 * area, f"union differs from the input by area {mismatch}"


def test_polygon_zm_keeps_its_z_values() -> None:
    (case,) = [c for c in CASES if c["input_wkt"].startswith("POLYGON ZM")]
    (rings,) = polygon_parts(read(case["input_wkt"]))
    result = triangulate(rings)
    assert len(result.triangles) == 1
    corners = {tuple(p) for p in result.vertices[result.triangles[0]].tolist()}
    assert corners == {(0.0, 0.0, 4.0), (1.0, 7.0, 9.0), (6.0, 2.0, 6.0)}


def test_curve_polygon_is_linearised_into_a_fan_of_its_arc() -> None:
    (case,) = [c for c in CASES if c["input_wkt"].startswith("CURVEPOLYGON")]
    geometry = read(case["input_wkt"])
    (rings,) = polygon_parts(geometry)
    result = triangulate(rings)
    distinct = len({p[:2] for p in rings[0]})
    assert distinct > 10  # the arc became many points
    assert len(result.triangles) == distinct - 2
