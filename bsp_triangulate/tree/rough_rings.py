"""Rings the batch path leaves, triangulated for the insertion of many polygons' points
(rule "delaunay" with points, docs/algorithm.md, section 5b).

Such rings (most often too many vertices for the lock-step builder) are triangulated under
rule "first"; ``points_batch.insert_points`` flips that triangulation into the rings'
constrained Delaunay one before it inserts the points, so that these polygons join the
others' insertion instead of going one by one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry.delaunay_mesh import edge_links
from ..geometry.predicates import orient_many
from ..geometry.rings import normalise_rings
from ..geometry.rings_batch import ring_edge_keys
from ..triangulation import Triangulation, TriangulationError
from .one_polygon import _triangulate


def rough_ring_meshes(
    polygons: Sequence[Sequence[object]], found: list[Triangulation | None], plane: str
) -> list[bool]:
    """Where the batch path left a polygon's rings (``found`` None), their triangulation
    under rule first into ``found``, to be flipped into their constrained Delaunay one by the
    insertion; per polygon whether it is such a one. Left out where rule first fails, the
    rings share a point (vertices of equal x, y), a triangle is not strictly counter-
    clockwise in XY (working plane other than XY) or the mesh's outline is not the rings'
    edges (a vertex on another ring's edge), which the one-polygon builder decides."""
    rough = [False] * len(found)
    for number, mesh in enumerate(found):
        if mesh is not None:
            continue
        try:
            with np.errstate(over="ignore", invalid="ignore", under="ignore"):
                first = _triangulate(
                    polygons[number],
                    rule="first",
                    planar_tolerance=0.0,
                    invalid="fail",
                    plane=plane,
                )
        except (TriangulationError, ArithmeticError, ValueError, TypeError):
            continue
        xy = first.vertices[:, :2]
        corners = xy[first.triangles]
        if (
            len(first.triangles)
            and len(np.unique(xy, axis=0)) == len(xy)
            and (orient_many(*(corners[:, k, axis] for k in range(3) for axis in (0, 1))) > 0).all()
            and _rims_are_ring_edges(polygons[number], first, plane)
        ):
            # every triangle strictly counter-clockwise in XY (not so in another working plane)
            found[number], rough[number] = first, True
    return rough


def _rims_are_ring_edges(rings: Sequence[object], mesh: Triangulation, plane: str) -> bool:
    """Whether the edges with one triangle of ``mesh`` are exactly the edges of the
    normalised ``rings`` (not so where a vertex lies on another edge, which the engine
    splits there)."""
    clean, _ = normalise_rings(rings, plane)
    sizes = np.array([len(ring) for ring in clean], dtype=np.int64)
    n = int(sizes.sum())
    if n != len(mesh.vertices):
        return False
    ring_keys = np.sort(ring_edge_keys(np.cumsum(sizes) - sizes, sizes, n))
    across, repeated = edge_links(mesh.triangles, n)
    rim = np.flatnonzero(across < 0)
    tri = mesh.triangles
    a, b = tri[:, [1, 2, 0]].ravel()[rim], tri[:, [2, 0, 1]].ravel()[rim]
    rim_keys = np.sort(np.minimum(a, b) * n + np.maximum(a, b))
    return not repeated.any() and np.array_equal(rim_keys, ring_keys)
