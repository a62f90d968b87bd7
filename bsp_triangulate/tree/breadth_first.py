"""The BSP tree read off a triangulation level by level (docs/algorithm.md, section 5b).

Each root's tree is grown breadth-first over the triangles: a node's left child is the
triangle across its new side at V1, its right child the one across its new side at V2, and a
triangle that two nodes of one level reach goes to the first of them in the level's order
(their parents' order, left before right). The rows come out in pre-order. A level is a
handful of numpy passes over all roots at once; levels of few nodes (a long narrow polygon)
run in plain Python, with the same result.
"""

from __future__ import annotations

import numpy as np

# a level smaller than this runs in plain Python (per-call numpy overhead dominates there)
_SMALL = 48
# per slot k of a triangle: the slot of its next edge and of the one after
_NEXT = np.array([1, 2, 0], dtype=np.int64)
_AFTER_NEXT = np.array([2, 0, 1], dtype=np.int64)
_NEXT_LIST = (1, 2, 0)
_AFTER_NEXT_LIST = (2, 0, 1)

Columns = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def breadth_first(across: np.ndarray, roots: np.ndarray) -> tuple[Columns, np.ndarray]:
    """The tree of each root slot in turn (``across``: per slot ``3 t + k``, the directed edge
    from corner ``k + 1`` to ``k + 2`` of triangle ``t``, the slot of the same edge the other
    way round, or -1 where it is not crossed): per node in pre-order, root by root, the slot
    of its base (the chord with the rest on its left, opposite its apex), its parent (numbered
    among all nodes), depth and side (0 root, 1 left, 2 right); and per root the number of
    triangles its tree holds. Roots whose triangles are connected share them out level by
    level, first come first served."""
    across = np.asarray(across, dtype=np.int64)
    levels = _levels(across, np.asarray(roots, dtype=np.int64))
    if not levels:
        none = np.zeros(0, dtype=np.int64)
        return (none, none, none, none), none
    slot = np.concatenate([level[0] for level in levels])
    parent = np.concatenate([level[1] for level in levels])
    side = np.concatenate([level[2] for level in levels])
    bounds = np.cumsum([0] + [len(level[0]) for level in levels])
    depth = np.repeat(np.arange(len(levels), dtype=np.int64), np.diff(bounds))
    position, sizes = _pre_order(parent, side, bounds)
    order = np.empty(len(slot), dtype=np.int64)
    order[position] = np.arange(len(slot))
    up = parent[order]
    parents = np.where(up >= 0, position[np.maximum(up, 0)], -1)
    return (slot[order], parents, depth[order], side[order]), sizes


