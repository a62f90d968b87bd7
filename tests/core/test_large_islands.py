"""Large polygons with many islands: the faster methods give exactly the results of the plain
ones.

- The small sub-polygons of a long sequence, built all at once by the lock-step builder
  (``tree/subtrees.py``), give the same triangles, parents, depths and sides as the one-step
  builder, under rules first, elevation and delaunay, with the mirrored working plane, with
  touching rings (islands sharing a point with the shell or with each other, a vertex on
  another ring's edge), and with the lock-step calls split into groups.
- The bridge search that tests blocks of candidates at once (``_Bridger.find_bridge``) picks
  the bridge that testing one candidate at a time picks, and long segments tested first near
  their far end give what segments looked up whole give; islands outside the outer ring, as
  given, are searched from once, and the others joined without a search as the searches
  would join them.
- Rule delaunay's outward search on long sub-polygons picks the apex that testing every
  candidate picks.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable

import numpy as np
import pytest

from bsp_triangulate import TriangulationError, triangulate
from bsp_triangulate.geometry import bridges
from bsp_triangulate.tree import one_polygon, subtrees

from .checks import check_triangulation
from .random_polygons import (
    add_islands,
    grid_ring,
    is_valid,
    star_ring,
    touching_island,
    with_random_orientation,
)

FIELDS = ("vertices", "triangles", "parent", "depth", "side")
RULES = ("first", "elevation", "delaunay")


def _wavy(vertices: int, islands: int, seed: int) -> list[np.ndarray]:
    """A wavy shell with small rotated squares on a grid inside (clockwise islands)."""
    rnd = random.Random(seed)
    angles = 2 * np.pi * np.arange(vertices) / vertices
    radii = 100.0 * (1 + 0.08 * np.sin(13 * angles) + 0.02 * np.sin(97 * angles))
    rings = [np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])]
    side = math.ceil(math.sqrt(islands)) + 1
    spacing = 110.0 / side
    for row in range(side):
        for column in range(side):
            cx, cy = -55 + (column + 0.5) * spacing, -55 + (row + 0.5) * spacing
            if len(rings) > islands or math.hypot(cx, cy) > 70:
                continue
            turn, half = rnd.uniform(0, 1.5), spacing * rnd.uniform(0.1, 0.3)
            square = [(-1, -1), (-1, 1), (1, 1), (1, -1)]
            rings.append(
                np.array(
                    [
                        (
                            cx + half * (x * math.cos(turn) - y * math.sin(turn)),
                            cy + half * (x * math.sin(turn) + y * math.cos(turn)),
                        )
                        for x, y in square
                    ]
                )
            )
    return rings


def _lifted(rings: list[np.ndarray]) -> list[np.ndarray]:
    return [np.column_stack([r, np.sin(r[:, 0] / 7) * 10 + np.cos(r[:, 1] / 5) * 5]) for r in rings]


def _one_step(monkeypatch: pytest.MonkeyPatch, rings: list, **options) -> object:
    with monkeypatch.context() as patch:
        patch.setattr(one_polygon._Tree, "_lockstep_rule", lambda self: None)
        return triangulate(rings, **options)


def _same(first: object, second: object) -> None:
    for field in FIELDS:
        a, b = getattr(first, field), getattr(second, field)
        assert a.dtype == b.dtype and np.array_equal(a, b), field


def _touching_islands(vertices: int, seed: int) -> list[np.ndarray]:
    """A wavy shell with islands on a grid that touch in pairs: two triangles meeting at a
    point, or a square with a triangle whose corner lies on the midpoint of the square's edge
    (integer directions and halves: every touching point exact). Clockwise islands."""
    rnd = random.Random(seed)
    rings = _wavy(vertices, 0, seed)[:1]
    directions = [(5, 0), (3, 4), (4, 3), (0, 5), (-3, 4), (-4, 3)]
    for row in range(6):
        for column in range(6):
            centre = np.array([-50.0 + 20 * column, -50.0 + 20 * row])
            if math.hypot(*centre) > 70:
                continue
            u = np.array(rnd.choice(directions), dtype=np.float64)
            v = np.array([-u[1], u[0]])
            if (row + column) % 2:
                for sign in (1, -1):
                    tip = centre + sign * 1.5 * u
                    rings.append(np.array([centre, tip - 0.5 * v, tip + 0.5 * v]))
            else:
                corners = ((-1, -1), (1, -1), (1, 1), (-1, 1))
                rings.append(np.array([centre + 0.5 * (a * u + b * v) for a, b in corners]))
                far = centre + 1.5 * u
                rings.append(np.array([centre + 0.5 * u, far - 0.5 * v, far + 0.5 * v]))
    return [rings[0]] + [r if _clockwise(r) else r[::-1].copy() for r in rings[1:]]


def _clockwise(ring: np.ndarray) -> bool:
    x, y = ring[:, 0], ring[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) < 0


CASES = [
    ("wavy", _wavy(1200, 30, 1)),
    ("wavy mirrored", [r[:, ::-1].copy() for r in _wavy(900, 20, 2)]),
    ("wavy touching", [*_wavy(800, 16, 3), np.array([(100.0 * 1.0, 0.0), (90, -3), (90, 3)])]),
    ("islands touching in pairs", _touching_islands(700, 6)),
]


@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
@pytest.mark.parametrize(("name", "rings"), CASES, ids=[c[0] for c in CASES])
def test_subtrees_of_the_lockstep_builder_match_one_step(
    monkeypatch: pytest.MonkeyPatch, name: str, rings: list, rule: str
) -> None:
    rings = _lifted(rings) if rule == "elevation" else rings
    for invalid in ("fail", "as_given"):
        plain = _one_step(monkeypatch, rings, rule=rule, invalid=invalid)
        fast = triangulate(rings, rule=rule, invalid=invalid)
        _same(plain, fast)
    if name != "wavy touching":
        check_triangulation(rings, fast)


@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
@pytest.mark.parametrize(("name", "rings"), CASES, ids=[c[0] for c in CASES])
def test_small_sub_polygons_built_one_step_in_place_match_one_step(
    monkeypatch: pytest.MonkeyPatch, name: str, rings: list, rule: str
) -> None:
    """Where the lock-step builder is not worth its rounds (or finds no tree), the deferred
    sub-polygons are built one step at a time, each subtree put in its place: the same
    fields as building the whole tree one step at a time."""
    rings = _lifted(rings) if rule == "elevation" else rings
    for invalid in ("fail", "as_given"):
        plain = _one_step(monkeypatch, rings, rule=rule, invalid=invalid)
        with monkeypatch.context() as patch:
            patch.setattr(subtrees, "worth_lockstep", lambda sizes, rule: False)
            _same(plain, triangulate(rings, rule=rule, invalid=invalid))
        with monkeypatch.context() as patch:
            patch.setattr(one_polygon._Tree, "_with_subtrees", lambda self, *args: None)
            _same(plain, triangulate(rings, rule=rule, invalid=invalid))


def test_subtrees_in_several_lockstep_calls(monkeypatch: pytest.MonkeyPatch) -> None:
    rings = _wavy(1500, 40, 4)
    plain = _one_step(monkeypatch, rings)
    monkeypatch.setattr(subtrees, "GROUP_POSITIONS", 300)
    _same(plain, triangulate(rings))


def test_blocked_bridge_search_matches_one_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """Blocks of one candidate test candidates exactly as the plain search does."""
    rings = _wavy(600, 60, 5)
    fast = triangulate(rings, rule="delaunay")
    monkeypatch.setattr(bridges, "_FIRST_BLOCK", 1)
    monkeypatch.setattr(bridges, "_LAST_BLOCK", 1)
    _same(fast, triangulate(rings, rule="delaunay"))
    _same(triangulate(rings), _one_step(monkeypatch, rings))


def _square(cx: float, cy: float) -> np.ndarray:
    """A clockwise 2 x 2 square centred on (cx, cy)."""
    return np.array([(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)]) + np.array([cx, cy])


def _count_near_first(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Per call of ``_Bridger._blocked_near`` from now on, the segments it found blocked."""
    blocked: list[int] = []
    near_first = bridges._Bridger._blocked_near

    def counted(self: bridges._Bridger, *args: object) -> object:
        found = near_first(self, *args)
        blocked.append(0 if found is None else len(found[0]))
        return found

    monkeypatch.setattr(bridges._Bridger, "_blocked_near", counted)
    return blocked


