"""Equality with the one-polygon builder: what ``triangulate`` gives a polygon (or the
error it raises), and whether another path's result is the same in every field and dtype
(or the same error message)."""

from __future__ import annotations

import numpy as np

from bsp_triangulate import TriangulationError, triangulate

FIELDS = ("vertices", "triangles", "parent", "depth", "side", "point_ids")


def engine_or_error(rings: list, rule: str, invalid: str) -> object:
    """``triangulate``'s result for ``rings``, or the TriangulationError it raises."""
    try:
        return triangulate(rings, rule=rule, invalid=invalid)
    except TriangulationError as exc:
        return exc


def same_result(got: object, want: object) -> bool:
    """``got`` is ``want``: every field with its dtype, or an error with the same message."""
    if isinstance(want, TriangulationError):
        return isinstance(got, TriangulationError) and str(got) == str(want)
    return all(
        getattr(got, name).dtype == getattr(want, name).dtype
        and np.array_equal(getattr(got, name), getattr(want, name))
        for name in FIELDS
    )
