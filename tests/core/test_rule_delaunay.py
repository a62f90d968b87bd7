"""Rule "delaunay": the BSP tree whose triangles form the constrained Delaunay triangulation.

The check is brute force and independent of the engine's predicates: for every triangle, no
vertex of the polygon that is visible from the triangle's interior lies strictly inside its
circumcircle (exact rational in-circle test; visible: the segment from the vertex to the
triangle's centroid meets the rings at that vertex only). The rings are the only constraints,
so the bridges must be Delaunay edges too. Plus the usual checks (checks.check_triangulation:
vertices, orientation, tree attributes, exact tiling, n + 2h - 2 triangles).
"""

from __future__ import annotations

import json
import random
from fractions import Fraction

import numpy as np
import pytest
import shapely
from osgeo import ogr

from bsp_triangulate import triangulate, triangulate_many
from bsp_triangulate.geometry.predicates import (
    cocircular_sign,
    cocircular_signs,
    incircle,
    incircle_many,
    incircle_sos,
    incircle_sos_many,
)

from ..conftest import SHARED_DATA
from .checks import check_triangulation, used_rings
from .random_polygons import random_polygon

EARCUT = SHARED_DATA / "earcut" / "fixtures"
FARMS = SHARED_DATA / "swellendam" / "farms_33S.shp"
GEOS = json.loads((SHARED_DATA / "geos" / "test_cases.json").read_text())


def _incircle_fraction(a, b, c, d) -> int:
    """Exact in-circle sign (a, b, c counter-clockwise: +1 strictly inside)."""
    ax, ay, bx, by, cx, cy, dx, dy = (Fraction(float(v)) for v in (*a, *b, *c, *d))
    adx, ady, bdx, bdy, cdx, cdy = ax - dx, ay - dy, bx - dx, by - dy, cx - dx, cy - dy
    det = (
        (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
        + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
        + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady)
    )
    return (det > 0) - (det < 0)


def delaunay_violations(rings: list, result, extra: object = None) -> list[str]:
    """Triangles with a vertex visible from their interior strictly inside their circle;
    ``extra``: further vertices (interior points), (k, 2) or more columns."""
    kept = used_rings(rings)
    columns = [np.asarray(r, dtype=float)[:, :2] for r in kept]
    if extra is not None and len(extra):
        columns.append(np.asarray(extra, dtype=float)[:, :2])
    points = np.unique(np.concatenate(columns), axis=0)
    boundary = shapely.MultiLineString(
        [[tuple(p[:2]) for p in r] + [tuple(r[0][:2])] for r in kept]
    )
    shapely.prepare(boundary)
    v = np.asarray(result.vertices, dtype=float)[:, :2]
    problems = []
    for number, (i, j, k) in enumerate(np.asarray(result.triangles).tolist()):
        a, b, c = v[i], v[j], v[k]
        # float circumcircle, generous margin; the exact test decides
        d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
        if d == 0:
            problems.append(f"triangle {number} has zero area")
            continue
        sa, sb, sc = a @ a, b @ b, c @ c
        ux = (sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1])) / d
        uy = (sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0])) / d
        r2 = (a[0] - ux) ** 2 + (a[1] - uy) ** 2
        d2 = (points[:, 0] - ux) ** 2 + (points[:, 1] - uy) ** 2
        near = points[d2 < r2 * (1 + 1e-6) + 1e-300]
        centroid = (a + b + c) / 3.0
        for w in near:
            if (w == a).all() or (w == b).all() or (w == c).all():
                continue
            if _incircle_fraction(a, b, c, w) <= 0:
                continue
            seen = shapely.LineString([tuple(w), tuple(centroid)]).intersection(boundary)
            if seen.is_empty or seen.equals(shapely.Point(w)):
                problems.append(f"triangle {number} {(i, j, k)}: vertex {tuple(w)} inside")
                break
    return problems


def check_delaunay(rings: list) -> None:
    result = triangulate(rings, rule="delaunay")
    check_triangulation(rings, result, valid=True)
    problems = delaunay_violations(rings, result)
    assert not problems, problems[:5]