def _outcomes(rings: list[np.ndarray], rules: tuple[str, ...], failing: str) -> list[object]:
    """The triangulations of ``rings`` as given under ``rules``, then the message with which
    rule ``failing`` reports them."""
    found: list[object] = [triangulate(rings, rule=r, invalid="as_given") for r in rules]
    with pytest.raises(TriangulationError) as error:
        triangulate(rings, rule=failing)
    return [*found, str(error.value)]


def _same_outcomes(first: list[object], second: list[object]) -> None:
    for one, other in zip(first[:-1], second[:-1]):
        _same(one, other)
    assert first[-1] == second[-1]


@pytest.mark.parametrize("where", ["outside", "across the shell"])
def test_bridge_search_near_first_matches_whole_segments(
    monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    """An island outside the outer ring, or across it, has no valid bridge: the search tests
    every vertex. Long segments tested first against the edges near their other end give
    the bridges, triangles and errors of segments looked up whole."""
    rings = [*_wavy(1500, 40, 6), _square(130.0 if where == "outside" else 100.0, 0.0)]
    blocked = _count_near_first(monkeypatch)
    monkeypatch.setattr(bridges, "_NEAR_CELLS", (2, 8))
    near = _outcomes(rings, RULES, "first")
    assert sum(blocked) > 0  # segments were found blocked near their far end
    monkeypatch.setattr(bridges, "_NEAR_CELLS", ())
    _same_outcomes(near, _outcomes(rings, RULES, "first"))


class _Forgetful(dict):
    """A bridger's record of hopeless searches that keeps nothing, counting the lookups that
    would have found one."""

    hits = 0

    def get(self, key: object, default: object = None) -> object:
        _Forgetful.hits += key in self.seen
        return default

    def __setitem__(self, key: object, value: object) -> None:
        self.seen.add(key)

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[object] = set()


def test_hopeless_searches_remembered_as_searched_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rule delaunay tries an island with no Delaunay bridge again in later rounds. Islands
    outside the outer ring find no valid target at all: later searches from the same vertex
    test only the vertices joined since, and give what whole searches give."""
    squares = [_square(cx, cy) for cx, cy in ((130.0, 0.0), (0.0, -135.0), (101.0, 0.0))]
    rings = [*_wavy(1200, 30, 8), *squares]
    remembered = _outcomes(rings, ("delaunay",), "delaunay")
    init = bridges._Bridger.__init__

    def forgetful(self: bridges._Bridger, *args: object) -> None:
        init(self, *args)
        self._hopeless = _Forgetful()

    monkeypatch.setattr(bridges._Bridger, "__init__", forgetful)
    whole = _outcomes(rings, ("delaunay",), "delaunay")
    assert _Forgetful.hits > 0  # later searches would have used the record
    _same_outcomes(remembered, whole)


def _coordinates(*rings: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray, list]:
    """x, y of the rings' points one after the other, and each ring's vertex ids."""
    points = np.array([point for ring in rings for point in ring], dtype=np.float64)
    sizes = np.cumsum([0] + [len(ring) for ring in rings])
    ids = [np.arange(start, end) for start, end in zip(sizes[:-1], sizes[1:])]
    return points[:, 0].copy(), points[:, 1].copy(), ids


def _hopeless_then_as_fresh(
    x: np.ndarray, y: np.ndarray, rings: list, island: int, join: Callable
) -> tuple[int, int]:
    """Island ``island``'s first vertex finds no valid target; after ``join`` (the same on a
    fresh bridger) its search finds what the fresh bridger's finds, which is returned."""
    bridger = bridges._Bridger(x, y, rings)
    assert bridger.find_bridge(rings[island], 0) is None
    join(bridger)
    fresh = bridges._Bridger(x, y, rings)
    join(fresh)
    expected = fresh.find_bridge(rings[island], 0)
    assert expected is not None
    assert bridger.find_bridge(rings[island], 0) == expected
    return expected


