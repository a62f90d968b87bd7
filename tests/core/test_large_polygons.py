"""Large polygons: the chain boxes find every blocking edge and every point in a disc, a long
star ring is tiled, and the ring area sign (its float filter from the first vertex, its exact
sum in chunks) is exact.

The engine looks up the edges that may block a candidate triangle of a long sub-polygon by
descending boxes over runs of consecutive edges (``ChainBoxes``). The boxes only prune, so the
answer must equal that of testing every edge of the sub-polygon; this is checked on rings with
collinear runs, repeated points (bridges, touching islands), self-intersections, and the same
points far from the origin or scaled by a non-representable factor.
"""

from __future__ import annotations

import random
from fractions import Fraction

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.geometry import predicates
from bsp_triangulate.geometry.bridges import bridge_islands, remove_spikes, split_touching
from bsp_triangulate.geometry.predicates import ring_area_sign
from bsp_triangulate.geometry.rings import normalise_rings, prepare
from bsp_triangulate.geometry.spatial_index import ChainBoxes
from bsp_triangulate.rules import get_rule
from bsp_triangulate.tree.one_by_one import edge_blocks, facing_one
from bsp_triangulate.tree.one_polygon import _Tree

from .checks import check_triangulation
from .random_polygons import random_polygon

# (scale, offset) applied to integer coordinates
FRAMES = [(1.0, 0.0), (1e-9 / 3, 0.0), (0.1, 5e6), (1e15, 0.0)]


def _tree(rings: list) -> _Tree:
    clean, axes = normalise_rings(rings)
    prepared = prepare(clean, axes)
    ring_ids = split_touching(prepared.x, prepared.y, prepared.rings)
    sequence = bridge_islands(prepared.x, prepared.y, ring_ids, prepared.ring_numbers, relaxed=True)
    sequence = remove_spikes(prepared.x, prepared.y, sequence)
    return _Tree(prepared, sequence, prepared.vertices[:, 2], get_rule("first"), True)


def _blocked_by_any_edge(tree: _Tree, lo: int, hi: int, c: int) -> bool:
    xs, ys = tree.xs, tree.ys
    corners = (xs[hi], ys[hi], xs[lo], ys[lo], xs[c], ys[c])
    box = (min(corners[0::2]), min(corners[1::2]), max(corners[0::2]), max(corners[1::2]))
    return any(edge_blocks(corners, *box, xs, ys, e, tree.sign) for e in range(lo, hi))


def _polygons() -> list[tuple[str, list]]:
    out = []
    for seed in range(6):
        rnd = random.Random(f"large-{seed}")
        out.append((f"polyomino-{seed}", random_polygon(rnd, islands=2, grid=True, touching=2)))
        out.append((f"star-{seed}", random_polygon(rnd, islands=3, touching=2)))
        # random points in random order: a ring crossing itself everywhere
        points = [(float(rnd.randint(-6, 6)), float(rnd.randint(-6, 6))) for _ in range(40)]
        out.append((f"scribble-{seed}", [points]))
    return out


def _framed_tree(rings: list, scale: float, offset: float) -> _Tree:
    """The tree of ``rings`` scaled and moved; the test is skipped where they degenerate."""
    rings = [[(x * scale + offset, y * scale + offset) for x, y, *_ in r] for r in rings]
    try:
        tree = _tree(rings)
    except Exception:  # a scribble may not even normalise: nothing to compare
        pytest.skip("degenerate input")
    if tree.m < 4:
        pytest.skip("degenerate input")
    return tree


@pytest.mark.parametrize(("scale", "offset"), FRAMES)
@pytest.mark.parametrize(("name", "rings"), _polygons(), ids=[n for n, _ in _polygons()])
def test_chain_boxes_find_exactly_the_blocked_candidates(
    name: str, rings: list, scale: float, offset: float
) -> None:
    tree = _framed_tree(rings, scale, offset)
    tree.boxes = ChainBoxes(tree.sx, tree.sy, leaf=2)  # deep boxes even for small rings
    rnd = random.Random(name)
    m = tree.m
    blocked = 0
    for _ in range(1500):
        lo = rnd.randrange(0, m - 1)
        hi = rnd.randrange(lo + 2, m + 1)
        c = rnd.randrange(lo + 1, hi)
        if not facing_one(tree.xs, tree.ys, lo, hi, c):
            continue
        expected = _blocked_by_any_edge(tree, lo, hi, c)
        assert tree._blocked_boxes(lo, hi, c, tree_corners(tree, lo, hi, c), []) == expected, (
            lo,
            hi,
            c,
        )
        blocked += expected
    assert blocked > 0


