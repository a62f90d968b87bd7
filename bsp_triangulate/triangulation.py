"""Result and error types of the BSP triangulation engine."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class TriangulationError(ValueError):
    """A polygon cannot be triangulated; the message says what is wrong and in which ring."""


def _empty(shape: tuple[int, ...], dtype: type) -> np.ndarray:
    return np.zeros(shape, dtype=dtype)


@dataclass
class Triangulation:
    """Triangles of one polygon, in BSP pre-order.

    - ``vertices``: (N, 3) float64, every one an input vertex (z = 0 where the input has none).
    - ``triangles``: (M, 3) int64 indices into ``vertices``, counter-clockwise in XY; the first
      two indices are the triangle's base edge, shared with its parent.
    - ``parent``: (M,) index of the parent triangle, -1 for the root.
    - ``depth``: (M,) depth in the tree, 0 for the root.
    - ``side``: (M,) 0 root, 1 left child, 2 right child.
    - ``point_ids``: one per given interior point: the row of ``vertices`` it became, or -1
      where it was not used (outside the polygon, on its boundary, or a repeat of an earlier
      point); empty when no points were given.
    """

    vertices: np.ndarray = field(default_factory=lambda: _empty((0, 3), np.float64))
    triangles: np.ndarray = field(default_factory=lambda: _empty((0, 3), np.int64))
    parent: np.ndarray = field(default_factory=lambda: _empty((0,), np.int64))
    depth: np.ndarray = field(default_factory=lambda: _empty((0,), np.int64))
    side: np.ndarray = field(default_factory=lambda: _empty((0,), np.int8))
    point_ids: np.ndarray = field(default_factory=lambda: _empty((0,), np.int64))

    def __len__(self) -> int:
        return len(self.triangles)

    @property
    def is_empty(self) -> bool:
        return len(self.triangles) == 0
