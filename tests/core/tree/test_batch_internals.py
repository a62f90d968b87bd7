"""Internal steps of the batch path against plain reference formulations."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.geometry.rings_batch import _band_pairs, ragged_index


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


def batch_equals_engine(polygons: list, rule: str = "first") -> int:
    """Assert that every batch result equals the engine's; return how many were batched."""
    from bsp_triangulate import TriangulationError, triangulate
    from bsp_triangulate.tree.batch import triangulate_batch

    handled = 0
    for rings, mine in zip(polygons, triangulate_batch(polygons, rule)):
        if mine is None:
            continue
        handled += 1
        try:
            expected = triangulate(rings, rule=rule)
        except TriangulationError:
            pytest.fail("the engine rejects a polygon the batch path triangulated")
        for name in ("vertices", "triangles", "parent", "depth", "side"):
            assert np.array_equal(getattr(mine, name), getattr(expected, name)), name
    return handled


@pytest.mark.parametrize("wobble", [0.0, 1e-15, 1e-12, 1e-9, 1e-7])
def test_batch_equals_engine_on_near_collinear_combs(wobble: float) -> None:
    rng = np.random.default_rng(17)
    polygons = [near_collinear_polygon(rng, int(rng.integers(5, 25)), wobble) for _ in range(40)]
    assert batch_equals_engine(polygons) >= 0.9 * len(polygons)


@pytest.mark.parametrize("wobble", [0.0, 1e-15, 1e-9])
def test_batch_equals_engine_on_large_near_collinear_combs(wobble: float) -> None:
    """Sub-polygons of more than 64 vertices are tested run by run (bounding boxes of runs
    of the boundary first): the results stay the engine's where the sides pass within
    rounding distance of the teeth."""
    rng = np.random.default_rng(29)
    polygons = [near_collinear_polygon(rng, int(rng.integers(40, 150)), wobble) for _ in range(40)]
    assert batch_equals_engine(polygons) >= 30


def bridged_star(rng: np.random.Generator, count: int, grid: bool) -> tuple:
    """A star with an island joined by a bridge, as the batch path lays sequences out
    (closing repeat included), and the twin of each position (the bridge ends) or -1."""
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, count))
    radius = np.where(np.arange(count) % 2 == 0, 100.0, rng.uniform(20.0, 90.0, count))
    outer = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
    island = 8.0 * np.column_stack([np.cos(angles[::-1][:8]), np.sin(angles[::-1][:8])])
    if grid:
        outer, island = np.round(outer * 4.0) / 4.0, np.round(island * 4.0) / 4.0
    else:
        outer += [512_345.678, 6_012_345.25]
        island += [512_345.678, 6_012_345.25]
    i = int(rng.integers(0, count))
    seq = np.concatenate([outer[: i + 1], island, island[:1], outer[i:], outer[:1]])
    twin = np.full(len(seq), -1)
    twin[i], twin[i + len(island) + 2] = i + len(island) + 2, i
    twin[i + 1], twin[i + len(island) + 1] = i + len(island) + 1, i + 1
    return seq, twin


