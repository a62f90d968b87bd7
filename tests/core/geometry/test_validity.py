"""The validity proof: whatever it proves valid, GEOS (shapely's) finds valid too."""

from __future__ import annotations

import warnings

import numpy as np
import shapely

from bsp_triangulate.formats.wkb import polygon_table
from bsp_triangulate.geometry.rings_batch import flatten_rings, touching_polygons
from bsp_triangulate.geometry.validity import proven_valid, proven_valid_rings
from tests.core.validity_cases import (
    all_cases,
    footprint_cases,
    radial_cases,
    special_cases,
    star_cases,
)


def _proven(wkbs: list[bytes]) -> np.ndarray:
    table = polygon_table(wkbs)
    return proven_valid(table, np.ones(len(wkbs), dtype=bool))


def test_proven_polygons_are_valid_for_geos():
    wkbs = all_cases()
    proven = _proven(wkbs)
    # rings GEOS cannot even build (unclosed) count as invalid
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        valid = shapely.is_valid(shapely.from_wkb(wkbs, on_invalid="ignore"))
    assert not (proven & ~valid).any(), np.flatnonzero(proven & ~valid)
    # the proof covers most valid polygons of these kinds, not only trivial ones
    assert proven.sum() > 0.5 * valid.sum()


def test_building_outlines_that_are_not_star_shaped_are_proven_edge_pair_by_edge_pair():
    wkbs, intact = footprint_cases()
    proven = _proven(wkbs)
    valid = shapely.is_valid(shapely.from_wkb(wkbs))
    assert not (proven & ~valid).any()
    # every intact outline (with or without its courtyard) is proven, so GEOS never sees it
    assert proven[intact].all()
    # the broken ones GEOS rejects are many, and none of them is proven
    assert (~valid).sum() > 200


def test_star_shaped_rings_whose_vertex_mean_sees_not_all_of_them():
    wkbs, intact = radial_cases()
    proven = _proven(wkbs)
    valid = shapely.is_valid(shapely.from_wkb(wkbs))
    assert not (proven & ~valid).any()
    # every ring as generated is proven, whether or not its vertex mean lies in its kernel
    assert proven[intact].all()
    # the swapped pairs make bow ties that GEOS rejects
    assert (~valid).sum() > 30


def test_the_answer_does_not_depend_on_the_other_geometries_of_the_batch():
    wkbs = all_cases()
    alone = np.array([_proven([wkb])[0] for wkb in wkbs[:300]])
    assert (alone == _proven(wkbs)[:300]).all()
    assert (alone[::-1] == _proven(wkbs[:300][::-1])).all()


def test_hand_made_cases():
    proven = _proven(special_cases()).tolist()
    # a square, clockwise and far from the origin is proven; unclosed, nearly closed, huge,
    # tiny (underflow), NaN, duplicate points, bow ties, spikes and collinear rings are not;
    # a point in the middle of a straight edge is fine
    assert proven[:4] == [True, True, False, False]
    assert proven[4:7] == [False, False, True]
    assert proven[7:14] == [False, False, False, False, False, True, False]
    # an empty part or an empty island is left to GEOS
    assert proven[-2:] == [False, False]


def test_only_wanted_geometries_are_examined():
    wkbs = star_cases(count=20)
    wanted = np.arange(20) % 2 == 0
    proven = proven_valid(polygon_table(wkbs), wanted)
    assert not proven[~wanted].any()
    assert proven[wanted].any()


def test_geometries_the_bulk_reader_leaves_are_not_proven():
    wkbs = star_cases(count=5)
    wkbs[2] = b"\x00" + wkbs[2][1:]  # big-endian marker on little-endian data: not parsed
    proven = _proven(wkbs)
    assert not proven[2]


def _cleaned_rings(wkbs: list[bytes]) -> tuple[list[list[np.ndarray]], np.ndarray]:
    """The single polygons among ``wkbs`` as ring lists, and their positions in ``wkbs``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        geometries = shapely.from_wkb(wkbs, on_invalid="ignore")
    polygons, where = [], []
    for index, geometry in enumerate(geometries):
        if isinstance(geometry, shapely.Polygon) and not geometry.is_empty:
            rings = [geometry.exterior, *geometry.interiors]
            polygons.append([np.asarray(ring.coords)[:, :2] for ring in rings])
            where.append(index)
    return polygons, np.array(where)


def test_open_rings_are_proven_as_their_polygons_and_never_touch():
    polygons, where = _cleaned_rings(all_cases())
    flat = flatten_rings(polygons, max_vertices=1 << 20)
    wanted = flat.handled & ~flat.empty
    proven = proven_valid_rings(
        flat.vx, flat.vy, flat.ring_start, flat.ring_len, flat.ring_poly, wanted
    )
    table_proven = _proven(all_cases())[where]
    # the same proof: what the table proves, the open rings prove (cleaning removes nothing
    # from a proven ring), and a few more once repeated points are cleaned away
    assert not (table_proven & wanted & ~proven).any()
    assert (table_proven & wanted).sum() > 500
    # no proven polygon has coinciding vertices or a vertex on an edge
    touching = touching_polygons(flat, flat.vx, wanted)
    assert touching[wanted & ~proven].any()
    assert not (touching & proven).any()
    assert not proven[~wanted].any()
