"""The batch path (``triangulate_batch``) against the engine, field by field.

Wherever the batch path returns a result it must equal ``triangulate``'s (vertices, triangles,
parent, depth, side, dtypes included); where it returns None the engine decides. Every test
also asserts that the batch path handled most of its polygons, so that it cannot pass by
returning None. Inputs: random polygons (integer grids with collinear runs, polyomino outlines,
float stars, 1-3 islands, islands touching at a vertex, both orientations, z values with rule
"elevation", duplicate points), earcut's small fixtures and the Swellendam farms layer.
"""

from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest

from bsp_triangulate import TriangulationError, triangulate
from bsp_triangulate.geometry.bridges import split_touching
from bsp_triangulate.geometry.rings import normalise_rings, prepare
from bsp_triangulate.tree import lockstep
from bsp_triangulate.tree.batch import MAX_VERTICES, MID_MIN_COUNT, MID_VERTICES, triangulate_batch

from ...conftest import SHARED_DATA
from ..random_polygons import (
    add_islands,
    is_valid,
    random_polygon,
    rings_are_disjoint,
    star_ring,
    with_z,
)

FIELDS = ("vertices", "triangles", "parent", "depth", "side")
FARMS = SHARED_DATA / "swellendam" / "farms_33S.shp"
EARCUT = SHARED_DATA / "earcut" / "fixtures"


def mismatches(polygons: list, rule: str = "first") -> tuple[list[str], int]:
    """Descriptions of batch results that differ from the engine's, and how many were handled."""
    results = triangulate_batch(polygons, rule)
    assert len(results) == len(polygons)
    problems = []
    handled = 0
    for number, (rings, mine) in enumerate(zip(polygons, results)):
        if mine is None:
            continue
        handled += 1
        try:
            expected = triangulate(rings, rule=rule)
        except TriangulationError as exc:
            problems.append(f"polygon {number}: engine raises {exc}, batch gives a result")
            continue
        differing = first_differing_field(mine, expected)
        if differing is not None:
            problems.append(f"polygon {number}: {differing} differs")
    return problems, handled


def first_differing_field(got: object, want: object) -> str | None:
    """The first of ``FIELDS`` whose array (values or dtype) differs, or None."""
    for name in FIELDS:
        mine, theirs = getattr(got, name), getattr(want, name)
        if mine.dtype != theirs.dtype or not np.array_equal(mine, theirs):
            return name
    return None


def with_duplicates(rnd: random.Random, rings: list) -> list:
    """Each ring with a few points repeated in place and its closing point added."""
    out = []
    for ring in rings:
        points = []
        for point in ring:
            points.append(point)
            if rnd.random() < 0.15:
                points.append(point)
        out.append([*points, points[0]])
    return out


def random_set(seed: int, count: int, **options) -> list:
    rnd = random.Random(seed)
    return [random_polygon(rnd, **options) for _ in range(count)]


@pytest.mark.parametrize(
    ("family", "options"),
    [
        ("integer-star", {}),
        ("polyomino-collinear-runs", {"grid": True}),
        ("float-star", {"integer": False}),
        ("one-to-three-islands", {"islands": None}),
        ("float-islands", {"islands": 2, "integer": False}),
    ],
)
def test_batch_equals_engine_on_random_simple_polygons(family: str, options: dict) -> None:
    seed = sum(map(ord, family))
    if options.get("islands", 0) is None:
        rnd = random.Random(seed)
        polygons = [random_polygon(rnd, islands=rnd.randint(1, 3)) for _ in range(80)]
    else:
        polygons = random_set(seed, 80, **options)
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled >= 0.9 * len(polygons)


def test_batch_equals_engine_with_duplicate_and_closing_points() -> None:
    rnd = random.Random(11)
    polygons = [
        with_duplicates(rnd, random_polygon(rnd, islands=rnd.randint(0, 2))) for _ in range(60)
    ]
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled >= 0.9 * len(polygons)


def test_batch_leaves_touching_islands_to_the_engine_or_agrees() -> None:
    rnd = random.Random(5)
    polygons = [random_polygon(rnd, islands=1, touching=2) for _ in range(60)]
    problems, _ = mismatches(polygons)
    assert problems == []
    results = triangulate_batch(polygons)
    touching = [not rings_are_disjoint(rings) for rings in polygons]
    assert sum(touching) >= 40
    # rings apart from each other (no touching island was found for them) are handled
    assert all(r is not None for r, t in zip(results, touching) if not t)
    # the touching ones go to the engine, the larger ones after the validity proof failed
    assert all(r is None for r, t in zip(results, touching) if t)
    assert (
        sum(t and sum(len(ring) for ring in rings) >= 16 for rings, t in zip(polygons, touching))
        >= 40
    )