def _levels(across: np.ndarray, roots: np.ndarray) -> list[Columns]:
    """Per level in breadth-first order: the nodes' base slots, parents (breadth-first
    numbers), sides and whether V1 is at the base's start."""
    used = np.zeros(len(across) // 3, dtype=bool)
    owner = np.empty(len(used), dtype=np.int64)  # scratch: which node took a triangle
    slot = roots
    parent = np.full(len(roots), -1, dtype=np.int64)
    side = np.zeros(len(roots), dtype=np.int64)
    at_start = np.ones(len(roots), dtype=bool)
    levels = []
    taken = 0
    while len(slot):
        step = _python_step if len(slot) < _SMALL else _numpy_step
        level, children = step(across, used, owner, taken, slot, parent, side, at_start)
        levels.append(level)
        taken += len(level[0])
        slot, parent, side, at_start = children
    return levels


def _numpy_step(
    across: np.ndarray,
    used: np.ndarray,
    owner: np.ndarray,
    taken: int,
    slot: np.ndarray,
    parent: np.ndarray,
    side: np.ndarray,
    at_start: np.ndarray,
) -> tuple[Columns, Columns]:
    """One level: the nodes that take their triangle (the first to reach a free one), and
    their children in order."""
    t = slot // 3
    keep = np.flatnonzero(~used[t])
    t_keep = t[keep]
    claimed = np.arange(len(keep))
    owner[t_keep] = claimed
    lost = owner[t_keep] != claimed
    if lost.any():
        # a triangle reached twice goes to the first: sort out only those reached twice
        contested = t_keep[lost]
        used[contested] = True
        involved = np.flatnonzero(used[t_keep])
        used[contested] = False
        _, first = np.unique(t_keep[involved], return_index=True)
        wins = np.ones(len(keep), dtype=bool)
        wins[involved] = False
        wins[involved[first]] = True
        keep = keep[wins]
    slot, parent, side, at_start, t = slot[keep], parent[keep], side[keep], at_start[keep], t[keep]
    used[t] = True
    k = slot - 3 * t
    upper = across[3 * t + _AFTER_NEXT[k]]  # across the side from the apex to the base's start
    lower = across[3 * t + _NEXT[k]]  # across the side from the base's end to the apex
    # the left child stands on V1's new side, the right on V2's; V1 stays at the start of
    # the child's base across the upper side, at its end across the lower
    pairs = np.empty((len(slot), 2), dtype=np.int64)
    pairs[:, 0] = np.where(at_start, upper, lower)
    pairs[:, 1] = np.where(at_start, lower, upper)
    pair_starts = np.empty((len(slot), 2), dtype=bool)
    pair_starts[:, 0] = at_start
    pair_starts[:, 1] = ~at_start
    children = pairs.ravel()
    crossed = children >= 0
    numbers = np.repeat(np.arange(taken, taken + len(slot), dtype=np.int64), 2)
    sides = np.tile(np.array([1, 2], dtype=np.int64), len(slot))
    level = (slot, parent, side, at_start)
    return level, (
        children[crossed],
        numbers[crossed],
        sides[crossed],
        pair_starts.ravel()[crossed],
    )


def _python_step(
    across: np.ndarray,
    used: np.ndarray,
    owner: np.ndarray,
    taken: int,
    slot: np.ndarray,
    parent: np.ndarray,
    side: np.ndarray,
    at_start: np.ndarray,
) -> tuple[Columns, Columns]:
    """:func:`_numpy_step` for a level of few nodes."""
    out: tuple[list, list, list, list] = ([], [], [], [])
    nxt: tuple[list, list, list, list] = ([], [], [], [])
    number = taken
    for s, p, d, start in zip(slot.tolist(), parent.tolist(), side.tolist(), at_start.tolist()):
        t = s // 3
        if used[t]:
            continue
        used[t] = True
        for column, value in zip(out, (s, p, d, start)):
            column.append(value)
        k = s - 3 * t
        upper = int(across[3 * t + _AFTER_NEXT_LIST[k]])
        lower = int(across[3 * t + _NEXT_LIST[k]])
        left, right = (upper, lower) if start else (lower, upper)
        if left >= 0:
            for column, value in zip(nxt, (left, number, 1, start)):
                column.append(value)
        if right >= 0:
            for column, value in zip(nxt, (right, number, 2, not start)):
                column.append(value)
        number += 1
    return _arrays(out), _arrays(nxt)


def _arrays(columns: tuple[list, list, list, list]) -> Columns:
    slot, parent, side, at_start = columns
    return (
        np.array(slot, dtype=np.int64),
        np.array(parent, dtype=np.int64),
        np.array(side, dtype=np.int64),
        np.array(at_start, dtype=bool),
    )


def _pre_order(
    parent: np.ndarray, side: np.ndarray, bounds: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per node (breadth-first numbers, levels between ``bounds``) its place in the pre-order
    of all trees, root after root, and per root its tree's size."""
    n = len(parent)
    size = np.ones(n, dtype=np.int64)
    left_size = np.zeros(n, dtype=np.int64)
    for lo, hi in reversed(list(zip(bounds[1:-1].tolist(), bounds[2:].tolist()))):
        if hi - lo < _SMALL:
            for node in range(lo, hi):
                up = int(parent[node])
                size[up] += size[node]
                if side[node] == 1:
                    left_size[up] = size[node]
            continue
        up, below, left = parent[lo:hi], size[lo:hi], side[lo:hi] == 1
        # each node has at most one left and one right child: no index repeats per line
        size[up[left]] += below[left]
        size[up[~left]] += below[~left]
        left_size[up[left]] = below[left]
    roots = int(bounds[1])
    sizes = size[:roots].copy()
    position = np.empty(n, dtype=np.int64)
    position[:roots] = np.cumsum(sizes) - sizes
    for lo, hi in zip(bounds[1:-1].tolist(), bounds[2:].tolist()):
        if hi - lo < _SMALL:
            for node in range(lo, hi):
                up = int(parent[node])
                shift = int(left_size[up]) if side[node] == 2 else 0
                position[node] = position[up] + 1 + shift
            continue
        up = parent[lo:hi]
        position[lo:hi] = position[up] + 1 + np.where(side[lo:hi] == 2, left_size[up], 0)
    return position, sizes