@pytest.mark.parametrize(("scale", "offset"), FRAMES)
@pytest.mark.parametrize(("name", "rings"), _polygons(), ids=[n for n, _ in _polygons()])
def test_chain_boxes_near_a_disc_hold_every_point_in_it(
    name: str, rings: list, scale: float, offset: float
) -> None:
    # rule delaunay's near-end apex reads the positions p, lo < p < hi, in the disc from the
    # runs (start, end) found, as range(max(start, lo + 1), end): none may be missed
    tree = _framed_tree(rings, scale, offset)
    boxes = ChainBoxes(tree.sx, tree.sy, leaf=2)
    rnd = random.Random(name)
    xs, ys, m = tree.xs, tree.ys, tree.m
    met = 0
    for _ in range(500):
        lo = rnd.randrange(0, m - 1)
        hi = rnd.randrange(lo + 2, m + 1)
        p = rnd.randrange(0, m)
        ox, oy = xs[p] + rnd.uniform(-2, 2) * scale, ys[p] + rnd.uniform(-2, 2) * scale
        limit = (rnd.uniform(0, 3) * scale) ** 2
        runs = list(boxes.leaves_near(lo, hi, (ox, oy, limit)))
        covered = {q for start, end in runs for q in range(max(start, lo + 1), end)}
        for q in range(lo + 1, hi):
            dx, dy = xs[q] - ox, ys[q] - oy
            if dx * dx + dy * dy <= limit:
                assert q in covered, (lo, hi, q)
                met += 1
    assert met > 0


def tree_corners(tree: _Tree, lo: int, hi: int, c: int) -> tuple[float, ...]:
    xs, ys = tree.xs, tree.ys
    return (xs[hi], ys[hi], xs[lo], ys[lo], xs[c], ys[c])


def _star(vertices: int, seed: int = 1) -> np.ndarray:
    """The scale run's star: radius alternating between two random bands."""
    rng = np.random.default_rng(seed)
    angles = np.linspace(0.0, 2 * np.pi, vertices, endpoint=False)
    radii = np.where(np.arange(vertices) % 2 == 0, 1000.0, 600.0) + rng.uniform(0, 200, vertices)
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


def test_long_star_ring_is_tiled_exactly() -> None:
    ring = _star(4000)
    result = triangulate([ring])
    assert len(result) == len(ring) - 2
    check_triangulation([ring.tolist()], result)


def test_star_ring_of_fifty_thousand_vertices_keeps_its_area() -> None:
    ring = _star(50_000)
    result = triangulate([ring])
    assert len(result) == len(ring) - 2
    v = result.vertices[:, :2]
    a, b, c = (v[result.triangles[:, k]] for k in range(3))
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    x, y = ring[:, 0], ring[:, 1]
    area2 = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert (cross > 0).all()
    assert abs(cross.sum() - area2) <= 1e-9 * area2


def _exact_area_sign(x: np.ndarray, y: np.ndarray) -> int:
    n = len(x)
    total = sum(
        Fraction(x[i]) * Fraction(y[(i + 1) % n]) - Fraction(x[(i + 1) % n]) * Fraction(y[i])
        for i in range(n)
    )
    return (total > 0) - (total < 0)


@pytest.mark.parametrize("chunk", [3, 1 << 16])
def test_ring_area_sign_is_exact_near_zero_and_far_from_the_origin(
    chunk: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(predicates, "_EXACT_CHUNK", chunk)
    rng = np.random.default_rng(5)
    signs = set()
    for _ in range(600):
        n = int(rng.integers(3, 12))
        scale = rng.choice([1.0, 0.1, 3.0**-40, 1e-300, 1e300])
        x = rng.integers(-3, 4, n) * scale + rng.choice([0.0, 1e6, 1e17, -0.3])
        y = rng.integers(-3, 4, n) * rng.choice([1.0, 0.1, 3.0**-40]) + rng.choice([0.0, 7e6])
        with np.errstate(all="ignore"):
            got = ring_area_sign(x, y)
        assert got == _exact_area_sign(x, y)
        signs.add(got)
    assert signs == {-1, 0, 1}