@pytest.mark.parametrize("rule", ["first", "delaunay"])
def test_batch_decides_no_polygon_whose_ring_edges_the_engine_splits(rule: str) -> None:
    """The one-polygon builder takes the points the batch path inserted into its rings'
    triangulation without splitting the ring edges at vertices on them: the batch path
    leaves every polygon with such a vertex (or two vertices at one point) to the engine."""
    rnd = random.Random(11)
    polygons = [random_polygon(rnd, islands=1, touching=2) for _ in range(60)]
    polygons += [random_polygon(rnd, islands=2, grid=k % 2 == 0) for k in range(40)]
    square = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
    polygons += [
        [square, [(2.0, 0.0), (1.0, 1.0), (3.0, 1.0)]],  # an island's vertex on the outer edge
        [
            square,
            [(1.0, 1.0), (1.0, 3.0), (3.0, 3.0), (3.0, 1.0)],
            [(2.0, 1.0), (2.5, 2.0), (1.5, 2.0)],
        ],
        [[(0.0, 0.0), (4.0, 0.0), (2.0, 2.0), (4.0, 4.0), (0.0, 4.0), (2.0, 2.0)]],  # a pinch
        [square, [(1.0, 1.0), (1.0, 3.0), (3.0, 3.0), (3.0, 1.0)]],  # apart: decided
    ]
    results = triangulate_batch(polygons, rule)
    decided = 0
    for rings, result in zip(polygons, results):
        if result is None:
            continue
        decided += 1
        clean, axes = normalise_rings(rings, "auto")
        prepared = prepare(clean, axes)
        split = split_touching(prepared.x, prepared.y, prepared.rings)
        assert len(split) == len(prepared.rings)
        assert all(np.array_equal(a, b) for a, b in zip(split, prepared.rings))
    assert results[-1] is not None and all(r is None for r in results[-4:-1])
    assert decided >= 20


def test_batch_equals_engine_with_rule_elevation_on_polygons_with_z() -> None:
    rnd = random.Random(23)
    polygons = [with_z(rnd, random_polygon(rnd, islands=rnd.randint(0, 2))) for _ in range(80)]
    problems, handled = mismatches(polygons, rule="elevation")
    assert problems == []
    # small rings with z 0-9 can be steep (another working plane): left to the engine
    assert handled >= 0.6 * len(polygons)


def test_batch_equals_engine_on_flat_z_with_rule_elevation() -> None:
    """All z equal: every correct candidate ties, the first in candidate order wins."""
    rnd = random.Random(29)
    polygons = [
        [[(x, y, 5.0) for x, y in ring] for ring in random_polygon(rnd, islands=1)]
        for _ in range(40)
    ]
    problems, handled = mismatches(polygons, rule="elevation")
    assert problems == []
    assert handled >= 0.9 * len(polygons)


def test_batch_gives_empty_results_for_degenerate_outer_rings() -> None:
    polygons = [
        [[(0.0, 0.0), (1.0, 1.0), (0.0, 0.0)]],
        [[(2.0, 2.0), (2.0, 2.0), (2.0, 2.0)]],
        [[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]],
    ]
    results = triangulate_batch(polygons)
    assert results[0] is not None and results[0].is_empty
    assert results[1] is not None and results[1].is_empty
    assert results[2] is not None and len(results[2]) == 2
    assert mismatches(polygons)[0] == []


def test_batch_leaves_a_sliver_between_outer_ring_and_island_to_the_engine() -> None:
    """An island 1e-15 inside a square: net area negligible, the engine gives no triangles."""
    t = 1e-15
    outer = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
    island = [(t, t), (t, 4.0 - t), (4.0 - t, 4.0 - t), (4.0 - t, t)]
    square_with_hole = [outer, [(1.0, 1.0), (1.0, 2.0), (2.0, 2.0), (2.0, 1.0)]]
    results = triangulate_batch([[outer, island], square_with_hole])
    assert triangulate([outer, island]).is_empty
    assert results[0] is None
    assert results[1] is not None and len(results[1]) == 8
    assert mismatches([square_with_hole])[0] == []


def test_batch_leaves_unknown_rules_and_large_polygons_to_the_engine() -> None:
    square = [[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]]
    assert triangulate_batch([square], "no-such-rule") == [None]
    angles = np.linspace(0.0, 2.0 * np.pi, MAX_VERTICES + 1, endpoint=False)
    big = [np.column_stack([np.cos(angles), np.sin(angles)])]
    assert triangulate_batch([big, square])[0] is None


def mid_size_polygons(rnd: random.Random, count: int, integer: bool) -> list:
    """Valid star-shaped polygons of MAX_VERTICES to MID_VERTICES points, 0-3 islands."""
    polygons: list = []
    while len(polygons) < count:
        size = rnd.randint(MAX_VERTICES + 1, MID_VERTICES - 20)
        outer = star_ring(rnd, size, radius=rnd.choice((200.0, 1000.0)), integer=integer)
        if not is_valid([outer]):
            continue
        rings = add_islands(rnd, outer, rnd.randint(0, 3), 8.0, integer=integer)
        if rings is not None:
            polygons.append(rings)
    return polygons


@pytest.mark.parametrize("integer", [True, False])
def test_batch_equals_engine_on_many_mid_size_polygons(integer: bool) -> None:
    rnd = random.Random(31 + integer)
    polygons = mid_size_polygons(rnd, MID_MIN_COUNT + 4, integer)
    small = [random_polygon(rnd, islands=1) for _ in range(20)]
    problems, handled = mismatches(polygons + small)
    assert problems == []
    assert handled >= 0.9 * (len(polygons) + len(small))


def test_few_mid_size_polygons_are_left_to_the_engine() -> None:
    rnd = random.Random(5)
    polygons = mid_size_polygons(rnd, MID_MIN_COUNT - 1, integer=False)
    assert triangulate_batch(polygons) == [None] * len(polygons)


def without_closing_points(rings: list) -> list:
    return [[tuple(p) for p in (r[:-1] if len(r) > 1 and r[0] == r[-1] else r)] for r in rings]


