"""Helpers of batch_bridges against plain references: each island's leftmost vertex and the
ring edges of a bridging step."""

from __future__ import annotations

import random

import numpy as np

from bsp_triangulate.geometry.bridges_batch import _Edges, _leftmost, traversal_ids
from bsp_triangulate.geometry.rings_batch import flatten_rings

from ..random_polygons import random_polygon


def flat_and_working_x(polygons: list):
    flat = flatten_rings(polygons, 10_000)
    wx = np.where(np.repeat(flat.mirrored[flat.ring_poly], flat.ring_len), -flat.vx, flat.vx)
    return flat, wx


def polygons_with_ties() -> list:
    rnd = random.Random(5)
    polygons = [random_polygon(rnd, islands=rnd.randint(1, 3)) for _ in range(150)]
    # islands with several vertices at the smallest x, some at the same y after mirroring
    square = [(0, 0), (20, 0), (20, 20), (0, 20)]
    polygons.append([square, [(5, 5), (5, 8), (5, 6), (9, 7)], [(12, 12), (12, 15), (16, 12)]])
    polygons.append([square[::-1], [(5, 5), (9, 5), (9, 9), (5, 9)]])
    return polygons


def test_leftmost_equals_the_smallest_x_then_y_first_in_traversal_order() -> None:
    flat, wx = flat_and_working_x(polygons_with_ties())
    trav = traversal_ids(flat)
    islands = np.flatnonzero(np.arange(len(flat.ring_len)) != flat.poly_ring0[flat.ring_poly])
    got = _leftmost(flat, wx, flat.vy, trav, islands)
    for ring, position in zip(islands.tolist(), got.tolist()):
        start, length = flat.ring_start[ring], flat.ring_len[ring]
        ids = trav[start : start + length]
        keys = [(wx[i], flat.vy[i], k) for k, i in enumerate(ids.tolist())]
        assert position == start + min(keys)[2]


def test_ring_edges_equal_edges_by_next_index() -> None:
    flat, wx = flat_and_working_x(polygons_with_ties())
    nxt = np.arange(len(wx)) + 1
    nxt[flat.ring_start + flat.ring_len - 1] = flat.ring_start
    got = _Edges.of_rings(flat, wx, flat.vy)
    want = _Edges.of(wx, flat.vy, np.arange(len(wx)), nxt)
    for name in ("ax", "ay", "bx", "by", "lo_x", "hi_x"):
        assert np.array_equal(getattr(got, name), getattr(want, name)), name
