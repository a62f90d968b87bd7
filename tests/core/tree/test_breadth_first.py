"""The tree read off a triangulation level by level: each triangle once, at its fewest steps
from the root, in pre-order, and the same whether a level runs in numpy or in Python."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from bsp_triangulate.geometry.delaunay_mesh import edge_links
from bsp_triangulate.tree import breadth_first as module
from bsp_triangulate.tree.breadth_first import breadth_first


def grid_mesh(columns: int, rows: int, first: int = 0) -> np.ndarray:
    """A grid of squares, each cut into two counter-clockwise triangles, vertices from
    ``first`` on."""
    triangles = []
    for row in range(rows):
        for column in range(columns):
            a = first + row * (columns + 1) + column
            b, c, d = a + 1, a + columns + 2, a + columns + 1
            triangles += [[a, b, c], [a, c, d]] if (row + column) % 2 else [[a, b, d], [b, c, d]]
    return np.array(triangles, dtype=np.int64)


def long_and_wide() -> tuple[np.ndarray, np.ndarray]:
    """A wide grid (levels of many nodes) and a long strip (levels of few), apart: the links
    and one root slot per piece, on each piece's first edge from vertex 0 to 1."""
    wide = grid_mesh(40, 30)
    strip = grid_mesh(300, 1, first=41 * 31)
    triangles = np.vstack([wide, strip])
    across, repeated = edge_links(triangles, int(triangles.max()) + 1)
    assert not repeated.any()
    start, end = triangles[:, [1, 2, 0]].ravel(), triangles[:, [2, 0, 1]].ravel()
    roots = [int(np.flatnonzero((start == v) & (end == v + 1))[0]) for v in (0, 41 * 31)]
    return across, np.array(roots)


def fewest_steps(across: np.ndarray, root: int) -> dict[int, int]:
    """Per triangle reached from the root's, the fewest edges crossed to it."""
    steps = {root // 3: 0}
    queue = deque([root // 3])
    while queue:
        t = queue.popleft()
        for slot in range(3 * t, 3 * t + 3):
            other = int(across[slot])
            if other >= 0 and other // 3 not in steps:
                steps[other // 3] = steps[t] + 1
                queue.append(other // 3)
    return steps


def test_each_triangle_once_at_its_fewest_steps_in_pre_order() -> None:
    across, roots = long_and_wide()
    (slot, parent, depth, side), sizes = breadth_first(across, roots)
    t = slot // 3
    assert sorted(t.tolist()) == list(range(len(across) // 3))
    assert sizes.tolist() == [2 * 40 * 30, 2 * 300]
    steps = {**fewest_steps(across, roots[0]), **fewest_steps(across, roots[1])}
    assert depth.tolist() == [steps[triangle] for triangle in t.tolist()]
    child = np.flatnonzero(parent >= 0)
    # a child stands on a side of its parent's triangle, one level down
    assert (across[slot[child]] // 3 == t[parent[child]]).all()
    assert (depth[child] == depth[parent[child]] + 1).all()
    assert set(side[child].tolist()) == {1, 2} and (side[parent < 0] == 0).all()
    # pre-order: a node's left child right after it, its right child after the left subtree
    subtree = np.ones(len(slot), dtype=np.int64)
    for node in range(len(slot) - 1, 0, -1):
        if parent[node] >= 0:
            subtree[parent[node]] += subtree[node]
    for node in child.tolist():
        up = int(parent[node])
        lefts = [c for c in np.flatnonzero(parent == up).tolist() if side[c] == 1]
        expected = up + 1 + (subtree[lefts[0]] if side[node] == 2 and lefts else 0)
        assert node == expected
    assert np.flatnonzero(parent < 0).tolist() == [0, sizes[0]]


@pytest.mark.parametrize("small", [0, 10**9])
def test_numpy_and_python_levels_give_the_same_tree(monkeypatch, small: int) -> None:
    across, roots = long_and_wide()
    mixed = breadth_first(across, roots)
    monkeypatch.setattr(module, "_SMALL", small)
    alone = breadth_first(across, roots)
    for got, expected in zip((*alone[0], alone[1]), (*mixed[0], mixed[1])):
        np.testing.assert_array_equal(got, expected)


def test_no_root_gives_no_node() -> None:
    across, _ = long_and_wide()
    (slot, parent, depth, side), sizes = breadth_first(across, np.array([], dtype=np.int64))
    assert len(slot) == len(parent) == len(depth) == len(side) == len(sizes) == 0