def test_hopeless_search_finds_the_vertices_joined_since() -> None:
    """A vertex of an island inside the cavity of a C-shaped island, the cavity's opening
    hidden behind the island itself, sees no vertex of the outer ring: its search finds no
    valid target. Once the C-shaped island is joined, its cavity's vertices are valid ones:
    the search again finds what a bridger without the record finds."""
    shell = [(-50, -50), (50, -50), (50, 50), (-50, 50)]
    # counter-clockwise; the cavity x -2..4, y -4..4 opens at the right, y -0.5..0.5
    c_shape = [(-3, -5), (5, -5), (5, -0.5), (4, -0.5), (4, -4), (-2, -4)]
    c_shape += [(-2, 4), (4, 4), (4, 0.5), (5, 0.5), (5, 5), (-3, 5)]
    inner = [(-1, -1), (-1, 1), (1, 1), (1, -1)]  # clockwise
    x, y, rings = _coordinates(shell, c_shape[::-1], inner)
    c_left = len(c_shape) - 1  # (-3, -5), reversed to the end

    def join_c_shape(bridger: bridges._Bridger) -> None:
        target = bridger.find_bridge(rings[1], c_left)
        assert target is not None
        bridger.splice(target[0], rings[1], c_left)

    _hopeless_then_as_fresh(x, y, rings, 2, join_c_shape)


