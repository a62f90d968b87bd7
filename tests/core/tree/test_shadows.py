"""Rule first on long sub-polygons skips candidates in the shadow of a vertex
(``tree/shadows.py``): every skipped candidate truly fails, and the trees are those of the
plain scan of every candidate."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.geometry.spatial_index import ChainBoxes
from bsp_triangulate.tree import one_polygon
from bsp_triangulate.tree import shadows as shadows_module
from bsp_triangulate.tree.shadows import Horizon, Shadows

from .rivers import river

FIELDS = ("vertices", "triangles", "parent", "depth", "side")


def _same(first: object, second: object) -> None:
    for field in FIELDS:
        assert np.array_equal(getattr(first, field), getattr(second, field)), field


@pytest.mark.parametrize(
    "rings",
    [river(600, 30, 1), river(800, 40, 2), river(500, 25, 3, grid=5.0)],
    ids=["river", "river 2", "river on a 5 m grid"],
)
def test_shadowed_scan_gives_the_trees_of_the_plain_scan(
    monkeypatch: pytest.MonkeyPatch, rings: list[np.ndarray]
) -> None:
    # the walk is what is tested: the apex seen from s_lo (which decides most nodes) left out
    monkeypatch.setattr(one_polygon, "visible_apex", lambda *args: None)
    used: list[int] = []
    shadowed = one_polygon._Tree._first_apex_shadowed
    monkeypatch.setattr(
        one_polygon._Tree,
        "_first_apex_shadowed",
        lambda self, *args: used.append(1) or shadowed(self, *args),
    )
    for invalid in ("fail", "as_given"):
        fast = triangulate(rings, invalid=invalid)
        with monkeypatch.context() as patch:
            patch.setattr(one_polygon, "_SHADOWED", math.inf)
            _same(fast, triangulate(rings, invalid=invalid))
    assert used


def _strictly_inside(a: tuple, b: tuple, c: tuple, p: tuple) -> bool:
    def orient(u: tuple, v: tuple, w: tuple) -> Fraction:
        return (v[0] - u[0]) * (w[1] - u[1]) - (v[1] - u[1]) * (w[0] - u[0])

    return orient(a, b, p) > 0 and orient(b, c, p) > 0 and orient(c, a, p) > 0


def _lattice_chain(
    seed: int, spread: int, count: int
) -> tuple[np.random.Generator, list[float], list[float], Shadows]:
    """A random chain of ``count`` lattice points within ``spread`` steps (vertices on the
    chord and on the shadows' edges), its base from the last point to the first, scaled and
    moved by the seed; its random generator, coordinates and empty staircase."""
    rng = np.random.default_rng(seed)
    scale = 1.0 if seed % 2 else 1e-3
    offset = 1e5 * (seed % 3)
    points = rng.integers(-spread, spread + 1, (count, 2)) * scale + offset
    points[0], points[-1] = (offset - 3 * scale, offset), (offset + 3 * scale, offset)
    x, y = points[:, 0].copy(), points[:, 1].copy()
    xs, ys = x.tolist(), y.tolist()
    return rng, xs, ys, Shadows(xs, ys, ChainBoxes(x, y, leaf=4), 0, count - 1)


def _corner_edge_inside(exact: list, lo: int, hi: int, c: int) -> bool:
    """The edge at a corner of the base (lo -> lo + 1, hi - 1 -> hi) meets the open interior
    of the triangle on the base with apex ``c`` (their shadows, ``Shadows._corner_shadows``)."""
    a, b = exact[hi], exact[lo]
    return _meets_inside(a, b, exact[c], exact[lo], exact[lo + 1]) or _meets_inside(
        a, b, exact[c], exact[hi - 1], exact[hi]
    )


@pytest.mark.parametrize("seed", range(6))
def test_skipped_candidates_fail_exactly(seed: int) -> None:
    """On random chains (lattice points: vertices on the chord and on the shadows' edges),
    each candidate not yielded lies on or right of the chord, or some vertex of the
    sub-polygon lies strictly inside its triangle, or an edge at a corner of the base or
    another edge of the sub-polygon (a ray of an edge met on the walk across the chord's
    line) meets its open interior (exact rational tests)."""
    rng, xs, ys, shadows = _lattice_chain(seed, 12, 700)
    lo, hi = shadows.lo, shadows.hi
    for position in [*rng.integers(1, hi, 5).tolist(), *range(lo + 1, lo + 17)]:
        shadows.add(int(position))
    top = hi - 1
    yielded = list(shadows.candidates(top))
    assert yielded == sorted(yielded, reverse=True)
    exact = [(Fraction(u), Fraction(v)) for u, v in zip(xs, ys)]
    a, b = exact[hi], exact[lo]
    skipped = set(range(lo + 1, top + 1)) - set(yielded)
    assert skipped
    shadowed = 0
    for c in skipped:
        facing = (b[0] - a[0]) * (exact[c][1] - a[1]) - (b[1] - a[1]) * (exact[c][0] - a[0])
        if facing > 0:
            assert (
                any(_strictly_inside(a, b, exact[c], exact[p]) for p in range(lo + 1, hi))
                or _corner_edge_inside(exact, lo, hi, c)
                or _edge_inside(exact, lo, hi, c)
            ), c
            shadowed += 1
    assert shadowed > 10


def _edge_inside(exact: list, lo: int, hi: int, c: int) -> bool:
    """Some edge (e, e + 1) of the sub-polygon [lo, hi] meets the open interior of the
    triangle on the base with apex ``c``."""
    a, b = exact[hi], exact[lo]
    return any(_meets_inside(a, b, exact[c], exact[e], exact[e + 1]) for e in range(lo, hi))


def _meets_inside(a: tuple, b: tuple, c: tuple, p: tuple, q: tuple) -> bool:
    """Some point of the segment p-q lies strictly inside the counter-clockwise triangle
    (a, b, c) (exact: the parameters where it is strictly left of every side)."""
    low, high = Fraction(0), Fraction(1)
    for u, v in ((a, b), (b, c), (c, a)):
        f0 = (v[0] - u[0]) * (p[1] - u[1]) - (v[1] - u[1]) * (p[0] - u[0])
        f1 = (v[0] - u[0]) * (q[1] - u[1]) - (v[1] - u[1]) * (q[0] - u[0])
        if f0 <= 0 and f1 <= 0:
            return False
        if f0 != f1:
            root = f0 / (f0 - f1)
            low, high = (max(low, root), high) if f1 > f0 else (low, min(high, root))
    return low < high


@pytest.mark.parametrize("seed", range(6))
def test_candidates_skipped_behind_an_edge_fail_exactly(seed: int) -> None:
    """Edges cast shadows along their length (``Shadows.add_edge``): each candidate not
    yielded lies on or right of the chord, or has a vertex, or a point of an edge that cast
    a shadow or of an edge at a corner of the base, strictly inside its triangle (exact
    rational tests)."""
    rng, xs, ys, shadows = _lattice_chain(seed, 40, 400)
    lo, hi = shadows.lo, shadows.hi
    edges = rng.integers(0, hi, 12).tolist()
    for edge in edges:
        shadows.add_edge(int(edge))
    top = hi - 1
    yielded = set(shadows.candidates(top))
    exact = [(Fraction(u), Fraction(v)) for u, v in zip(xs, ys)]
    a, b = exact[hi], exact[lo]
    shadowed = 0
    for c in set(range(lo + 1, top + 1)) - yielded:
        facing = (b[0] - a[0]) * (exact[c][1] - a[1]) - (b[1] - a[1]) * (exact[c][0] - a[0])
        if facing > 0:
            assert (
                any(_strictly_inside(a, b, exact[c], exact[p]) for p in range(lo + 1, hi))
                or any(_meets_inside(a, b, exact[c], exact[e], exact[e + 1]) for e in edges)
                or _corner_edge_inside(exact, lo, hi, c)
                or _edge_inside(exact, lo, hi, c)
            ), c
            shadowed += 1
    assert shadowed > 10


@pytest.mark.parametrize("reflex", ["none", "at B", "at A", "both"])
def test_every_apex_the_near_shadows_leave_lies_in_their_region_box(reflex: str) -> None:
    """``Shadows.region_box``: every candidate strictly left of the chord that no vertex of
    the sub-polygon lies strictly inside and no edge meets inside (a superset of the correct
    apexes) lies in the box, on random lattice chains (exact rational tests). A convex base
    corner's edge closes its end of the staircase; at a reflex corner (its neighbour right
    of the chord's line), the edge by which the chain comes back across the line beyond it."""
    boxes = inside = outside = 0
    for seed in range(60):
        rng, xs, ys, _ = _lattice_chain(seed, 6 + seed % 5, 14 + seed % 12)
        step = 1.0 if seed % 2 else 1e-3
        count = len(xs)
        # left of the chord is the side y < 0 of the base's line; beyond B (position 0),
        # x below B's, beyond A (the last position) above A's
        for corner, near, far, away in ((0, 1, 2, -1.0), (count - 1, count - 2, count - 3, 1.0)):
            if reflex in ("both", "at B" if corner == 0 else "at A"):
                xs[near] = xs[corner] + away * step * int(rng.integers(1, 4))
                ys[near] = ys[corner] + step * int(rng.integers(1, 4))
                xs[far] = xs[corner] + away * step * int(rng.integers(1, 4))
                ys[far] = ys[corner] - step * int(rng.integers(1, 4))
            else:
                ys[near] = ys[corner] - step * int(rng.integers(1, 6))
        x, y = np.array(xs), np.array(ys)
        shadows = Shadows(xs, ys, ChainBoxes(x, y, leaf=4), 0, count - 1)
        lo, hi = shadows.lo, shadows.hi
        near = np.r_[lo + 1 : lo + 4, hi - 3 : hi, rng.integers(lo + 1, hi, 2)]
        shadows.add_many(x, y, near)
        area = shadows.region_box()
        if area is None:
            continue
        boxes += 1
        xmin, ymin, xmax, ymax = area
        exact = [(Fraction(u), Fraction(v)) for u, v in zip(xs, ys)]
        a, b = exact[hi], exact[lo]
        for c in range(lo + 1, hi):
            facing = (b[0] - a[0]) * (exact[c][1] - a[1]) - (b[1] - a[1]) * (exact[c][0] - a[0])
            if facing <= 0:
                continue
            in_box = xmin <= xs[c] <= xmax and ymin <= ys[c] <= ymax
            if in_box:
                inside += 1
                continue
            outside += 1
            assert (
                any(_strictly_inside(a, b, exact[c], exact[p]) for p in range(lo + 1, hi))
                or _corner_edge_inside(exact, lo, hi, c)
                or _edge_inside(exact, lo, hi, c)
            ), (seed, c)
    assert boxes >= 2
    assert inside >= 10
    assert outside >= 2


@pytest.mark.parametrize("at_b", [True, False], ids=["at B", "at A"])
def test_the_edge_crossing_back_beyond_a_reflex_corner_blocks_what_lies_past_its_reach(
    at_b: bool,
) -> None:
    """``Shadows._crossing_back``: where the chain leaves a base corner right of the chord's
    line and comes back across it beyond the corner, every point strictly left of the chord
    at a larger angle at that corner than the returned one, and farther from it than the
    returned reach, has that edge across the open triangle (exact rational tests on random
    lattice chains and lattice points)."""
    checked = 0
    for seed in range(40):
        rng, xs, ys, _ = _lattice_chain(seed, 8, 40)
        step = 1.0 if seed % 2 else 1e-3
        count = len(xs)
        corner, near = (0, 1) if at_b else (count - 1, count - 2)
        away = -1.0 if at_b else 1.0  # beyond B: x below B's; beyond A: above A's
        run = int(rng.integers(1, 4))  # positions right of the line before the crossing
        for k in range(run + 1):
            position = near + (k if at_b else -k)
            xs[position] = xs[corner] + away * step * int(rng.integers(1, 5))
            side = 1 if k < run else -1  # right of the line (y > 0), then back left
            ys[position] = ys[corner] + side * step * int(rng.integers(1, 5))
        x, y = np.array(xs), np.array(ys)
        shadows = Shadows(xs, ys, ChainBoxes(x, y, leaf=4), 0, count - 1)
        crossing = shadows._crossing_back(at_b)
        if crossing is None:
            continue
        angle, reach = crossing
        exact = [(Fraction(u), Fraction(v)) for u, v in zip(xs, ys)]
        a, b = exact[count - 1], exact[0]
        cx, cy = xs[corner], ys[corner]
        edges = range(0, run + 1) if at_b else range(count - run - 2, count - 1)
        for u, v in rng.integers(-40, 41, (300, 2)).tolist():
            px, py = xs[corner] + u * step / 2, ys[corner] + v * step / 2 - 1e-3 * step
            angles = shadows.angles(px, py)
            if not 0 < angles[0] < math.pi or not 0 < angles[1] < math.pi:
                continue
            if angles[1 if at_b else 0] <= angle or math.hypot(px - cx, py - cy) <= reach:
                continue
            c = (Fraction(px), Fraction(py))
            assert any(_meets_inside(a, b, c, exact[e], exact[e + 1]) for e in edges), (seed, u, v)
            checked += 1
    assert checked > 200


def test_rule_elevation_bounds_its_apexes_in_a_box_with_the_same_trees(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Long bases of rule elevation drop the candidates outside the box of the near
    shadows' region (``Shadows.region_box``) before their tests; the trees are those of
    testing every candidate."""
    boxes: list[bool] = []
    region_box = Shadows.region_box
    monkeypatch.setattr(Shadows, "region_box", lambda self: boxes.append(1) or region_box(self))
    monkeypatch.setattr(one_polygon, "_REGION_SPAN", 128)
    rings = river(900, 60, 6)
    rings = [np.column_stack([r, np.cos(r[:, 0] / 53) * 25 + r[:, 1] / 7]) for r in rings]
    fast = triangulate(rings, rule="elevation")
    with monkeypatch.context() as patch:
        _ignore_shadows(patch)
        patch.setattr(Shadows, "region_box", lambda self: None)
        patch.setattr(one_polygon, "_SCALAR_CANDIDATES", math.inf)
        _same(fast, triangulate(rings, rule="elevation"))
    assert len(boxes) > 20


def _ignore_shadows(patch: pytest.MonkeyPatch) -> None:
    """No candidate is found in a shadow: each gets the exact tests."""
    patch.setattr(Shadows, "shadowed", lambda self, alpha, beta: False)
    patch.setattr(Shadows, "shadowed_many", lambda self, sx, sy, p: np.zeros(len(p), dtype=bool))


def test_rule_elevation_skips_shadowed_candidates_with_the_same_trees(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Rule elevation tests candidates closest in z first; those in a shadow are skipped
    without the exact test, and the trees are those of testing every one."""
    used: list[int] = []
    shadows = one_polygon._Tree._near_shadows
    monkeypatch.setattr(
        one_polygon._Tree,
        "_near_shadows",
        lambda self, *args: used.append(1) or shadows(self, *args),
    )
    rings = river(700, 30, 4)
    rings = [np.column_stack([r, np.sin(r[:, 0] / 97) * 40 + r[:, 1] / 50]) for r in rings]
    for invalid in ("fail", "as_given"):
        fast = triangulate(rings, rule="elevation", invalid=invalid)
        with monkeypatch.context() as patch:
            _ignore_shadows(patch)
            _same(fast, triangulate(rings, rule="elevation", invalid=invalid))
    assert used


@pytest.mark.parametrize("seed", range(6))
def test_shadows_cast_together_are_those_cast_one_by_one(seed: int) -> None:
    """``Shadows.add_many`` (rule elevation's shadows of the positions next to the base)
    shadows exactly the candidates that adding each vertex with ``add`` shadows, including
    positions outside the sub-polygon and on the chord (lattice points), which cast none."""
    rng, xs, ys, together = _lattice_chain(seed, 12, 300)
    _, _, _, one_by_one = _lattice_chain(seed, 12, 300)
    edge = int(rng.integers(1, 250))
    for shadows in (together, one_by_one):
        shadows.add_edge(edge)
    positions = np.r_[-3:70, 230:305]
    together.add_many(np.array(xs), np.array(ys), positions)
    for position in positions.tolist():
        if 0 <= position < len(xs):
            one_by_one.add(position)
    assert together.alphas
    for c in range(1, len(xs) - 1):
        angles = together.angles(xs[c], ys[c])
        assert together.shadowed(*angles) == one_by_one.shadowed(*angles), c
    positions = np.arange(1, len(xs) - 1)
    assert np.array_equal(
        together.shadowed_many(np.array(xs), np.array(ys), positions),
        one_by_one.shadowed_many(np.array(xs), np.array(ys), positions),
    )


def test_rule_elevation_casts_the_shadows_next_to_the_base_with_the_same_trees(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Rule elevation's shadows of the positions next to the base (and its bands filtered
    whole once a base has tested 16 candidates) leave the trees of testing every candidate
    exactly, on a river whose bases reject most of their closest candidates."""
    used: list[int] = []
    near = one_polygon._Tree._near_shadows
    monkeypatch.setattr(
        one_polygon._Tree, "_near_shadows", lambda self, *args: used.append(1) or near(self, *args)
    )
    rings = river(900, 60, 5)
    rings = [np.column_stack([r, np.cos(r[:, 0] / 61) * 25 + r[:, 1] / 9]) for r in rings]
    fast = triangulate(rings, rule="elevation")
    with monkeypatch.context() as patch:
        _ignore_shadows(patch)
        patch.setattr(one_polygon, "_SCALAR_CANDIDATES", math.inf)
        _same(fast, triangulate(rings, rule="elevation"))
    assert len(used) > 20


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e4])
def test_corner_edges_rule_out_the_line_beyond_the_base(scale: float) -> None:
    """Chains zigzagging across the chord's line beyond both ends of the base (boxes that
    straddle the line there, whose points near it no vertex shadows): the edges at the base's
    corners rule them out, and each candidate skipped truly fails (exact rational tests)."""
    rng = np.random.default_rng(int(scale * 7) % 13)
    beyond_b = [(x, -1.0 if k % 2 else 1.0) for k, x in enumerate(range(-60, -4))]
    beyond_a = [(x, -1.0 if k % 2 else 1.0) for k, x in enumerate(range(5, 61))]
    middle = [tuple(p) for p in rng.integers(-20, 21, (60, 2)).astype(float)]
    chain = [(-3.0, 0.0), (-4.0, -2.0), *beyond_b, *middle, *beyond_a, (4.0, -2.0), (3.0, 0.0)]
    points = np.array(chain) * scale + 1e5
    x, y = points[:, 0].copy(), points[:, 1].copy()
    xs, ys = x.tolist(), y.tolist()
    lo, hi = 0, len(chain) - 1
    shadows = Shadows(xs, ys, ChainBoxes(x, y, leaf=4), lo, hi)
    assert shadows.corner_alpha < math.inf and shadows.corner_beta < math.inf
    yielded = set(shadows.candidates(hi - 1))
    exact = [(Fraction(u), Fraction(v)) for u, v in zip(xs, ys)]
    a, b = exact[hi], exact[lo]
    beyond = {chain.index(p) for p in beyond_a + beyond_b if p[1] < 0}
    assert beyond.isdisjoint(yielded)
    for c in set(range(lo + 1, hi)) - yielded:
        facing = (b[0] - a[0]) * (exact[c][1] - a[1]) - (b[1] - a[1]) * (exact[c][0] - a[0])
        if facing > 0:
            assert any(
                _strictly_inside(a, b, exact[c], exact[p]) for p in range(lo + 1, hi)
            ) or _corner_edge_inside(exact, lo, hi, c), c


def _skipped_by_one_edge(
    chain: list, edge_start: tuple, far: list, scale: float
) -> tuple[Shadows, int]:
    """Shadows on the base from the chain's last point to its first (scaled, far from the
    origin) with those of the edge from ``edge_start`` cast; asserts that no point of
    ``far`` is yielded and that every candidate skipped truly fails (exact rational tests).
    Returns the shadows and how many skipped candidates that edge alone rules out."""
    points = np.array(chain) * scale - 100.0
    x, y = points[:, 0].copy(), points[:, 1].copy()
    xs, ys = x.tolist(), y.tolist()
    lo, hi = 0, len(chain) - 1
    shadows = Shadows(xs, ys, ChainBoxes(x, y, leaf=4), lo, hi)
    edge = chain.index(edge_start)
    shadows.add_edge(edge)
    yielded = set(shadows.candidates(hi - 1))
    exact = [(Fraction(u), Fraction(v)) for u, v in zip(xs, ys)]
    a, b = exact[hi], exact[lo]
    assert yielded.isdisjoint(chain.index(p) for p in far)
    by_the_edge_alone = 0
    for c in set(range(lo + 1, hi)) - yielded:
        facing = (b[0] - a[0]) * (exact[c][1] - a[1]) - (b[1] - a[1]) * (exact[c][0] - a[0])
        if facing > 0:
            inside = any(_strictly_inside(a, b, exact[c], exact[p]) for p in range(lo + 1, hi))
            meets = _meets_inside(a, b, exact[c], exact[edge], exact[edge + 1])
            assert inside or meets, c
            by_the_edge_alone += not inside
    return shadows, by_the_edge_alone


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e4])
def test_an_edge_across_the_line_beyond_the_base_rules_out_the_slivers_past_it(
    scale: float,
) -> None:
    """Candidates along the chord's line far beyond A (slivers: no vertex's shadow covers
    them, and the corner edges turn away) past an edge that crosses the line there: that
    edge crosses their side from A, and they are skipped; every candidate skipped truly fails
    (exact rational tests)."""
    slivers = [(float(x), -1.0) for x in range(20, 61)]
    chain = [(-3.0, 0.0), (-4.0, 3.0), (-2.0, -9.0), (10.0, 2.0), (10.0, -2.0), *slivers]
    chain += [(4.0, 2.0), (3.0, 0.0)]
    shadows, by_the_edge_alone = _skipped_by_one_edge(chain, (10.0, 2.0), slivers, scale)
    assert shadows.corner_alpha == math.inf and shadows.corner_beta == math.inf
    assert shadows.rays_a
    assert by_the_edge_alone > 20


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e4])
def test_an_edge_beyond_the_base_rules_out_the_candidates_behind_it(scale: float) -> None:
    """Candidates far beyond A behind an edge that lies wholly left of the chord (it crosses
    neither the chord's line nor their triangles' corners, so no vertex's shadow covers
    them): seen from A, the edge spans their angles nearer than they are, so it crosses
    their side from A, and they are skipped (``Horizon``); every candidate skipped truly
    fails (exact rational tests)."""
    behind = [(float(x), -1.5) for x in range(24, 61)]
    chain = [(-3.0, 0.0), (-4.0, 3.0), (-2.0, -9.0), (12.0, -0.2), (12.0, -3.0), *behind]
    chain += [(4.0, 2.0), (3.0, 0.0)]
    _, by_the_edge_alone = _skipped_by_one_edge(chain, (12.0, -0.2), behind, scale)
    assert by_the_edge_alone > 20


def _horizon_reach2(occluders: list, angle: float) -> float:
    return min((r for low, high, r in occluders if low < angle < high), default=math.inf)


@pytest.mark.parametrize("seed", range(4))
def test_horizon_keeps_the_least_reach_per_angle(seed: int) -> None:
    """``Horizon``: the least squared reach of the occluders over each angle, and its largest
    value over a range, equal those of every occluder looked at (cuts included)."""
    rng = np.random.default_rng(seed)
    horizon = Horizon()
    occluders = []
    for _ in range(60):
        low = float(rng.choice([rng.uniform(0, 3), rng.integers(0, 30) / 10]))
        high = low + float(rng.choice([rng.uniform(0, 1), rng.integers(1, 10) / 10]))
        reach2 = float(rng.uniform(1, 100))
        horizon.add(low, high, reach2)
        occluders.append((low, high, reach2))
    cuts = sorted({v for low, high, _ in occluders for v in (low, high)})
    probes = cuts + [(u + v) / 2 for u, v in zip(cuts, cuts[1:])] + rng.uniform(-1, 5, 50).tolist()
    for angle in probes:
        assert horizon.reach2(angle) == _horizon_reach2(occluders, angle)
    for _ in range(300):
        low, high = sorted(rng.choice(probes, 2).tolist())
        inside = [p for p in probes if low <= p <= high]
        expected = max(_horizon_reach2(occluders, p) for p in inside)
        # a range of more cuts than a query walks rules nothing out (inf), never more
        assert horizon.reach2_over(low, high) in (expected, math.inf)
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(shadows_module, "_WALK", 1 << 20)
            assert horizon.reach2_over(low, high) == expected


@pytest.mark.parametrize("exponent", [0, 520, 1000])
def test_a_canal_far_beyond_float_squares_gives_the_same_tree(exponent: int) -> None:
    """A long thin canal scaled by a power of two up to 2**1000: the rays' squared distances
    overflow to inf (nothing ruled out), never raise, and every tree equals the unscaled
    one's (a power-of-two scale changes no sign)."""
    n = 400
    x = np.linspace(0.0, 1.0, n)
    lower = np.column_stack([x, np.full(n, -0.001)])
    upper = np.column_stack([x[::-1], np.full(n, 0.001)])
    ring = np.concatenate([lower, upper])
    expected = triangulate([ring])
    got = triangulate([ring * 2.0**exponent])
    for name in ("triangles", "parent", "depth", "side"):
        assert np.array_equal(getattr(got, name), getattr(expected, name)), name