def laid_out(parts: list, exact: bool, proven: np.ndarray | None = None) -> tuple:
    """Parts as (points, twin) laid out one after another as the batch path lays out its
    sequences: (starts, ``Sequences``)."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    starts = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    seq = np.concatenate([p[0] for p in parts])
    twin = np.concatenate([np.where(p[1] >= 0, p[1] + s, -1) for p, s in zip(parts, starts)])
    sx, sy = seq[:, 0].copy(), seq[:, 1].copy()
    return starts, batch_bsp.Sequences.of(sx, sy, twin, starts, exact, proven)


def every_candidate(parts: list, starts: np.ndarray, smallest: int) -> tuple:
    """(lo, hi, c) of every candidate c of every sub-polygon [lo, hi] with hi - lo at least
    ``smallest`` of the laid-out parts, by lo, then hi, then c."""
    lo, hi, c = [], [], []
    for (points, _), start in zip(parts, starts):
        last = start + len(points) - 1
        for low in range(start + 1, last - 1):
            for high in range(low + smallest, last + 1):
                lo += [low] * (high - low - 1)
                hi += [high] * (high - low - 1)
                c += list(range(low + 1, high))
    return np.array(lo, dtype=np.int64), np.array(hi, dtype=np.int64), np.array(c, dtype=np.int64)


def runs_against_the_whole_table(seqs, lo: np.ndarray, hi: np.ndarray, c: np.ndarray) -> tuple:
    """The counter-clockwise ones of the items (sub-polygon [lo, hi], candidate c), decided by
    ``_bad_runs`` and by one full-width ``_bad_rows`` table: both find the same failures and
    a vertex inside for the same items, and every vertex reported inside is strictly inside
    its triangle. Returns (lo, hi, c, bad) of those items."""
    from bsp_triangulate.geometry.predicates import orient_many
    from bsp_triangulate.tree import lockstep as batch_bsp

    sx, sy = seqs.sx, seqs.sy
    ccw = orient_many(sx[hi], sy[hi], sx[lo], sy[lo], sx[c], sy[c]) > 0
    lo, hi, c = lo[ccw], hi[ccw], c[ccw]
    width = int((hi - lo).max()) + 1
    bad, inside = batch_bsp._bad_rows(
        sx, sy, lo, hi, c, seqs.extent_x[c], seqs.extent_y[c], seqs.twin, width, seqs.exact
    )
    run_bad, run_inside = batch_bsp._bad_runs(seqs, lo, hi, c)
    assert np.array_equal(run_bad, bad)
    assert np.array_equal(run_inside >= 0, inside >= 0)
    found = np.flatnonzero(run_inside >= 0)
    p = run_inside[found]
    a, b, q = hi[found], lo[found], c[found]
    for u, v in ((a, b), (b, q), (q, a)):
        assert (orient_many(sx[u], sy[u], sx[v], sy[v], sx[p], sy[p]) > 0).all()
    return lo, hi, c, bad


def star_items(seed: int, grid: bool) -> tuple:
    """30 laid-out bridged stars of 70-200 points, and 20,000 items each picking one of them:
    (random generator, ``Sequences``, the item's star start and length)."""
    rng = np.random.default_rng(seed)
    parts = [bridged_star(rng, int(rng.integers(70, 200)), grid) for _ in range(30)]
    starts, seqs = laid_out(parts, grid)
    owner = rng.integers(0, len(parts), 20_000)
    length = np.array([len(p[0]) for p in parts])[owner]
    return rng, seqs, starts[owner], length


@pytest.mark.parametrize("grid", [True, False])
def test_runs_decide_like_the_whole_table(grid: bool) -> None:
    rng, seqs, start, length = star_items(41, grid)
    # random sub-polygons [lo, hi] of more than 64 vertices and counter-clockwise candidates
    lo = start + rng.integers(1, length - 66)
    hi = np.minimum(lo + 65 + rng.integers(0, length), start + length - 1)
    c = lo + 1 + (rng.random(len(lo)) * (hi - lo - 1)).astype(np.int64)
    lo, _, _, bad = runs_against_the_whole_table(seqs, lo, hi, c)
    assert len(lo) > 5_000 and 0.05 < bad.mean() < 0.95


@pytest.mark.parametrize("grid", [True, False])
def test_candidates_outside_a_base_corner_fail_the_whole_table(grid: bool) -> None:
    # a candidate right of the edge lo -> lo + 1 (or hi - 1 -> hi) at a convex base corner
    # has that edge inside its triangle's angle there: the tables reject it too
    from bsp_triangulate.geometry.predicates import orient_many
    from bsp_triangulate.tree import lockstep as batch_bsp

    rng, seqs, start, length = star_items(47, grid)
    lo = start + 1 + (rng.random(len(start)) * (length - 6)).astype(np.int64)
    hi = np.minimum(lo + 3 + rng.integers(0, length), start + length - 1)
    c = lo + 1 + (rng.random(len(lo)) * (hi - lo - 1)).astype(np.int64)
    sx, sy = seqs.sx, seqs.sy
    left = orient_many(sx[hi], sy[hi], sx[lo], sy[lo], sx[c], sy[c]) > 0
    lo, hi, c = lo[left], hi[left], c[left]
    node = np.arange(len(lo))
    outside = ~batch_bsp._within_corners(seqs, lo, hi, node, c)
    assert outside.sum() > 1_000
    lo, hi, c = lo[outside], hi[outside], c[outside]
    width = int((hi - lo).max()) + 1
    bad, _ = batch_bsp._bad_rows(
        sx, sy, lo, hi, c, seqs.extent_x[c], seqs.extent_y[c], seqs.twin, width, seqs.exact
    )
    assert bad.all()


@pytest.mark.parametrize("grid", [True, False])
def test_runs_decide_like_the_whole_table_on_small_sub_polygons(grid: bool) -> None:
    # a pass of the tables that holds one large sub-polygon takes every item run by run, so
    # the runs must also decide the smallest ones: 4 to 65 vertices, within one run or across
    # run ends; candidates anywhere, often the ear hi - 1 or the last one, lo + 1
    rng, seqs, start, length = star_items(43, grid)
    span = rng.integers(3, 65, len(start))
    lo = start + 1 + (rng.random(len(start)) * (length - span - 2)).astype(np.int64)
    hi = lo + span
    c = lo + 1 + (rng.random(len(lo)) * (span - 1)).astype(np.int64)
    pick = rng.random(len(lo))
    c[pick < 0.3] = hi[pick < 0.3] - 1  # the ear
    c[pick > 0.9] = lo[pick > 0.9] + 1
    lo, _, _, bad = runs_against_the_whole_table(seqs, lo, hi, c)
    assert len(lo) > 5_000 and 0.05 < bad.mean() < 0.95


def combs_and_stars(rng: np.random.Generator, combs: int, stars: int, wobble: float) -> tuple:
    """Near-collinear combs (5-24 vertices) and bridged stars (6-29 points) laid out as the
    batch path lays out sequences: (parts as (points, twin), starts, ``Sequences``)."""
    rings = [near_collinear_polygon(rng, int(rng.integers(5, 25)), wobble)[0] for _ in range(combs)]
    parts = [(np.concatenate([r, r[:1]]), np.full(len(r) + 1, -1)) for r in rings]
    parts += [bridged_star(rng, int(rng.integers(6, 30)), False) for _ in range(stars)]
    return (parts, *laid_out(parts, False))


@pytest.mark.parametrize("wobble", [0.0, 1e-15, 1e-12])
def test_ear_facing_equals_facing_on_near_collinear_combs(wobble: float) -> None:
    """``_facing_ear`` (a node's first candidate hi - 1) decides like ``_facing`` on every
    sub-polygon [lo, hi] of combs whose vertices lie within rounding distance of the lines
    through others, and of bridged stars (bridge ends at the same point)."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    parts, starts, seqs = combs_and_stars(np.random.default_rng(43), 40, 20, wobble)
    lo, hi, c = every_candidate(parts, starts, 2)
    lo, hi = lo[c == hi - 1], hi[c == hi - 1]
    passed = batch_bsp._facing_ear(seqs, lo, hi)
    assert 0.05 < passed.mean() < 0.95
    assert np.array_equal(passed, batch_bsp._facing(seqs, lo, hi, hi - 1))


def test_facing_known_zeros_equal_exact_signs(monkeypatch: pytest.MonkeyPatch) -> None:
    """``_facing`` leaves out of the exact signs the determinants that are zero because the
    candidate is at a corner or a base end is the twin of the candidate's neighbour (bridged
    stars); on every candidate of every sub-polygon it decides as with every exact sign, on
    those stars and on combs whose other unsure determinants are not zero."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    parts, starts, seqs = combs_and_stars(np.random.default_rng(47), 30, 30, 1e-15)
    lo, hi, c = every_candidate(parts, starts, 2)
    cleared = []
    drop = batch_bsp._drop_known_zeros

    def counting(seqs, lo, hi, c, dx, dy, unsure):
        before = int(unsure.sum())
        drop(seqs, lo, hi, c, dx, dy, unsure)
        cleared.append(before - int(unsure.sum()))

    monkeypatch.setattr(batch_bsp, "_drop_known_zeros", counting)
    passed = batch_bsp._facing(seqs, lo, hi, c)
    monkeypatch.setattr(batch_bsp, "_drop_known_zeros", lambda *args: None)
    exact = batch_bsp._facing(seqs, lo, hi, c)
    assert sum(cleared) > 100 and 0.05 < passed.mean() < 0.95
    assert np.array_equal(passed, exact)