def test_batch_equals_engine_on_small_earcut_fixtures() -> None:
    polygons = []
    for path in sorted(EARCUT.glob("*.json")):
        rings = json.loads(path.read_text())
        if sum(len(ring) for ring in rings) <= MAX_VERTICES:
            polygons.append(rings)
    problems, _ = mismatches(polygons)
    assert problems == []
    # most small fixtures touch or are degenerate on purpose; the plain ones must be handled
    plain = [is_valid(r) and rings_are_disjoint(r) for r in map(without_closing_points, polygons)]
    results = triangulate_batch(polygons)
    assert sum(plain) >= 8
    assert all(r is not None for r, p in zip(results, plain) if p)


def farm_polygons(limit: int) -> list:
    import shapely
    from osgeo import ogr

    source = ogr.Open(str(FARMS))
    polygons = []
    for feature in source.GetLayer(0):
        geometry = shapely.from_wkb(bytes(feature.GetGeometryRef().ExportToWkb()))
        for part in getattr(geometry, "geoms", [geometry]):
            rings = [np.asarray(part.exterior.coords)]
            rings += [np.asarray(ring.coords) for ring in part.interiors]
            if sum(len(r) for r in rings) <= 60:
                polygons.append(rings)
        if len(polygons) >= limit:
            break
    return polygons


def test_batch_equals_engine_on_swellendam_farms() -> None:
    polygons = farm_polygons(120)
    assert len(polygons) >= 100
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled >= 0.9 * len(polygons)


def test_polygons_the_caller_proved_valid_skip_the_search_with_the_same_results(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from bsp_triangulate import triangulate_many
    from bsp_triangulate.tree import batch

    rnd = random.Random(31)
    valid = [random_polygon(rnd, islands=rnd.randint(0, 2)) for _ in range(40)]
    touching = [random_polygon(rnd, islands=1, touching=2) for _ in range(40)]
    polygons = valid + touching
    plain = triangulate_batch(polygons)
    flags = [True] * len(valid) + [False] * len(touching)
    told = triangulate_batch(polygons, proven=flags)
    for mine, expected in zip(told, plain):
        assert (mine is None) == (expected is None)
        if mine is not None:
            for name in ("vertices", "triangles", "parent", "depth", "side"):
                assert np.array_equal(getattr(mine, name), getattr(expected, name)), name
    assert sum(r is not None for r in told[: len(valid)]) >= 36
    assert all(r is None for r in told[len(valid) :])
    # neither the proof nor the touching search sees a polygon the caller proved
    seen = []
    for name in ("proven_valid_rings", "touching_polygons"):
        original = getattr(batch, name)

        def wrapped(*args, _original=original):
            seen.append(int(args[-1].sum()))
            return _original(*args)

        monkeypatch.setattr(batch, name, wrapped)
    triangulate_batch(valid, proven=[True] * len(valid))
    assert seen and not any(seen)
    triangulate_batch(valid)
    assert any(seen)
    with pytest.raises(ValueError, match="flags"):
        triangulate_many(polygons, proven=flags[:-1])


@pytest.mark.parametrize("elevations", ["smooth", "near ties"])
def test_rule_elevation_on_larger_stars_equals_engine(elevations: str) -> None:
    """The closest candidate is taken without testing the others only where the choice is
    sure: smooth terrain, and decimal elevations whose distances tie within rounding."""
    rng = np.random.default_rng(37)
    polygons = []
    for _ in range(40):
        count = int(rng.integers(20, 80))
        angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, count))
        radius = np.where(np.arange(count) % 2 == 0, 100.0, rng.uniform(30.0, 90.0, count))
        x, y = radius * np.cos(angles), radius * np.sin(angles)
        if elevations == "smooth":
            z = 50.0 + 0.3 * x - 0.2 * y + 5.0 * np.sin(x / 17.0)
        else:
            # decimal tenths: 2 zc - z1 - z2 rounds, so near-ties are decided exactly
            z = rng.choice([0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.1 + 0.2], count)
        polygons.append([np.column_stack([x, y, z])])
    problems, handled = mismatches(polygons, rule="elevation")
    assert problems == []
    assert handled == len(polygons)


