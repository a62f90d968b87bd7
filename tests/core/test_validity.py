"""The validity proof: whatever it proves valid, GEOS (shapely's) finds valid too."""

from __future__ import annotations

import warnings

import numpy as np
import shapely

from bsp_triangulate.validity import proven_valid
from bsp_triangulate.wkb import polygon_table
from tests.core.validity_cases import all_cases, special_cases, star_cases


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