@pytest.mark.parametrize("scale", [1.0, 0.005, 1e100])
def test_bent_vertices_in_triangle_equal_every_bent_vertex_tested(scale: float) -> None:
    """``_bent_in_triangle`` (a box filter in float32, then exact signs) finds what testing
    every bent position between lo and hi exactly finds, on bridged stars far from the
    origin; at scale 0.005 (radius 0.5 m, float32 spacing 0.5 m there) float32 rounding
    merges most coordinates and the filter passes them to the exact signs; at scale 1e100
    every coordinate is beyond float32's range (infinite there, still in order)."""
    from bsp_triangulate.geometry.predicates import orient_many
    from bsp_triangulate.tree import lockstep as batch_bsp

    rng = np.random.default_rng(53)
    offset = np.array([512_345.678, 6_012_345.25])
    parts = []
    for _ in range(40):
        seq, twin = bridged_star(rng, int(rng.integers(6, 30)), False)
        parts.append(((seq - offset) * scale + offset, twin))
    starts, seqs = laid_out(parts, False, np.ones(len(parts), dtype=bool))
    sx, sy = seqs.sx, seqs.sy
    lo, hi, c = every_candidate(parts, starts, 3)
    ccw = orient_many(sx[hi], sy[hi], sx[lo], sy[lo], sx[c], sy[c]) > 0
    lo, hi, c = lo[ccw], hi[ccw], c[ccw]
    bad, found = batch_bsp._bent_in_triangle(seqs, lo, hi, c)
    # every bent position strictly between lo and hi, not at a corner's point
    owner = np.repeat(np.arange(len(lo)), hi - lo - 1)
    p = ragged_index(lo + 1, hi - lo - 1)
    keep = seqs.proven[p] & np.isin(p, seqs.bent)
    for corner in (hi, lo, c):
        keep &= (sx[p] != sx[corner[owner]]) | (sy[p] != sy[corner[owner]])
    owner, p = owner[keep], p[keep]
    signs = np.stack(
        [
            orient_many(sx[u[owner]], sy[u[owner]], sx[v[owner]], sy[v[owner]], sx[p], sy[p])
            for u, v in ((hi, lo), (lo, c), (c, hi))
        ]
    )
    closed = np.bincount(owner[(signs >= 0).all(axis=0)], minlength=len(lo)) > 0
    expected_bad = closed | batch_bsp._bridge_at_corner(seqs, lo, hi, c)
    strictly = (signs > 0).all(axis=0)
    expected_found = np.full(len(lo), len(sx))
    np.minimum.at(expected_found, owner[strictly], p[strictly])
    expected_found[expected_found == len(sx)] = -1
    assert len(lo) > 20_000 and 0.05 < expected_bad.mean() < 0.95
    assert (expected_found >= 0).sum() > 1_000
    assert np.array_equal(bad, expected_bad)
    assert np.array_equal(found, expected_found)