@pytest.mark.parametrize("elevations", ["smooth", "whole metres"])
def test_rule_elevation_near_candidates_first_equals_engine(
    elevations: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A node of many candidates takes its closest ones first, and where its choice among
    them may not hold against the others it is decided again in a later round with more of
    them, or with all: the trees are the engine's, on mid-size polygons (all three paths
    taken)."""
    calls = {"nearest": 0, "wider": 0, "all": 0}
    elevation_apex = lockstep._elevation_apex

    def counted(seqs, sz, state, top_z):
        block = state[lockstep._BLOCK]
        calls["nearest"] += int((block < 0).sum())
        calls["wider"] += int((block > 0).sum())
        calls["all"] += int((block == 0).sum())
        return elevation_apex(seqs, sz, state, top_z)

    monkeypatch.setattr(lockstep, "_elevation_apex", counted)
    rnd = random.Random(41)
    polygons = []
    for rings in mid_size_polygons(rnd, MID_MIN_COUNT + 4, integer=False):
        lifted = []
        for ring in rings:
            xy = np.asarray(ring, dtype=np.float64)
            z = 80.0 + 0.05 * xy[:, 0] - 0.03 * xy[:, 1] + 6.0 * np.sin(xy[:, 0] / 23.0)
            lifted.append(np.column_stack([xy, np.round(z) if elevations != "smooth" else z]))
        polygons.append(lifted)
    problems, handled = mismatches(polygons, rule="elevation")
    assert problems == []
    assert handled == len(polygons)
    assert calls["nearest"] and calls["wider"] and calls["all"]


def concave_stars(rnd: random.Random, count: int) -> list:
    """Concave stars of 16-40 vertices (valid, proven: star-shaped) with one or two islands."""
    polygons: list = []
    while len(polygons) < count:
        outer = star_ring(rnd, rnd.randint(16, 40), radius=100.0, integer=False)
        rings = add_islands(rnd, outer, rnd.randint(1, 2), 12.0, integer=False)
        if is_valid([outer]) and rings is not None:
            polygons.append(rings)
    return polygons


def family_polygons(family: str) -> list:
    rnd = random.Random(sum(map(ord, family)))
    if family == "farms":
        return farm_polygons(400)
    if family == "float-islands":
        return [random_polygon(rnd, islands=2, integer=False) for _ in range(300)]
    if family == "integer-stars":
        return [random_polygon(rnd, islands=rnd.randint(0, 1)) for _ in range(300)]
    if family == "grid":
        return [random_polygon(rnd, grid=True) for _ in range(300)]
    return concave_stars(rnd, 300)


def with_terrain_z(polygons: list) -> list:
    """The polygons with z from a smooth terrain (a slope and a sine), so that rule
    elevation has something to choose by."""
    return [
        [[(x, y, 20.0 + 0.2 * x - 0.1 * y + 3.0 * math.sin(y / 9.0)) for x, y in ring]
         for ring in rings]
        for rings in polygons
    ]  # fmt: skip


class MendLog:
    """Per call of ``lockstep._reopened``, how many failing nodes it found a wrong ancestor
    for (their subtrees mended in place), in ``mended``."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.mended: list[int] = []
        reopened = lockstep._reopened

        def counted(seqs, record, failing):
            nodes, repaired = reopened(seqs, record, failing)
            self.mended.append(int(repaired.sum()))
            return nodes, repaired

        monkeypatch.setattr(lockstep, "_reopened", counted)


