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


def assert_each_as_engine(
    polygons: list, many: list, packed: object, rule: str, invalid: str
) -> None:
    """Each polygon's result from ``triangulate_many`` (``many``) and from
    ``triangulate_packed`` (``packed``, its errors included) is ``triangulate``'s."""
    listed = packed.to_list()
    for number, rings in enumerate(polygons):
        want = engine_or_error(rings, rule, invalid)
        assert same_result(many[number], want), number
        assert same_result(packed.errors.get(number, listed[number]), want), number
