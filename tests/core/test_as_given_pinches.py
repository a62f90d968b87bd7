"""Invalid rings kept as given (``invalid="as_given"``) where the fallback apex lands on another
occurrence of a base vertex (a ring that touches itself): no triangle repeats a vertex and
every child's base is an edge of its parent.

Named after the earcut fixtures that broke it: ``issue111`` at every rotation and ``water3``
at rotation 0 gave triangles such as [4, 3, 3], whose children then shared no edge with them.
"""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate import triangulate, triangulate_many

from .checks import check_triangulation, deviation
from .test_earcut_fixtures import ROTATIONS, allowed_deviation, load, rotate


def check_pinch_free(result) -> None:
    """No triangle with two equal vertex indices; every child shares its base with its parent."""
    t = np.asarray(result.triangles)
    repeated = np.flatnonzero((t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2]))
    assert len(repeated) == 0, f"triangles with a repeated vertex: {t[repeated[:5]].tolist()}"
    for child in np.flatnonzero(result.parent >= 0).tolist():
        parent = t[result.parent[child]].tolist()
        edges = {frozenset(parent[i : i + 2]) for i in range(2)} | {frozenset(parent[::2])}
        base = frozenset(t[child, :2].tolist())
        assert base in edges, f"triangle {child} {t[child]} has no edge of its parent {parent}"


@pytest.mark.parametrize(
    ("name", "degrees"),
    [*(("issue111", d) for d in ROTATIONS), *(("water3", d) for d in ROTATIONS)],
    ids=lambda value: str(value),
)
def test_as_given_self_touching_fixture_repeats_no_vertex(name: str, degrees: int) -> None:
    rings = rotate(load(name), degrees)
    for result in (
        triangulate(rings, invalid="as_given"),
        triangulate_many([rings], invalid="as_given")[0],
    ):
        check_pinch_free(result)
        check_triangulation(rings, result, valid=False)
        dev = deviation(rings, result.vertices, result.triangles)
        limit = allowed_deviation(name, degrees)
        assert dev <= limit if limit > 0 else dev < 1e-12


@pytest.mark.parametrize("rule", ["first", "elevation", "delaunay"])
def test_as_given_issue111_every_rule(rule: str) -> None:
    rings = load("issue111")
    check_pinch_free(triangulate(rings, invalid="as_given", rule=rule))