def _hair_left_of_the_chord(
    a: tuple[float, float], b: tuple[float, float], beyond: float, count: int, baits: int
) -> tuple[np.ndarray, int]:
    """A valid polygon (xyz) whose root base runs from vertex 0 (A) to vertex 1 (B), with its
    last vertex C = A + ``beyond`` (A - B) on the chord's line beyond A in decimal, a hair
    left of it in binary: C's computed angle at B wraps past 0 to about 2 pi. Between B and C
    a long comb (``count`` vertices) with a deep tooth in the middle, its vertices high but
    for ``baits`` low ones near the tooth: rule elevation's closest candidates, each holding
    the tooth. C is correct and the closest in z of the correct ones. Returns the ring and C's
    index."""
    (ax, ay), (bx, by) = a, b
    length = math.hypot(ax - bx, ay - by)
    ux, uy = (ax - bx) / length, (ay - by) / length
    nx, ny = uy, -ux

    def at(u: float, n: float) -> tuple[float, float]:
        return (ax + u * ux + n * nx, ay + u * uy + n * ny)

    cx, cy = ax + beyond * (ax - bx), ay + beyond * (ay - by)
    u_b, u_c, far = -length, math.hypot(cx - ax, cy - ay), 0.5 * length
    chain = [at(u_b - 0.02 * length, 0.02 * length), at(u_b - 0.05 * length, 0.1 * length)]
    chain.append(at(u_b - 0.05 * length, far))
    zs = [5.0, 5.0, 5.0]
    middle, tooth, placed = 0.5 * u_b, False, 0
    for k, u in enumerate(np.linspace(u_b - 0.05 * length, u_c + 0.05 * length, count)[1:-1]):
        if abs(u - middle) < 0.01 * length and not tooth:
            chain += [
                at(middle - 0.005 * length, far),
                at(middle, 0.1 * length),
                at(middle + 0.005 * length, far),
            ]
            zs += [7.0, 7.0, 7.0]
            tooth = True
            continue
        chain.append(at(float(u), far * (1 + 0.01 * math.sin(k))))
        bait = 0.02 * length < abs(u - middle) < 0.5 * length and placed < baits
        zs.append(0.5 if bait else 5.0 + 0.001 * k)
        placed += bait
    chain += [at(u_c + 0.05 * length, far), at(u_c + 0.02 * length, 0.05 * length)]
    zs += [6.0, 6.0]
    ring = np.array([a, b, *chain, (cx, cy)])
    z = 1e-3 * np.array([0.0, 0.0, *zs, 1.0])
    return np.column_stack([ring, z]), len(ring) - 1


