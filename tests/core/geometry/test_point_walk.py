"""The walk that makes the bridged sequence of a polygon without islands and its interior
points at once gives the sequence of the joining one point at a time, and so the same tree."""

from __future__ import annotations

import random

import numpy as np
import pytest
import shapely

from bsp_triangulate import triangulate
from bsp_triangulate.geometry import bridges
from bsp_triangulate.geometry.point_walk import walk_sequence
from tests.core.random_polygons import star_ring

FIELDS = ("vertices", "triangles", "parent", "depth", "side", "point_ids")


def points_inside(ring: list, rnd: random.Random, count: int, lattice: bool) -> np.ndarray:
    """Points strictly inside the ring: on a lattice of unit cells (cocircular in fours, many
    at equal distances), or anywhere."""
    polygon = shapely.Polygon(ring)
    xmin, ymin, xmax, ymax = polygon.bounds
    if lattice:
        xs, ys = np.meshgrid(np.arange(np.floor(xmin), xmax), np.arange(np.floor(ymin), ymax))
        candidates = np.column_stack([xs.ravel() + 0.5, ys.ravel() + 0.5])
    else:
        candidates = np.array(
            [(rnd.uniform(xmin, xmax), rnd.uniform(ymin, ymax)) for _ in range(4 * count)]
        )
    inside = candidates[shapely.contains_xy(polygon, candidates[:, 0], candidates[:, 1])]
    picked = rnd.sample(range(len(inside)), min(count, len(inside)))
    return inside[sorted(picked)]


@pytest.mark.parametrize("lattice", [False, True])
def test_the_walk_gives_the_joinings_tree(lattice: bool, monkeypatch: pytest.MonkeyPatch):
    rnd = random.Random(21 if lattice else 22)
    walked = []
    original = bridges._walked

    def counted(*args):
        result = original(*args)
        walked.append(result is not None)
        return result

    for _ in range(30):
        ring = star_ring(rnd, rnd.randint(6, 30), radius=20.0, integer=lattice)
        if not shapely.Polygon(ring).is_valid:
            continue
        points = points_inside(ring, rnd, rnd.randint(1, 120), lattice)
        if rnd.random() < 0.5:
            ring = ring[::-1]  # clockwise: the working plane is mirrored
        if not len(points):
            continue
        monkeypatch.setattr(bridges, "_walked", counted)
        fast = triangulate([ring], points=points, rule="delaunay")
        monkeypatch.setattr(bridges, "_walked", lambda *args: None)
        slow = triangulate([ring], points=points, rule="delaunay")
        for field in FIELDS:
            np.testing.assert_array_equal(getattr(fast, field), getattr(slow, field))
    assert sum(walked) >= 15


def test_a_spike_per_point_in_the_order_of_its_angle():
    # a square; points linked to corner 0 at 30 and 60 degrees and one linked to a point
    x = np.array([0.0, 4.0, 4.0, 0.0, 2.0, 1.0, 1.0])
    y = np.array([0.0, 0.0, 4.0, 4.0, 1.1547005383792517, 1.7320508075688772, 2.5])
    links = np.array([[4, 0], [5, 0], [6, 5]])
    sequence = walk_sequence(x, y, np.array([0, 1, 2, 3]), links)
    # leaving 0 for 1 first, then around: the spikes at 0 come last, 60 degrees before 30
    assert sequence.tolist() == [0, 1, 2, 3, 0, 5, 6, 5, 0, 4]


def test_nearly_one_direction_is_left_to_the_joining():
    x = np.array([0.0, 4.0, 4.0, 0.0, 1.0, 2.0])
    y = np.array([0.0, 0.0, 4.0, 4.0, 1.0, 2.0 + 1e-14])
    assert walk_sequence(x, y, np.array([0, 1, 2, 3]), np.array([[4, 0], [5, 0]])) is None
    # a link outside the polygon leaves it: no sequence
    x2 = np.array([0.0, 4.0, 4.0, 0.0, -1.0])
    y2 = np.array([0.0, 0.0, 4.0, 4.0, -1.0])
    assert walk_sequence(x2, y2, np.array([0, 1, 2, 3]), np.array([[4, 0]])) is None
