"""Internal steps of the batch path against plain reference formulations."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.batch_rings import _band_pairs, ragged_index


def reference_band_pairs(
    coord: np.ndarray, poly_of: np.ndarray, count: int, edges: np.ndarray, lo, hi
) -> set[tuple[int, int]]:
    """(edge, vertex) pairs by binary search on the sorted keys, as the band was first found."""
    has = np.bincount(poly_of, minlength=count) > 0
    first = np.flatnonzero(np.r_[True, poly_of[1:] != poly_of[:-1]])
    cmin = np.zeros(count)
    cmax = np.zeros(count)
    cmin[has] = np.minimum.reduceat(coord, first)
    cmax[has] = np.maximum.reduceat(coord, first)
    scale = 0.5 / np.where(cmax > cmin, cmax - cmin, 1.0)
    key = poly_of + (coord - cmin[poly_of]) * scale[poly_of]
    order = np.argsort(key)
    sorted_key = key[order]
    owner = poly_of[edges]
    start = np.searchsorted(sorted_key, owner + (lo - cmin[owner]) * scale[owner], "left")
    stop = np.searchsorted(sorted_key, owner + (hi - cmin[owner]) * scale[owner], "right")
    tied = np.zeros(len(sorted_key), dtype=bool)
    same = sorted_key[1:] == sorted_key[:-1]
    tied[1:] |= same
    tied[:-1] |= same
    start += ~tied[start]
    stop -= ~tied[stop - 1]
    counts = np.maximum(stop - start, 0)
    pairs = zip(np.repeat(edges, counts).tolist(), order[ragged_index(start, counts)].tolist())
    return set(pairs)


@pytest.mark.parametrize("seed", range(6))
def test_band_pairs_equal_a_binary_search_on_lattice_coordinates(seed: int) -> None:
    rng = np.random.default_rng(seed)
    sizes = rng.integers(3, 30, 200)
    poly_of = np.repeat(np.arange(len(sizes)), sizes)
    # few distinct values: many ties, also between an edge's end points
    coord = rng.integers(0, 6, len(poly_of)).astype(np.float64) * 0.5 + 1e6 * poly_of
    starts = np.cumsum(sizes) - sizes
    nxt = np.arange(len(poly_of)) + 1
    nxt[starts + sizes - 1] = starts
    edges = np.flatnonzero(rng.random(len(poly_of)) < 0.7)
    ends = nxt[edges]
    ascending = coord[edges] <= coord[ends]
    low = np.where(ascending, edges, ends)
    high = np.where(ascending, ends, edges)
    e, v = _band_pairs(coord, poly_of, len(sizes), edges, low, high)
    got = list(zip(e.tolist(), v.tolist()))
    assert len(got) == len(set(got))
    expected = reference_band_pairs(coord, poly_of, len(sizes), edges, coord[low], coord[high])
    assert set(got) == expected


def near_collinear_polygon(rng: np.random.Generator, count: int, wobble: float) -> list:
    """A comb: teeth whose tips lie within ``wobble`` (relative) of one line, far from the
    origin, so that candidate triangles' sides pass within rounding distance of vertices."""
    x = np.sort(rng.uniform(0.0, 100.0, count))
    tips = np.column_stack([x, 0.5 * x + 20.0 + wobble * 100.0 * rng.standard_normal(count)])
    bases = np.column_stack([x + 0.3, np.full(count, -5.0)])
    outer = np.concatenate([bases, tips[::-1]])
    outer += [512_345.678, 6_012_345.25]
    return [outer]


@pytest.mark.parametrize("wobble", [0.0, 1e-15, 1e-12, 1e-9, 1e-7])
def test_batch_equals_engine_on_near_collinear_combs(wobble: float) -> None:
    from bsp_triangulate import TriangulationError, triangulate
    from bsp_triangulate.batch import triangulate_batch

    rng = np.random.default_rng(17)
    polygons = [near_collinear_polygon(rng, int(rng.integers(5, 25)), wobble) for _ in range(40)]
    handled = 0
    for rings, mine in zip(polygons, triangulate_batch(polygons)):
        if mine is None:
            continue
        handled += 1
        try:
            expected = triangulate(rings)
        except TriangulationError:
            pytest.fail("the engine rejects a polygon the batch path triangulated")
        for name in ("vertices", "triangles", "parent", "depth", "side"):
            assert np.array_equal(getattr(mine, name), getattr(expected, name)), name
    assert handled >= 0.9 * len(polygons)