def test_hopeless_searches_forgotten_after_a_bridge_with_no_valid_target() -> None:
    """Two squares outside the outer ring's corner (10, 10): the first finds no valid target
    (it sees the corner, from outside its angle). The second, hidden behind the first, is
    joined to the corner anyway (as given): its bridge leaves the corner outside the angle
    there, which now holds the first square's vertex. The corner is a valid target for it
    from then on, as a bridger without the record finds."""
    shell = [(0, 0), (10, 0), (10, 10), (0, 10)]
    first = [(12, 12), (12, 13), (13, 13), (13, 12)]  # clockwise
    second = [(15, 12), (15, 13), (16, 13), (16, 12)]
    x, y, rings = _coordinates(shell, first, second)

    def join_second(bridger: bridges._Bridger) -> None:
        assert bridger.find_bridge(rings[2], 0) is None
        node, _ = bridger.nearest_occurrence(int(rings[2][0]))
        bridger.splice(node, rings[2], 0)

    assert _hopeless_then_as_fresh(x, y, rings, 1, join_second)[1] == 2  # the corner


def test_hopeless_searches_forgotten_after_a_touching_island() -> None:
    """A triangle below the outer ring's corner (0, 0) finds no valid target. An island
    touching that corner, with an edge along the ring's, leaves a spike there whose angle
    takes every direction but its own: the corner is then a valid target, as a bridger
    without the record finds."""
    shell = [(10, 0), (10, 10), (0, 10), (0, 0)]
    below = [(0, -3), (-1, -4), (1, -4)]
    touching = [(0, 0), (0, 2), (1, 1)]
    x, y, rings = _coordinates(shell, below, touching)

    def join_touching(bridger: bridges._Bridger) -> None:
        target = bridger.find_bridge(rings[2], 0)
        assert target is not None and target[1] == 3  # at the corner (0, 0)
        bridger.splice(target[0], rings[2], 0)

    assert _hopeless_then_as_fresh(x, y, rings, 1, join_touching)[1] == 3