# --- the predicate ------------------------------------------------------------------------------


def test_incircle_matches_exact_arithmetic_near_cocircular_points() -> None:
    rnd = random.Random(5)
    for _ in range(400):
        centre = (rnd.uniform(-1e6, 1e6), rnd.uniform(-1e6, 1e6))
        radius = rnd.uniform(1e-3, 1e3)
        pts = []
        for _ in range(4):
            t = rnd.uniform(0, 6.283)
            pts.append((centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)))
        a, b, c, d = pts
        expected = _incircle_fraction(a, b, c, d)
        assert incircle(*a, *b, *c, *d) == expected
        many = incircle_many(a[0], a[1], b[0], b[1], c[0], c[1], np.array([d[0]]), np.array([d[1]]))
        assert many[0] == expected
    # exactly cocircular (integers), inside and outside
    assert incircle(0, 0, 4, 0, 4, 4, 0, 4) == 0
    assert incircle(0, 0, 4, 0, 4, 4, 1, 1) == 1
    assert incircle(0, 0, 4, 0, 4, 4, 5, 5) == -1
    assert incircle(0, 0, 4, 4, 4, 0, 1, 1) == -1  # clockwise a, b, c: the sign flips


@pytest.mark.parametrize("count", [0, 1, 7, 24, 25, 300, 9000])
def test_incircle_of_points_around_one_circle_matches_exact_arithmetic(count: int) -> None:
    """One circle (scalar corners) against many points: few on Python floats, more through
    the float filter with the corners unbroadcast; the signs are the exact ones, as with every
    input broadcast to arrays. Points near the circle, on it (corners of a rectangle of the
    grid), at its corners, and far."""
    rnd = random.Random(count)
    step, x0, y0 = 0.1, 969491.275403656647541, -6250296.99
    a, b, c = (x0, y0), (x0 + 4 * step, y0), (x0 + 4 * step, y0 + 2 * step)
    points = []
    for k in range(count):
        kind = k % 4
        if kind == 0:
            points.append((x0 + step * rnd.randint(-3, 7), y0 + step * rnd.randint(-3, 5)))
        elif kind == 1:
            t = rnd.uniform(0, 6.283)
            centre = (x0 + 2 * step, y0 + step)
            radius = float(np.hypot(2 * step, step)) * (1 + rnd.choice([-1, 1]) * 1e-15)
            points.append((centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)))
        elif kind == 2:
            points.append(rnd.choice([a, b, c]))
        else:
            points.append((rnd.uniform(-1e7, 1e7), rnd.uniform(-1e7, 1e7)))
    px = np.array([p[0] for p in points], dtype=np.float64)
    py = np.array([p[1] for p in points], dtype=np.float64)
    got = incircle_many(*a, *b, *c, px, py)
    assert got.dtype == np.int8 and got.shape == (count,)
    spread = [np.full(count, v) for v in (*a, *b, *c)]
    np.testing.assert_array_equal(got, incircle_many(*spread, px, py))
    sample = range(0, count, max(count // 300, 1))
    expected = [_incircle_fraction(a, b, c, points[k]) for k in sample]
    np.testing.assert_array_equal(got[list(sample)], expected)


def test_points_the_circle_filter_drops_are_strictly_outside() -> None:
    """The float circle that lets the one-step search drop candidates before the exact
    in-circle test (``one_polygon._circle_around``): every point it drops is strictly outside
    the circle (exact arithmetic), on triangles of every shape and size far from the origin,
    with points near the circle, inside, and at the corners; slivers get no filter."""
    from bsp_triangulate.tree.one_polygon import _circle_around, _circle_reach

    rnd = random.Random(56)
    dropped = kept = refused = 0
    for _ in range(300):
        x0, y0 = rnd.uniform(-1e7, 1e7), rnd.uniform(-1e7, 1e7)
        size = 10.0 ** rnd.uniform(-4, 4)
        corners = [(x0 + size * rnd.uniform(-1, 1), y0 + size * rnd.uniform(-1, 1)) for _ in "abc"]
        if rnd.random() < 0.2:  # a sliver: c almost on the line a-b
            (ax, ay), (bx, by) = corners[:2]
            t = rnd.uniform(-0.5, 1.5)
            corners[2] = (ax + t * (bx - ax) + 1e-9 * size, ay + t * (by - ay))
        (ax, ay), (bx, by), (cx, cy) = corners
        if _orientation(corners) <= 0:
            (ax, ay), (bx, by) = (bx, by), (ax, ay)
        reach = _circle_reach(ax, ay, bx, by, cx, cy)
        circle = _circle_around(ax, ay, bx, by, cx, cy, reach)
        if circle is None:
            refused += 1
            continue
        ox, oy, limit = circle
        radius = limit**0.5
        for _ in range(40):
            angle = rnd.uniform(0, 6.283)
            scale = rnd.choice([1 - 1e-9, 1.0, 1 + 1e-9, 1 + 1e-6, 1 + 1e-3, rnd.uniform(0, 3)])
            point = (ox + scale * radius * np.cos(angle), oy + scale * radius * np.sin(angle))
            point = rnd.choice([point, point, point, (ax, ay), (cx, cy)])
            dx, dy = point[0] - ox, point[1] - oy
            if dx * dx + dy * dy > limit:
                dropped += 1
                assert _incircle_fraction((ax, ay), (bx, by), (cx, cy), point) < 0
            else:
                kept += 1
    assert dropped > 1000 and kept > 1000 and refused > 20


def _orientation(corners: list[tuple[float, float]]) -> int:
    (ax, ay), (bx, by), (cx, cy) = (tuple(map(Fraction, p)) for p in corners)
    value = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return (value > 0) - (value < 0)


@pytest.mark.parametrize("step", [0.1, 81.993426195884126, 1 / 3])
def test_cell_centres_on_rectangles_and_their_ties_match_exact_arithmetic(step: float) -> None:
    # points of a grid far from the origin (a DEM's cell centres): the corners of any
    # axis-parallel rectangle are exactly cocircular, which the vectorised test sees without
    # integer arithmetic; the tie rule, vectorised, decides as the scalar one
    rnd = random.Random(7)
    xs = [969491.275403656647541 + step * i for i in range(4)]
    ys = [-6250296.99 + step * i for i in range(4)]
    grid = [(x, y) for x in xs for y in ys]
    cases = [[c for _ in range(4) for c in rnd.choice(grid)] for _ in range(3000)]
    cases = [c for c in cases if len({tuple(c[0:2]), tuple(c[2:4]), tuple(c[4:6])}) == 3]
    columns = np.array(cases).T
    expected = [_incircle_fraction(c[0:2], c[2:4], c[4:6], c[6:8]) for c in cases]
    np.testing.assert_array_equal(incircle_many(*columns), expected)
    assert (np.array(expected) == 0).sum() > 100
    ties = np.flatnonzero(np.array(expected) == 0)
    np.testing.assert_array_equal(
        cocircular_signs(*columns[:, ties]), [cocircular_sign(*cases[i]) for i in ties]
    )
    np.testing.assert_array_equal(
        incircle_sos_many(*columns), [incircle_sos(*case) for case in cases]
    )


# --- the rule on data ---------------------------------------------------------------------------


def _earcut_valid() -> list[str]:
    names = []
    for path in sorted(EARCUT.glob("*.json")):
        rings = json.loads(path.read_text())
        kept = used_rings(rings)
        if not kept or sum(len(r) for r in kept) > 2500:
            continue
        try:
            if shapely.Polygon(kept[0], kept[1:]).is_valid:
                names.append(path.stem)
        except (ValueError, shapely.errors.GEOSException):
            continue
    return names


@pytest.mark.parametrize("name", _earcut_valid())
def test_earcut_fixture_is_constrained_delaunay(name: str) -> None:
    rings = json.loads((EARCUT / f"{name}.json").read_text())
    check_delaunay(used_rings(rings))


def _geos_polygons() -> list:
    polygons = []
    for case in GEOS:
        wkt = case["input_wkt"]
        if not wkt.upper().startswith(("POLYGON", "MULTIPOLYGON")):
            continue
        geometry = shapely.from_wkt(wkt)
        for part in getattr(geometry, "geoms", [geometry]):
            if part.is_empty or not part.is_valid:
                continue
            rings = [list(part.exterior.coords)] + [list(r.coords) for r in part.interiors]
            polygons.append([[p[:2] for p in r] for r in rings])
    return polygons


def test_geos_cases_are_constrained_delaunay() -> None:
    polygons = _geos_polygons()
    assert len(polygons) > 10
    for rings in polygons:
        check_delaunay(rings)


def _farms(limit: int, most: int, large: bool = False) -> list:
    """Valid farm parts of at most ``most`` points (the first ``limit``), or with
    ``large`` every part of more points or with islands."""
    source = ogr.Open(str(FARMS))
    polygons = []
    for feature in source.GetLayer(0):
        geometry = shapely.from_wkb(bytes(feature.GetGeometryRef().ExportToWkb()))
        for part in getattr(geometry, "geoms", [geometry]):
            rings = [np.asarray(part.exterior.coords)[:, :2]]
            rings += [np.asarray(r.coords)[:, :2] for r in part.interiors]
            small = sum(len(r) for r in rings) <= most
            if part.is_valid and (small != large or (large and len(rings) > 1)):
                polygons.append(rings)
        if len(polygons) >= limit:
            break
    return polygons


def test_swellendam_farms_are_constrained_delaunay() -> None:
    farms = _farms(40, 400)
    assert len(farms) == 40
    for rings in farms:
        check_delaunay(rings)


def test_large_swellendam_farms_and_farms_with_islands_are_constrained_delaunay() -> None:
    farms = _farms(10_000, 400, large=True)
    assert len(farms) >= 4
    assert any(len(rings) > 1 for rings in farms)
    for rings in farms:
        check_delaunay(rings)


@pytest.mark.parametrize("seed", range(40))
def test_random_polygon_with_islands_is_constrained_delaunay(seed: int) -> None:
    rnd = random.Random(seed)
    rings = random_polygon(rnd, islands=rnd.randint(1, 4), integer=seed % 2 == 0)
    check_delaunay(rings)


def test_cocircular_vertices_give_a_fixed_valid_triangulation() -> None:
    # a regular octagon's vertices (integers, exactly cocircular: 5^2 = 3^2 + 4^2)
    octagon = [(5, 0), (4, 3), (0, 5), (-3, 4), (-5, 0), (-4, -3), (0, -5), (3, -4)]
    grid = [(x, y) for x in range(4) for y in (0,)] + [(3, 1), (3, 2), (0, 2), (0, 1)]
    for rings in ([octagon], [grid], [octagon, [(1, 0), (0, 1), (-1, 0), (0, -1)][::-1]]):
        first = triangulate(rings, rule="delaunay")
        check_triangulation(rings, first, valid=True)
        assert not delaunay_violations(rings, first)
        again = triangulate(rings, rule="delaunay")
        np.testing.assert_array_equal(first.triangles, again.triangles)


def test_cocircular_ties_fan_from_the_smallest_point_whatever_the_start_vertex() -> None:
    # the octagon's vertices are exactly cocircular: every triangle takes the
    # lexicographically smallest point, (-5, 0), whichever vertex the ring starts at
    octagon = [(5, 0), (4, 3), (0, 5), (-3, 4), (-5, 0), (-4, -3), (0, -5), (3, -4)]
    seen = set()
    for start in range(len(octagon)):
        ring = octagon[start:] + octagon[:start]
        result = triangulate([ring], rule="delaunay")
        corners = result.vertices[result.triangles][:, :, :2]
        assert all((-5, 0) in [tuple(c) for c in tri] for tri in corners.tolist())
        seen.add(frozenset(frozenset(map(tuple, tri)) for tri in corners.tolist()))
        batch = triangulate_many([[ring]], rule="delaunay")[0]
        np.testing.assert_array_equal(batch.triangles, result.triangles)
    assert len(seen) == 1
