"""mapbox/earcut's 59 test polygons, each at rotations 0, 90, 180 and 270 degrees.

Expectations come from earcut's expected.json and from docs/algorithm.md, never from the
engine's output:
- deviation (exact) within earcut's limit (``errors-with-rotation`` for rotated runs), and
  below 1e-12 where earcut allows none;
- where the polygon is valid (shapely) once the rings the engine ignores are left out (rings
  with fewer than 3 distinct points or zero area, e.g. Steiner points): the triangles tile it
  exactly (no overlap, no gap) and number 2V - B - 2 + 2h;
- the five fixtures earcut expects no triangles for give none, without an exception.
Invalid fixtures are triangulated with ``invalid="as_given"`` (earcut's behaviour); valid
ones are unaffected by that option (it only acts where no correct triangle exists).
Rotations are exact: (x, y) -> (-y, x) and its powers.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import pytest
import shapely

from bsp_triangulate import triangulate

from .checks import check_triangulation, deviation, used_rings

EARCUT = Path(__file__).resolve().parents[3] / "shared" / "data" / "earcut"
EXPECTED = json.loads((EARCUT / "expected.json").read_text())
FIXTURES = sorted(p.stem for p in (EARCUT / "fixtures").glob("*.json"))
NO_TRIANGLES = ("degenerate", "empty-square", "infinite-loop-jhl", "issue107", "issue83")
ROTATIONS = (0, 90, 180, 270)


@cache
def load(name: str) -> list:
    return json.loads((EARCUT / "fixtures" / f"{name}.json").read_text())


def rotate(rings: list, degrees: int) -> list:
    """Rotate counter-clockwise by a multiple of 90 degrees, exactly."""
    turn = {
        0: lambda x, y: (x, y),
        90: lambda x, y: (-y, x),
        180: lambda x, y: (-x, -y),
        270: lambda x, y: (y, -x),
    }[degrees]
    return [[turn(float(p[0]), float(p[1])) for p in ring] for ring in rings]


def is_valid_polygon(rings: list) -> bool:
    kept = used_rings(rings)
    if not kept:
        return False
    try:
        return bool(shapely.Polygon(kept[0], kept[1:]).is_valid)
    except (ValueError, shapely.errors.GEOSException):
        return False


def allowed_deviation(name: str, degrees: int) -> float:
    limit = EXPECTED["errors"].get(name, 0.0)
    if degrees:
        limit = EXPECTED["errors-with-rotation"].get(name, limit)
    return limit


def test_fixture_list_matches_expected_json() -> None:
    assert len(FIXTURES) == 59
    assert set(FIXTURES) == set(EXPECTED["triangles"])
    assert {n for n, count in EXPECTED["triangles"].items() if count == 0} == set(NO_TRIANGLES)


TRIANGULATED = [n for n in FIXTURES if n not in NO_TRIANGLES]


@pytest.mark.parametrize("degrees", ROTATIONS, ids=[f"rot{d}" for d in ROTATIONS])
@pytest.mark.parametrize("name", TRIANGULATED)
def test_earcut_fixture_triangulates_within_deviation(name: str, degrees: int) -> None:
    rings = rotate(load(name), degrees)
    # earcut's contract: invalid rings are triangulated as given, not rejected
    result = triangulate(rings, invalid="as_given")
    # vertices, orientation and tree always; exact tiling, zero deviation, count when valid
    check_triangulation(rings, result, valid=is_valid_polygon(rings))
    dev = deviation(rings, result.vertices, result.triangles)
    limit = allowed_deviation(name, degrees)
    assert dev <= limit if limit > 0 else dev < 1e-12, f"deviation {dev}, earcut allows {limit}"


@pytest.mark.parametrize("degrees", ROTATIONS, ids=[f"rot{d}" for d in ROTATIONS])
@pytest.mark.parametrize("name", NO_TRIANGLES)
def test_degenerate_earcut_fixture_gives_no_triangles(name: str, degrees: int) -> None:
    result = triangulate(rotate(load(name), degrees), invalid="as_given")
    assert len(result.triangles) == 0
    assert result.is_empty