@pytest.mark.parametrize(
    ("b", "beyond", "baits"),
    [
        ((-0.555, -0.439), 0.36, 4),  # wraps in math.atan2: the scalar shadowed test
        ((-1.253, -0.367), 1.72, 24),  # wraps in numpy's only: shadowed_many on a band
    ],
)
def test_rule_elevation_takes_its_apex_a_hair_left_of_the_chord(
    b: tuple[float, float], beyond: float, baits: int
) -> None:
    """Found by a review: an apex a hair left of the chord's line beyond a base end has an
    angle that computes past 0 (about 2 pi); the staircase called such a point shadowed,
    and rule elevation took another apex than its choice. A point not surely left of the
    chord is never shadowed now."""
    ring, apex = _hair_left_of_the_chord((0.0, 0.0), b, beyond, 340, baits)
    for invalid in ("fail", "as_given"):
        root = triangulate([ring], rule="elevation", invalid=invalid).triangles[0]
        assert sorted(root.tolist()) == [0, 1, apex]


def test_rule_first_takes_its_apex_a_hair_left_of_the_chord() -> None:
    """The same fault under rule first: the chain boxes' walk from the last candidate back
    skipped the first correct candidate, a hair left of the chord's line beyond A, as
    shadowed, after 20 candidates right of the chord (a loop of the boundary below the
    line), and took the one before it."""
    a, b = (0.0, 0.0), (-0.555, -0.439)
    length = math.hypot(*b)
    ux, uy = -b[0] / length, -b[1] / length
    nx, ny = uy, -ux

    def at(u: float, n: float) -> tuple[float, float]:
        return (u * ux + n * nx, u * uy + n * ny)

    c = (-b[0] * 0.36, -b[1] * 0.36)
    u_b, u_c, far = -length, math.hypot(*c), 0.5 * length
    chain = [at(u_b - 0.02 * length, 0.02 * length), at(u_b - 0.05 * length, 0.1 * length)]
    chain += [at(float(u), far) for u in np.linspace(u_b - 0.05 * length, u_c + 0.05 * length, 300)]
    chain.append(at(u_c + 0.02 * length, 0.05 * length))
    loop = [at(u_c + 0.01 * length, -0.05 * length)]
    loop += [at(float(u), -0.2 * length) for u in np.linspace(u_c, 0.2 * u_c, 20)]
    loop.append(at(0.05 * u_c, -0.02 * length))
    ring = np.array([a, b, *chain, c, *loop])
    apex = 2 + len(chain)
    for invalid in ("fail", "as_given"):
        root = triangulate([ring], rule="first", invalid=invalid).triangles[0]
        assert sorted(root.tolist()) == [0, 1, apex]


def test_shadowed_is_false_off_the_left_of_the_chord() -> None:
    """Angles within the margin of 0 or pi, or past them, are never in a shadow, whatever
    the staircase (scalar and numpy tests alike)."""
    xs, ys = [0.0, 1.0, 0.5, 2.0, 0.0], [0.0, 0.0, 1.0, 0.0, 0.0]
    boxes = ChainBoxes(np.array(xs), np.array(ys))
    shadows = Shadows(xs, ys, boxes, 0, 3)
    shadows._add(0.1, 0.1)
    for alpha, beta in [(2.0, 2 * math.pi - 1e-17), (2.0, 0.0), (math.pi, 0.5), (-1e-12, 0.5)]:
        assert not shadows.shadowed(alpha, beta)
    assert shadows.shadowed(1.0, 1.0)