@pytest.mark.parametrize("wobble", [0.0, 1e-15, 1e-12, 1e-9])
def test_rule_delaunay_on_near_collinear_combs(wobble: float) -> None:
    rng = np.random.default_rng(19)
    polygons = [near_collinear_polygon(rng, int(rng.integers(5, 25)), wobble) for _ in range(40)]
    assert batch_equals_engine(polygons, "delaunay") >= 0.9 * len(polygons)


def near_cocircular_polygon(rng: np.random.Generator, count: int, wobble: float) -> list:
    """Vertices on a circle far from the origin, moved by ``wobble`` (relative) along the
    radius: the in-circle signs of most candidate pairs are within rounding of zero."""
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, count))
    radius = 50.0 * (1.0 + wobble * rng.standard_normal(count))
    ring = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
    ring += np.array([512_345.678, 6_012_345.25])
    return [ring]


def guesses_against_tries(monkeypatch: pytest.MonkeyPatch) -> dict:
    """Makes every round of rule delaunay compare its apexes with the exact tries of all
    its nodes; the counts returned: nodes, nodes left to the tries by the float guess, and
    nodes whose apex is lo + 1 in a round of wider nodes (their guess tables are padded
    with lo + 1's copies)."""
    from bsp_triangulate.tree import lockstep

    apex, tries = lockstep._delaunay_apex, lockstep._delaunay_tries
    counts = {"nodes": 0, "tried": 0, "padded": 0}

    def both(seqs, state):
        found, chosen = apex(seqs, state)
        exact_found, exact = tries(seqs, state)
        assert np.array_equal(found, exact_found)
        assert np.array_equal(chosen[found], exact[found])
        counts["nodes"] += state.shape[1]
        lo, hi = state[lockstep._LO], state[lockstep._HI]
        narrower = hi - lo < (hi - lo).max()
        counts["padded"] += int(np.count_nonzero(found & narrower & (chosen == lo + 1)))
        return found, chosen

    def counted(seqs, state):
        counts["tried"] += state.shape[1]
        return tries(seqs, state)

    monkeypatch.setattr(lockstep, "_delaunay_apex", both)
    monkeypatch.setattr(lockstep, "_delaunay_tries", counted)
    return counts