def test_segments_near_first_clear_as_looked_up_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    """From every vertex to islands' vertices near and far, long and short segments, clear
    and blocked: the near-first lookups find each clear exactly where whole lookups do."""
    x, y, ids = _coordinates(*(ring.tolist() for ring in _wavy(1500, 40, 7)))
    us = np.arange(len(x))
    targets = (int(ids[1][0]), int(ids[20][2]), int(ids[-1][1]))
    blocked = _count_near_first(monkeypatch)
    monkeypatch.setattr(bridges, "_NEAR_CELLS", (2, 8))
    near = [bridges._Bridger(x, y, ids)._segments_looked_up(us, w) for w in targets]
    assert sum(blocked) > 0
    monkeypatch.setattr(bridges, "_NEAR_CELLS", ())
    for w, expected in zip(targets, near):
        whole = bridges._Bridger(x, y, ids)._segments_looked_up(us, w)
        assert 0 < whole.sum() < len(whole)
        assert np.array_equal(whole, expected)


def test_lockstep_subtrees_only_where_many_advance_together(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Many small sub-polygons go to the lock-step builder; a deep chain alone (a comb of
    near-collinear teeth) is built one step at a time, as a lock-step round per triangle
    would cost far more."""
    from .tree.test_batch_internals import near_collinear_polygon

    calls: list[int] = []
    build = subtrees.build_subtrees
    monkeypatch.setattr(
        subtrees, "build_subtrees", lambda *a, **k: calls.append(1) or build(*a, **k)
    )
    triangulate(_wavy(8000, 200, 1))
    assert calls
    calls.clear()
    rng = np.random.default_rng(29)
    comb = next(
        p for p in (near_collinear_polygon(rng, 140, 0.0) for _ in range(20)) if len(p[0]) > 260
    )
    plain = _one_step(monkeypatch, comb)
    _same(plain, triangulate(comb))
    assert not calls


def test_delaunay_subtrees_of_the_lockstep_builder_match_one_step(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Rule delaunay's small sub-polygons of a long sequence go to the lock-step builder
    too: the same tree, field by field, as one step at a time."""
    calls: list[str] = []
    build = subtrees.build_subtrees
    monkeypatch.setattr(
        subtrees, "build_subtrees", lambda *a, **k: calls.append(a[-1]) or build(*a, **k)
    )
    # sub-polygons of up to 256 positions, as under rule first: many subtrees on these sizes
    monkeypatch.setattr(one_polygon, "DELAUNAY_POSITIONS", 256)
    for rings in (_wavy(5000, 100, 1), [r[:, ::-1].copy() for r in _wavy(4000, 80, 6)]):
        fast = triangulate(rings, rule="delaunay")
        _same(_one_step(monkeypatch, rings, rule="delaunay"), fast)
        check_triangulation(rings, fast)
    assert "delaunay" in calls


def _grid_comb(teeth: int) -> list[np.ndarray]:
    """A comb on the integer grid (teeth of width 1 and 2, collinear runs along every edge,
    many cocircular quadruples), with square islands between the teeth's roots."""
    outer = [(0.0, 0.0)]
    for k in range(teeth):
        x = 3.0 * k
        outer += [(x + 1.0, 0.0), (x + 1.0, 5.0 + k % 3), (x + 2.0, 5.0 + k % 3), (x + 2.0, 0.0)]
    width = 3.0 * teeth + 1.0
    outer += [(width, 0.0)]
    outer += [(width, -float(y)) for y in range(1, 7)]
    outer += [(float(x), -6.0) for x in range(int(width) - 1, -1, -1)]
    outer += [(0.0, -float(y)) for y in range(5, 0, -1)]
    rings = [np.array(outer)]
    for k in range(0, teeth - 1, 2):
        x = 3.0 * k + 2.0
        rings.append(np.array([(x, -4.0), (x, -2.0), (x + 2.0, -2.0), (x + 2.0, -4.0)]))
    return rings


@pytest.mark.parametrize(
    ("name", "rings"),
    [
        ("wavy", _wavy(1500, 40, 7)),
        ("wavy mirrored", [r[:, ::-1].copy() for r in _wavy(1200, 30, 8)]),
        ("grid comb", _grid_comb(60)),
    ],
    ids=["wavy", "wavy mirrored", "grid comb"],
)
def test_delaunay_outward_search_matches_every_candidate(
    monkeypatch: pytest.MonkeyPatch, name: str, rings: list
) -> None:
    """Rule delaunay on long sub-polygons first tries the position next to an end of the base
    that sees it under the largest angle (shown in scalars: correct, its circle empty), then
    searches outwards from the base (positions surely right of the chord dropped in float,
    the rest tested exactly in turn): the same tree as testing every candidate, also where
    many positions lie on chords and circles (the grid comb) or share a point (bridges)."""
    searched: list[int] = []
    shown: list[int] = []
    search = one_polygon._Tree._delaunay_apex
    near_ends = one_polygon._Tree._delaunay_near_ends

    def counted(self, lo, hi):
        searched.append(hi - lo)
        return search(self, lo, hi)

    def counted_near_ends(self, lo, hi):
        apex = near_ends(self, lo, hi)
        shown.append(apex)
        return apex

    monkeypatch.setattr(one_polygon._Tree, "_delaunay_apex", counted)
    monkeypatch.setattr(one_polygon._Tree, "_delaunay_near_ends", counted_near_ends)
    fast = _one_step(monkeypatch, rings, rule="delaunay")
    assert max(searched) > one_polygon.SMALL_SEQUENCE
    # both ways of deciding a long sub-polygon are taken
    assert 0 < sum(apex >= 0 for apex in shown) < len(shown)
    monkeypatch.setattr(
        one_polygon._Tree,
        "_delaunay_apex",
        lambda self, lo, hi: self._delaunay_small(lo, hi, np.arange(hi - 1, lo, -1)),
    )
    _same(_one_step(monkeypatch, rings, rule="delaunay"), fast)
    check_triangulation(rings, fast)


def _random_delaunay_polygon(seed: int) -> list:
    """A random polygon of 150-600 vertices with up to 6 islands (some touching): a star with
    float or integer vertices, a densely digitised wave (many near-cocircular positions) or
    an integer-grid polyomino with its edges split in quarters (collinear runs, cocircular
    quadruples)."""
    rnd = random.Random(seed)
    kind = rnd.choice(["star", "istar", "grid", "wave"])
    while True:
        if kind == "star":
            outer = star_ring(rnd, rnd.randint(150, 600), radius=100.0, integer=False)
            islands, integer, size = rnd.randint(0, 6), False, 6.0
        elif kind == "istar":
            outer = star_ring(
                rnd, rnd.randint(150, 500), radius=rnd.choice((150, 300)), integer=True
            )
            islands, integer, size = rnd.randint(0, 6), True, 8.0
        elif kind == "wave":
            n = rnd.randint(150, 600)
            a = 2 * np.pi * np.arange(n) / n
            r = 100.0 * (1 + rnd.choice((0, 0.05)) * np.sin(rnd.randint(3, 20) * a))
            outer = [(float(x), float(y)) for x, y in zip(r * np.cos(a), r * np.sin(a))]
            islands, integer, size = rnd.randint(0, 6), False, 6.0
        else:
            cells = grid_ring(rnd, rnd.randint(40, 120), size=rnd.choice((12, 16)))
            if cells is None:
                continue
            corners = [(4 * x, 4 * y) for x, y in cells]
            outer = []
            for k, (x, y) in enumerate(corners):
                nx, ny = corners[(k + 1) % len(corners)]
                outer += [
                    ((4 - t) * x / 4 + t * nx / 4, (4 - t) * y / 4 + t * ny / 4) for t in range(4)
                ]
            islands, integer, size = rnd.randint(0, 6), True, 3.0
        if not is_valid([outer]):
            continue
        rings = add_islands(rnd, outer, islands, size, integer=integer)
        if rings is None:
            continue
        for _ in range(rnd.choice((0, 0, 2))):
            touching = touching_island(rnd, rings, rnd.randrange(len(rings)))
            if touching is not None:
                rings.append(touching)
        return with_random_orientation(rnd, rings)


@pytest.mark.parametrize(
    ("seed", "scale", "offset"),
    [
        (1000, 2.0**-380, 0.0),
        (1001, 2.0**-420, 0.0),
        (1025, 2.0**-420, 0.0),
        (1069, 2.0**500, 0.0),
        (1093, 2.0**500, 0.0),
        (1021, 2.0**500, 0.0),
        (1106, 1.0, 1e15),
    ],
)
def test_delaunay_far_from_unit_scale_matches_every_candidate(
    monkeypatch: pytest.MonkeyPatch, seed: int, scale: float, offset: float
) -> None:
    """Rule delaunay's float circles (search extents, the near-end apex's empty circle) hold
    far from unit scale: lengths of 2**-420 (whose cubes underflow), 2**500 (whose squares
    overflow) and points 1e15 from the origin (where the base's midpoint is off by 0.25)
    give the tree of testing every candidate exactly (these polygons got another one, or no
    tree at all)."""
    rings = [
        [(x * scale + offset, y * scale + offset) for x, y in r]
        for r in _random_delaunay_polygon(seed)
    ]
    found = _one_step(monkeypatch, rings, rule="delaunay")
    monkeypatch.setattr(
        one_polygon._Tree,
        "_delaunay_apex",
        lambda self, lo, hi: self._delaunay_small(lo, hi, np.arange(hi - 1, lo, -1)),
    )
    _same(_one_step(monkeypatch, rings, rule="delaunay"), found)


@pytest.mark.parametrize("rule", ["first", "elevation"])
def test_lockstep_subtrees_kept_where_others_are_built_one_step(
    monkeypatch: pytest.MonkeyPatch, rule: str
) -> None:
    """Invalid input as given (an island across another): the lock-step builder finds no
    tree for the sub-polygons where the crossing is, and only those are built one step at a
    time; the others keep their lock-step subtrees, and the fields are those of building the
    whole tree one step at a time."""
    rings = _wavy(12000, 100, 4)
    crossing = rings[5] + (rings[5][0] - rings[5][2]) * 0.3  # a copy moved across it
    rings = [*rings, crossing]
    rings = _lifted(rings) if rule == "elevation" else rings
    plain = _one_step(monkeypatch, rings, rule=rule, invalid="as_given")
    deferred, one_step = [], []
    with_subtrees, blocks = one_polygon._Tree._with_subtrees, one_polygon._Tree._one_step_blocks
    monkeypatch.setattr(
        one_polygon._Tree,
        "_with_subtrees",
        lambda self, rows, later, sub: (
            deferred.append(len(later)) or with_subtrees(self, rows, later, sub)
        ),
    )
    monkeypatch.setattr(
        one_polygon._Tree,
        "_one_step_blocks",
        lambda self, later: one_step.append(len(later)) or blocks(self, later),
    )
    _same(plain, triangulate(rings, rule=rule, invalid="as_given"))
    assert 0 < sum(one_step) < sum(deferred)


def test_islands_outside_the_shell_are_searched_from_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Islands outside the outer ring, as given: the first search finds no valid bridge (it
    tests every vertex of the sequence); the other islands outside are joined to their
    nearest occurrence without a search, as their searches would have done here."""
    far = [(130.0 + 5.0 * k, 0.0) for k in range(4)] + [(0.0, -135.0 - 5.0 * k) for k in range(4)]
    rings = [*_wavy(1500, 40, 6), *(_square(cx, cy) for cx, cy in far)]
    searches: list[int] = []
    search = bridges._Bridger.find_bridge

    def counted(self: bridges._Bridger, *args: object) -> object:
        searches.append(1)
        return search(self, *args)

    monkeypatch.setattr(bridges._Bridger, "find_bridge", counted)
    skipped = _outcomes(rings, RULES, "first")
    with_skips = len(searches)
    searches.clear()
    monkeypatch.setattr(
        bridges, "_outside_vertices", lambda x, y, rings: np.zeros(len(x), dtype=bool)
    )
    searched = _outcomes(rings, RULES, "first")
    assert with_skips < len(searches)
    _same_outcomes(skipped, searched)