class RestartLog:
    """The trees that ``build_trees`` left to be built again with every table, as (its call,
    sequence) pairs. Unless ``mend``, trees are not mended in place (``_reopened``): every
    tree that does not complete is built again."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, mend: bool = False) -> None:
        from bsp_triangulate.tree import batch

        if not mend:
            monkeypatch.setattr(lockstep, "_REOPEN_LEVELS", 0)
        self.call = 0
        self.restarted: set[tuple[int, int]] = set()
        build_trees = batch.build_trees

        def counted_build_trees(*args, **kwargs):
            self.call += 1
            trees = build_trees(*args, **kwargs)
            self.restarted.update((self.call, int(i)) for i in np.flatnonzero(trees.again))
            return trees

        monkeypatch.setattr(batch, "build_trees", counted_build_trees)


@pytest.mark.parametrize(
    "family", ["farms", "float-islands", "integer-stars", "grid", "concave-stars"]
)
def test_candidates_decided_by_bent_vertices(family: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Candidates of proven-valid polygons decided without a table (``_bent_in_triangle``):
    a rejection agrees with the whole table, and a candidate it passes but the table rejects
    stops its tree, which is then built again with every table; all results equal the
    engine's."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    counts = {"passed": 0, "rejected": 0, "passed ears": 0, "passed and bad": 0, "least": 0}
    monkeypatch.setattr(batch_bsp, "_LEAST_FEW", 1)  # the least-angle apex in every call
    wrong: set[tuple[int, int]] = set()
    log = RestartLog(monkeypatch)
    bent_in_triangle = batch_bsp._bent_in_triangle

    def checked(seqs, lo, hi, c, crossings=False, across=None, least=None):
        bad, found = bent_in_triangle(seqs, lo, hi, c, crossings, across, least)
        table_bad, _ = batch_bsp._all_tables(seqs, lo, hi, c)
        if least is not None:
            # a failing ear's apex of least angle that faces its base passes every table,
            # or its tree (a wrong pass above it) is built again
            took = np.flatnonzero(least >= 0)
            took = took[batch_bsp._facing(seqs, lo[took], hi[took], least[took])]
            counts["least"] += len(took)
            least_bad, _ = batch_bsp._all_tables(seqs, lo[took], hi[took], least[took])
            sequence = np.searchsorted(seqs.starts, lo[took[least_bad]], side="right") - 1
            wrong.update((log.call, int(i)) for i in sequence)
        counts["passed"] += int((~bad).sum())
        counts["rejected"] += int(bad.sum())
        counts["passed ears"] += int((~bad & (c == hi - 1)).sum())
        counts["passed and bad"] += int((~bad & table_bad).sum())
        differ = bad != table_bad
        sequence = np.searchsorted(seqs.starts, lo[differ], side="right") - 1
        wrong.update((log.call, int(i)) for i in sequence)
        # a blocker lies strictly inside the triangle
        hit = np.flatnonzero(found >= 0)
        assert batch_bsp._strictly_inside(seqs, hi[hit], lo[hit], c[hit], found[hit]).all()
        return bad, found

    monkeypatch.setattr(batch_bsp, "_bent_in_triangle", checked)
    polygons = family_polygons(family)
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled >= 0.9 * len(polygons)
    assert wrong <= log.restarted
    assert counts["passed"] > 3 * counts["rejected"] > 0
    assert counts["passed ears"] > 0
    assert counts["least"] > 0
    if family == "concave-stars":
        # notches of the exterior across a triangle: passed, found wrong, started again
        assert counts["passed and bad"] > 0
        assert wrong


@pytest.mark.parametrize(
    "family", ["farms", "float-islands", "integer-stars", "grid", "concave-stars"]
)
def test_rounds_of_many_nodes_equal_engine(family: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Rounds of many nodes (every round here) test a node's first candidate with
    ``_facing_ear`` and the others' spans with ``_facing``; a node whose first candidate
    fails the ear test goes on to its next ones in the same round. The ear test agrees with
    ``_facing`` item by item, and all results equal the engine's."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    monkeypatch.setattr(batch_bsp, "_EAR_ROUND", 0)
    counts = {"ears": 0, "ears passed": 0, "spans": 0, "later apex at once": 0}
    facing_ear, first_passing = batch_bsp._facing_ear, batch_bsp._first_passing
    first_correct = batch_bsp._first_correct

    def counted_first_correct(seqs, state):
        correct, apex, blocker = first_correct(seqs, state)
        fresh = state[batch_bsp._CAND] == state[batch_bsp._HI] - 1
        counts["later apex at once"] += int(
            (fresh & correct & (apex < state[batch_bsp._HI] - 1)).sum()
        )
        return correct, apex, blocker

    def checked_ear(seqs, lo, hi):
        passed = facing_ear(seqs, lo, hi)
        assert np.array_equal(passed, batch_bsp._facing(seqs, lo, hi, hi - 1))
        counts["ears"] += len(lo)
        counts["ears passed"] += int(passed.sum())
        return passed

    def counted_first_passing(seqs, lo, hi, block, nodes, top, count):
        counts["spans"] += int((count > 1).sum())
        return first_passing(seqs, lo, hi, block, nodes, top, count)

    monkeypatch.setattr(batch_bsp, "_facing_ear", checked_ear)
    monkeypatch.setattr(batch_bsp, "_first_passing", counted_first_passing)
    monkeypatch.setattr(batch_bsp, "_first_correct", counted_first_correct)
    polygons = family_polygons(family)
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled >= 0.9 * len(polygons)
    assert counts["ears"] > counts["ears passed"] > 0
    assert counts["spans"] > 0
    assert counts["later apex at once"] > 0


def test_trees_built_again_that_fail_are_left_to_the_engine(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A tree to build again with every table keeps its place in its group's results until
    it is built; where that build does not complete either, the polygon leaves the batch
    results (to the engine), in the listed and the packed results alike, and the others are
    untouched."""
    from bsp_triangulate import api
    from bsp_triangulate.packed import PackedPolygons
    from bsp_triangulate.tree import batch

    polygons = concave_stars(random.Random(43), 300)
    log = RestartLog(monkeypatch)
    build_trees = batch.build_trees

    def full_tables_fail(*args, **kwargs):
        trees = build_trees(*args, **kwargs)
        if kwargs.get("proven", args[9] if len(args) > 9 else None) is None:
            trees.ok[:] = False
        return trees

    monkeypatch.setattr(batch, "build_trees", full_tables_fail)
    listed = triangulate_batch(polygons)
    again = len(log.restarted)
    assert again > 0
    assert sum(result is None for result in listed) == again
    problems, handled = mismatches(polygons)
    assert problems == [] and handled == len(polygons) - again
    packed = api.triangulate_packed(PackedPolygons.of(polygons))
    for rings, result in zip(polygons, packed.to_list()):
        assert first_differing_field(result, triangulate(rings)) is None


def test_trees_started_again_under_rule_elevation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rule "elevation" takes the closest of the candidates it believes correct: a wrong one
    taken without a table stops its tree, which starts again and equals the engine's."""
    polygons = with_terrain_z(concave_stars(random.Random(41), 300))
    log = RestartLog(monkeypatch)
    problems, handled = mismatches(polygons, rule="elevation")
    assert problems == []
    assert handled == len(polygons)
    assert log.restarted


# rule "delaunay": the largest angle among all correct candidates (cocircular ties to the
# first in candidate order), and Delaunay bridges; the same families as above


@pytest.mark.parametrize(
    ("family", "options"),
    [
        ("integer-star", {}),
        ("polyomino-collinear-runs", {"grid": True}),
        ("float-star", {"integer": False}),
        ("one-to-three-islands", {"islands": None}),
        ("float-islands", {"islands": 2, "integer": False}),
    ],
)
def test_rule_delaunay_equals_engine_on_random_simple_polygons(family: str, options: dict) -> None:
    seed = sum(map(ord, family)) + 1
    if options.get("islands", 0) is None:
        rnd = random.Random(seed)
        polygons = [random_polygon(rnd, islands=rnd.randint(1, 3)) for _ in range(80)]
    else:
        polygons = random_set(seed, 80, **options)
    problems, handled = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert handled >= 0.8 * len(polygons)


