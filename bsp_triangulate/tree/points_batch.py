"""Rule "delaunay" with interior points for many polygons at once (docs/algorithm.md, 5b).

The rings of the polygons come triangulated from the lock-step batch path (their constrained
Delaunay triangulations); here every polygon's points go into its triangulation, all
polygons at once, in batches (``geometry/delaunay_batch.MeshSet``, one region per polygon, in
the polygon's working plane so that cocircular ties fall as the one-polygon builder decides
them). Each polygon's triangles then go to the one-polygon builder with the rows of the
points they used, which reads the tree off them where those rows are its own.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry.delaunay_batch import MeshSet
from ..geometry.delaunay_mesh import containing_triangles, hilbert_order
from ..geometry.rings import xy_mirror
from ..triangulation import Triangulation


@dataclass
class InsertedMesh:
    """A polygon's rings' triangulation with its points inserted: ``triangles`` (t, 3) rows
    of its vertices (ring vertices, then the points used, in the order given), counter-
    clockwise in the output's XY; ``point_ids`` per given point its row there, or -1;
    ``mirrored``: its working plane mirrors x (its outer ring is clockwise in XY);
    ``across``: where known, the links of the triangles as they are in the working plane
    (``triangles`` with their first two corners swapped where ``mirrored``): per slot
    ``3t + k`` (the edge from corner k + 1 to k + 2 of triangle t) the slot of the same edge
    in the neighbouring triangle, or -1."""

    triangles: np.ndarray
    point_ids: np.ndarray
    mirrored: bool = False
    across: np.ndarray | None = None


def insert_points(
    polygons: Sequence[Sequence[object]],
    ring_meshes: Sequence[Triangulation | None],
    points: Sequence[object],
) -> list[InsertedMesh | None]:
    """Per polygon (rings as given, a triangulation of its rings or None, its points (m, 2
    or 3) in XY): its :class:`InsertedMesh`, or None where it has no ring triangulation. The
    ring triangulations are flipped into the constrained Delaunay one under the tie rule
    first: those the batch path leaves are any one (``rough_rings``), and the batch path's
    own rule "delaunay" trees keep a bridge that is the other diagonal of a cocircular group
    (its diametral circle holds no vertex strictly inside). A point is used where it lies
    strictly inside a triangle or on an edge between two, and is no vertex or repeat of an
    earlier point."""
    kept = [
        i
        for i, mesh in enumerate(ring_meshes)
        if mesh is not None and len(mesh.triangles) and len(points[i])
    ]
    found: list[InsertedMesh | None] = [None] * len(polygons)
    if not kept:
        return found
    sizes = np.array([len(ring_meshes[i].vertices) for i in kept], dtype=np.int64)
    offsets = np.cumsum(sizes) - sizes
    mirror = _mirrors(polygons, ring_meshes, kept)
    x = np.concatenate([ring_meshes[i].vertices[:, 0] * m for i, m in zip(kept, mirror)])
    y = np.concatenate([ring_meshes[i].vertices[:, 1] for i in kept])
    triangles = np.concatenate(
        [
            (ring_meshes[i].triangles[:, [1, 0, 2]] if m < 0 else ring_meshes[i].triangles) + o
            for i, m, o in zip(kept, mirror, offsets)
        ]
    )
    region = np.repeat(np.arange(len(kept)), [len(ring_meshes[i].triangles) for i in kept])
    given = [np.asarray(points[i], dtype=np.float64) for i in kept]
    counts = np.array([len(p) for p in given], dtype=np.int64)
    owner = np.repeat(np.arange(len(kept)), counts)
    px = np.concatenate([p[:, 0] for p in given]) * mirror[owner]
    py = np.concatenate([p[:, 1] for p in given])
    mesh = MeshSet(x, y, triangles, region)
    # before the points are looked for (far fewer slivers in a rough ring triangulation)
    mesh.make_delaunay(np.arange(len(region)))
    start = containing_triangles(x, y, mesh.triangles(), px, py, region, owner)
    ids = np.full(len(px), -1, dtype=np.int64)
    inside = np.flatnonzero(start >= 0)
    order = inside[hilbert_order(px[inside], py[inside])]
    order = order[np.argsort(owner[order], kind="stable")]  # polygon by polygon
    ids[order] = mesh.insert(px[order], py[order], start[order], boundary=False)
    # rows: ring vertices keep theirs; the used points follow them in the order given
    used = ids >= 0
    rank = np.cumsum(used) - 1
    used_counts = np.bincount(owner[used], minlength=len(kept))
    first_rank = np.cumsum(used_counts) - used_counts
    row = np.empty(mesh.vertex_count, dtype=np.int64)
    row[: len(x)] = np.arange(len(x)) - np.repeat(offsets, sizes)
    row[ids[used]] = sizes[owner[used]] + rank[used] - first_rank[owner[used]]
    point_rows = np.where(used, row[np.maximum(ids, 0)], -1)
    mesh_region = mesh.region[: mesh.triangle_count]
    by_region = np.argsort(mesh_region, kind="stable")
    local = row[mesh.triangles()[by_region]]
    tri_counts = np.bincount(mesh_region, minlength=len(kept))
    tri_starts = np.cumsum(tri_counts) - tri_counts
    # the links in the same order, each polygon's slots from 0
    new_id = np.empty_like(by_region)
    new_id[by_region] = np.arange(len(by_region))
    linked = mesh.across[: 3 * mesh.triangle_count].reshape(-1, 3)[by_region].ravel()
    slot_base = np.repeat(3 * tri_starts, 3 * tri_counts)
    links = np.where(linked >= 0, 3 * new_id[linked // 3] + linked % 3 - slot_base, -1)
    point_starts = np.cumsum(counts) - counts
    for k, i in enumerate(kept):
        tri = local[tri_starts[k] : tri_starts[k] + tri_counts[k]]
        across = links[3 * tri_starts[k] : 3 * (tri_starts[k] + tri_counts[k])]
        found[i] = InsertedMesh(
            tri[:, [1, 0, 2]] if mirror[k] < 0 else tri,
            point_rows[point_starts[k] : point_starts[k] + counts[k]],
            bool(mirror[k] < 0),
            across,
        )
    return found


def _mirrors(
    polygons: Sequence[Sequence[object]],
    ring_meshes: Sequence[Triangulation | None],
    kept: list[int],
) -> np.ndarray:
    """Per polygon ``kept``: -1.0 where its outer ring is clockwise in XY, else 1.0. Read off
    the triangle on the outer ring's first edge (vertices 0 and 1), the first of its ring
    mesh: counter-clockwise, it lists 0 before 1 exactly where the polygon lies left of that
    edge; else (no such first triangle) from the ring itself."""
    first = np.array([ring_meshes[i].triangles[0] for i in kept], dtype=np.int64).reshape(-1, 3)
    after = first[:, [1, 2, 0]]
    forward = ((first == 0) & (after == 1)).any(axis=1)
    backward = ((first == 1) & (after == 0)).any(axis=1)
    mirror = np.where(forward, 1.0, -1.0)
    for k in np.flatnonzero(forward == backward).tolist():
        mirror[k] = xy_mirror(polygons[kept[k]])
    return mirror