@pytest.mark.parametrize("wobble", [0.0, 1e-16, 1e-14, 1e-12, 1e-9])
def test_rule_delaunay_float_guess_equals_exact_tries_near_cocircular(
    wobble: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Nearly cocircular vertices: the float guess decides a node only beyond its error
    bounds, so its apexes are those of the exact tries, and the results the engine's."""
    counts = guesses_against_tries(monkeypatch)
    rng = np.random.default_rng(23)
    polygons = [near_cocircular_polygon(rng, int(rng.integers(4, 40)), wobble) for _ in range(40)]
    assert batch_equals_engine(polygons, "delaunay") == len(polygons)
    assert counts["nodes"] > counts["tried"] > 0


def test_rule_delaunay_float_guess_equals_exact_tries_on_stars_of_many_sizes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Stars with an island, of 4 to 60 vertices: each round's guess tables mix nodes of
    every span, the narrower ones padded with copies of their last candidate, which is
    often the apex. The guess decides most nodes, and as the exact tries do."""
    counts = guesses_against_tries(monkeypatch)
    rng = np.random.default_rng(29)
    polygons = []
    for _ in range(60):
        count = int(rng.integers(4, 61))
        angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, count))
        radius = rng.uniform(40.0, 100.0, count)
        outer = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
        island = 10.0 * np.column_stack([np.cos(angles[:3]), np.sin(angles[:3])])[::-1]
        polygons.append([outer + 1_000.5, island + 1_000.5])
    # a few shells of 4 to 6 vertices cross their island: the engine's
    assert batch_equals_engine(polygons, "delaunay") >= 0.9 * len(polygons)
    # a padded copy of a guess at lo + 1 decides as that guess (else about 18 % are tried)
    assert counts["tried"] < 0.05 * counts["nodes"]
    assert counts["padded"] > 100


def test_a_run_whose_box_test_overflows_is_tested() -> None:
    # coordinates of 1e154: the box test's products overflow (nan), which surely-outside must
    # not read as outside; the full table finds the triangle blocked, so must the runs
    from bsp_triangulate.tree import lockstep as batch_bsp

    points = [(-2, -4), (-2, -1), (3, 0), (-4, -1), (1, 3), (2, 4), (-3, 3), (-4, 1), (-2, -3)]
    points += [(1, -2), (1, -2), (-3, 2), (-2, -4)]
    xy = np.array(points, dtype=np.float64) * 1e154
    sx, sy = xy[:, 0].copy(), xy[:, 1].copy()
    with np.errstate(all="ignore"):
        seqs = batch_bsp.Sequences.of(sx, sy, np.full(len(xy), -1), np.array([0]), False)
        lo, _, _, bad = runs_against_the_whole_table(
            seqs, np.array([2]), np.array([12]), np.array([8])
        )
    assert len(lo) == 1 and bad.tolist() == [True]