def test_rule_delaunay_with_duplicate_and_closing_points() -> None:
    rnd = random.Random(13)
    polygons = [
        with_duplicates(rnd, random_polygon(rnd, islands=rnd.randint(0, 2))) for _ in range(60)
    ]
    problems, handled = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert handled >= 0.8 * len(polygons)


def regular_polygons(count: int) -> list:
    """Regular polygons (all vertices cocircular), squares with square islands and grid
    rectangles: every base has cocircular candidates, decided by the tie rule."""
    polygons: list = []
    for k in range(count):
        n = 4 + k % 13
        angles = 2.0 * np.pi * np.arange(n) / n
        radius = 10.0 + k
        polygons.append([np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])])
        size = 4 + k % 5
        outer = [(0, 0), (size, 0), (size, size), (0, size)]
        island = [(1, 1), (1, 2), (2, 2), (2, 1)]
        polygons.append([outer, island] if size > 4 else [outer])
        polygons.append([[(x, 0) for x in range(size)] + [(size, 1), (0, 1)]])
    return polygons


def test_rule_delaunay_on_cocircular_vertices_equals_engine(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Cocircular candidates are never decided by the float guess: the exact tries take
    them, with the first in candidate order among the best."""
    from bsp_triangulate.tree import lockstep

    tried = []
    tries = lockstep._delaunay_tries

    def counted(seqs, state):
        tried.append(state.shape[1])
        return tries(seqs, state)

    monkeypatch.setattr(lockstep, "_delaunay_tries", counted)
    polygons = regular_polygons(40)
    problems, handled = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert handled == len(polygons)
    assert sum(tried) > 0


@pytest.mark.parametrize(("tries", "width"), [(8, 8), (0, 1), (1, 3)])
def test_rule_delaunay_tries_alone_equal_engine(
    tries: int, width: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every node through the exact tries (no float guess): the same results, whether a
    node tries its candidates one by one first or goes at once to testing the next few
    (doubling) of those left."""
    from bsp_triangulate.tree import lockstep

    monkeypatch.setattr(lockstep, "_delaunay_apex", lockstep._delaunay_tries)
    monkeypatch.setattr(lockstep, "_DELAUNAY_TRIES", tries)
    monkeypatch.setattr(lockstep, "_DELAUNAY_WIDTH", width)
    rnd = random.Random(3)
    polygons = concave_stars(rnd, 60) + regular_polygons(10)
    polygons += [random_polygon(rnd, islands=rnd.randint(0, 2)) for _ in range(40)]
    problems, handled = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert handled >= 0.9 * len(polygons)


@pytest.mark.parametrize(("tries", "width"), [(0, 1), (1, 3)])
def test_rule_delaunay_tries_in_few_at_a_time_choose_as_all_at_once(
    tries: int, width: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Node by node, the exact tries that test the candidates left a few at a time (doubling)
    choose the apexes that testing all of them at once chooses (on these polygons; in a
    proven one, a candidate that the bent positions' tables pass wrongly may be tested in
    one order and not the other, and its tree is then mended)."""
    tries_of = lockstep._delaunay_tries
    compared = []

    def both(seqs, state):
        monkeypatch.setattr(lockstep, "_DELAUNAY_TRIES", tries)
        monkeypatch.setattr(lockstep, "_DELAUNAY_WIDTH", width)
        found, apex = tries_of(seqs, state)
        monkeypatch.setattr(lockstep, "_DELAUNAY_WIDTH", 1 << 40)
        all_found, all_apex = tries_of(seqs, state)
        assert np.array_equal(found, all_found)
        assert np.array_equal(apex, all_apex)
        compared.append(state.shape[1])
        return found, apex

    monkeypatch.setattr(lockstep, "_delaunay_apex", both)
    rnd = random.Random(5)
    # mid-size concave polygons: nodes whose largest-angle candidates fail
    polygons = mid_size_polygons(rnd, MID_MIN_COUNT, integer=False) + regular_polygons(6)
    polygons += [random_polygon(rnd, islands=rnd.randint(0, 2)) for _ in range(30)]
    problems, _ = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert sum(compared) > 10_000


def test_rule_delaunay_on_small_earcut_fixtures_and_farms() -> None:
    polygons = []
    for path in sorted(EARCUT.glob("*.json")):
        rings = json.loads(path.read_text())
        if sum(len(ring) for ring in rings) <= MAX_VERTICES:
            polygons.append(rings)
    problems, _ = mismatches(polygons, rule="delaunay")
    assert problems == []
    farms = farm_polygons(120)
    problems, handled = mismatches(farms, rule="delaunay")
    assert problems == []
    assert handled >= 0.9 * len(farms)


@pytest.mark.parametrize("integer", [True, False])
def test_rule_delaunay_on_many_mid_size_polygons(integer: bool) -> None:
    rnd = random.Random(37 + integer)
    polygons = mid_size_polygons(rnd, MID_MIN_COUNT + 4, integer)
    small = [random_polygon(rnd, islands=1) for _ in range(20)]
    problems, handled = mismatches(polygons + small, rule="delaunay")
    assert problems == []
    assert handled >= 0.8 * (len(polygons) + len(small))


def test_rule_delaunay_bridge_from_another_island_vertex() -> None:
    """The island's leftmost vertex has its nearest target at a notch whose diametral
    circle holds another island vertex: the batch path bridges from the next island vertex
    in ring order, as the engine does."""
    from bsp_triangulate.geometry.bridges import bridge_islands
    from bsp_triangulate.geometry.rings import normalise_rings, prepare

    outer = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 6.0), (2.5, 5.5)]
    outer += [(0.0, 5.0)]
    island = [(4.0, 4.0), (6.0, 3.5), (4.0, 4.9)]
    clean, axes = normalise_rings([outer, island], "auto")
    prepared = prepare(clean, axes)
    bridged = [
        bridge_islands(prepared.x, prepared.y, prepared.rings, prepared.ring_numbers, delaunay=d)
        for d in (False, True)
    ]
    # leftmost vertex 7 (4, 4) for rule first, vertex 9 (4, 4.9) under rule delaunay
    assert bridged[0][6] == 7 and bridged[1][6] == 9
    problems, handled = mismatches([[outer, island]] * 3, rule="delaunay")
    assert problems == []
    assert handled == 3


def test_rule_delaunay_trees_started_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """A candidate passed wrongly without a table and chosen stops its tree, which is
    built again with every table and equals the engine's."""
    polygons = concave_stars(random.Random(47), 300)
    log = RestartLog(monkeypatch)
    problems, handled = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert handled >= 0.9 * len(polygons)
    assert log.restarted


def radial_polygons(rnd: random.Random, count: int) -> list:
    """Polygons of 120-250 vertices whose every radius is drawn anew (+-45 %), with a small
    star island at the centre: fan triangles across them are often crossed by a spike of
    the shell or by the island with no vertex inside."""
    polygons = []
    for _ in range(count):
        n = rnd.randint(120, 250)
        angles = [2.0 * math.pi * k / n for k in range(n)]
        radii = [100.0 * rnd.uniform(0.55, 1.45) for _ in range(n)]
        outer = [(r * math.cos(a), r * math.sin(a)) for r, a in zip(radii, angles)]
        # clockwise, alternately 30 m and 20 m from the centre
        island = [(30.0 - 10.0 * (k % 2), -k * math.pi / 4) for k in range(8)]
        island = [(r * math.cos(a), r * math.sin(a)) for r, a in island]
        polygons.append([np.array(outer), np.array(island)])
    return polygons


@pytest.mark.parametrize("rule", ["first", "delaunay", "elevation"])
def test_trees_mended_in_place(rule: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Radial polygons, whose proven shortcut passes triangles crossed by a spike (rules
    delaunay and elevation: with their checks for such edges off): the wrong node's subtree
    is built again in place (``_reopened``), no tree is built again as a whole, and every
    result equals the engine's; with no ancestor looked at, trees are built again as a
    whole, with the same results. A mended subtree takes the shortcut again below its
    reopened node (``_shortcut_again``); kept on every table, the results are the same."""
    polygons = radial_polygons(random.Random(33), 12)
    # twelve trees: every round would have under 16 open nodes, built one node at a time
    monkeypatch.setattr(lockstep, "_ONE_BY_ONE", 0)
    if rule == "delaunay":
        monkeypatch.setattr(
            lockstep, "_edge_across_sure", lambda seqs, lo, hi, c: np.zeros(len(lo), bool)
        )
        monkeypatch.setattr(lockstep, "_DELAUNAY_EVERY", 1 << 62)
    if rule == "elevation":
        polygons = with_terrain_z(polygons)
        monkeypatch.setattr(lockstep, "_ELEVATION_CROSSINGS", False)
    mends = MendLog(monkeypatch)
    log = RestartLog(monkeypatch, mend=True)
    returned = []
    shortcut_again = lockstep._shortcut_again

    def counted(seqs, waiting, done):
        left = shortcut_again(seqs, waiting, done)
        returned.append(len(waiting) - len(left))
        return left

    monkeypatch.setattr(lockstep, "_shortcut_again", counted)
    problems, handled = mismatches(polygons, rule=rule)
    assert problems == []
    assert handled == len(polygons)
    assert sum(mends.mended) > 0
    assert not log.restarted
    assert sum(returned) > 0

    monkeypatch.setattr(lockstep, "_SHORTCUT_RETURNS", 0)
    assert mismatches(polygons, rule=rule)[0] == []

    log = RestartLog(monkeypatch)
    assert mismatches(polygons, rule=rule)[0] == []
    assert log.restarted


def test_rule_elevation_looks_for_edges_across_in_proven_polygons(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Rule elevation on radial polygons with z: in proven polygons its candidates take the
    bent positions' tables and the test of the edges most likely to cross them
    (``_ELEVATION_CROSSINGS``), so that fewer nodes are mended than without that test (8
    against 66 here), and all results equal the engine's, as they do with every table in
    sub-polygons of more than 64 positions."""
    polygons = with_terrain_z(radial_polygons(random.Random(34), 12))
    mends = MendLog(monkeypatch)
    problems, handled = mismatches(polygons, rule="elevation")
    assert problems == []
    assert handled == len(polygons)
    with_crossings = sum(mends.mended)
    mends.mended.clear()
    monkeypatch.setattr(lockstep, "_ELEVATION_CROSSINGS", False)
    assert mismatches(polygons, rule="elevation")[0] == []
    assert sum(mends.mended) > with_crossings
    monkeypatch.setattr(lockstep, "_ELEVATION_EVERY", 64)
    assert mismatches(polygons, rule="elevation")[0] == []


def test_rule_delaunay_edges_across_sure_guesses(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rule delaunay on radial polygons: a sure guess in a large proven sub-polygon (no
    vertex in its circle) is checked for edges across it (``_edge_across_sure``) and the
    tries there test every position. Each rejection agrees with the whole table, all
    results equal the engine's, and far fewer trees are built again than without both."""
    polygons = radial_polygons(random.Random(31), 12)
    across = lockstep._edge_across_sure
    rejected = []

    def checked(seqs, lo, hi, c):
        bad = across(seqs, lo, hi, c)
        assert lockstep._all_tables(seqs, lo[bad], hi[bad], c[bad])[0].all()
        rejected.append(int(bad.sum()))
        return bad

    log = RestartLog(monkeypatch)
    monkeypatch.setattr(lockstep, "_edge_across_sure", checked)
    problems, handled = mismatches(polygons, rule="delaunay")
    assert problems == []
    assert handled == len(polygons)
    assert sum(rejected) > 0
    with_checks = len(log.restarted)

    monkeypatch.setattr(
        lockstep, "_edge_across_sure", lambda seqs, lo, hi, c: np.zeros(len(lo), bool)
    )
    monkeypatch.setattr(lockstep, "_DELAUNAY_EVERY", 1 << 62)
    log = RestartLog(monkeypatch)
    assert mismatches(polygons, rule="delaunay")[0] == []
    assert len(log.restarted) > 2 * with_checks + 2


def test_crossing_edges_across_fans(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rule first's candidates with two new sides in large proven sub-polygons are also
    checked against the edges most likely to cross them (``_edges_across``): each rejection
    agrees with the whole table, far fewer trees are built again, and all results equal the
    engine's."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    polygons = radial_polygons(random.Random(30), 12)
    # twelve trees: every round would have under 16 open nodes, built one node at a time
    monkeypatch.setattr(batch_bsp, "_ONE_BY_ONE", 0)
    edges_across = batch_bsp._edges_across
    rejected = []

    def checked(seqs, lo, hi, c, corners, across=None):
        bad = edges_across(seqs, lo, hi, c, corners, across)
        table_bad, _ = batch_bsp._all_tables(seqs, lo[bad], hi[bad], c[bad])
        assert table_bad.all()
        rejected.append(int(bad.sum()))
        return bad

    log = RestartLog(monkeypatch)
    monkeypatch.setattr(batch_bsp, "_edges_across", checked)
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled == len(polygons)
    assert sum(rejected) > 0
    with_checks = len(log.restarted)

    monkeypatch.setattr(
        batch_bsp,
        "_edges_across",
        lambda seqs, lo, hi, c, corners, across=None: np.zeros(len(lo), bool),
    )
    log = RestartLog(monkeypatch)
    assert mismatches(polygons)[0] == []
    assert len(log.restarted) > 2 * with_checks


def test_edge_across_blocks_later_candidates(monkeypatch: pytest.MonkeyPatch) -> None:
    """In a long sequence a candidate crossed by an edge with no vertex inside keeps that edge
    as its node's blocker: a later candidate whose side to s_hi the edge crosses fails
    without its tables. Each candidate passed over that way fails the whole table, and all
    results equal the engine's."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    polygons = radial_polygons(random.Random(31), 12)
    monkeypatch.setattr(batch_bsp, "_ONE_BY_ONE", 0)
    monkeypatch.setattr(batch_bsp, "LONG_SEQUENCE", 64)  # these polygons count as long
    first_passing = batch_bsp._first_passing
    passed_over = []

    def checked(seqs, lo, hi, block, nodes, top, count):
        hit, found = first_passing(seqs, lo, hi, block, nodes, top, count)
        edge = block[nodes] <= -2
        if edge.any():
            plain = np.where(block <= -2, -1, block)
            hit_plain, found_plain = first_passing(seqs, lo, hi, plain, nodes, top, count)
            # without the edge a node stops at a candidate that the edge passed over
            over = np.flatnonzero(edge & hit_plain & (~hit | (found < found_plain)))
            if len(over):
                owner = nodes[over]
                bad, _ = batch_bsp._all_tables(seqs, lo[owner], hi[owner], found_plain[over])
                assert bad.all()
                passed_over.append(len(over))
        return hit, found

    monkeypatch.setattr(batch_bsp, "_first_passing", checked)
    problems, handled = mismatches(polygons)
    assert problems == []
    assert handled == len(polygons)
    assert sum(passed_over) > 0


def test_small_sub_polygons_of_long_sequences_are_checked_for_crossings(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """In a long sequence, candidates of sub-polygons from ``_ACROSS_LONG`` positions on
    are checked for edges across them too (a tree built again costs more there): fewer
    trees are built again than with the check from ``_RUN_MIN`` positions only, and all
    results equal the engine's."""
    from bsp_triangulate.tree import lockstep as batch_bsp

    polygons = radial_polygons(random.Random(31), 12)
    monkeypatch.setattr(batch_bsp, "_ONE_BY_ONE", 0)
    monkeypatch.setattr(batch_bsp, "LONG_SEQUENCE", 64)  # these polygons count as long
    log = RestartLog(monkeypatch)
    assert mismatches(polygons)[0] == []
    checked = len(log.restarted)

    monkeypatch.setattr(batch_bsp, "_ACROSS_LONG", batch_bsp._RUN_MIN)
    log = RestartLog(monkeypatch)
    assert mismatches(polygons)[0] == []
    assert len(log.restarted) > checked
