"""Buildings as closed solids (the paper's §5 building models): the roof is the BSP
triangulation of the footprint at roof height, the floor the same triangles at ground height,
reversed, and the walls two triangles per edge of every ring, courtyards included.

Many footprints are built at once, in numpy, from one :func:`triangulate_packed` call:

- the roof: the triangulation of each footprint (the rings' z is the roof z: a constant
  height, or a roof's own z, which ``planar_tolerance`` snaps onto a plane, paper §4.2), its
  triangles counter-clockwise seen from above, so facing up (outwards);
- the walls: one quad (two triangles) under each boundary edge of the roof (an edge of one
  roof triangle only: every ring edge, once the engine has dropped repeated points), from
  the roof down to the ground, facing away from the footprint's inside (out of the building,
  or into a courtyard);
- the floor: the roof's triangles at ground z (per footprint, or per vertex where the ground
  follows the terrain), in reverse order, so facing down.

Each solid is closed and consistently oriented by construction: every edge is used by exactly
two of its triangles, once in each direction (checked; a footprint where it is not fails with
its reason). With a flat roof and a flat floor its volume is the footprint's area times the
height.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .api import triangulate_packed
from .geometry.rings_batch import ragged_index
from .packed import PackedPolygons

SURFACE_ROOF = 0
SURFACE_WALL = 1
SURFACE_FLOOR = 2
SURFACE_NAMES = ("roof", "wall", "floor")


@dataclass
class PackedSolids:
    """Closed solids of many footprints, one after another in footprint order.

    - ``vertices`` (V, 3): the vertices of all solids (roof vertices, then ground vertices);
    - ``triangles`` (F, 3): indices into ``vertices``, outward-facing, grouped by solid, each
      solid's roof first, then its walls, then its floor;
    - ``solid`` (F,): the footprint of each triangle; ``surface`` (F,): ``SURFACE_ROOF``,
      ``SURFACE_WALL`` or ``SURFACE_FLOOR``; ``depth`` (F,): the BSP depth of the roof
      triangle a roof or floor triangle is made of, -1 for walls;
    - ``triangle_count`` (P,): triangles of each footprint (0 for failed and empty ones);
    - ``errors``: footprint index -> the reason it has no solid.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    solid: np.ndarray
    surface: np.ndarray
    depth: np.ndarray
    triangle_count: np.ndarray
    errors: dict[int, str] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.triangle_count)

    @property
    def triangle_start(self) -> np.ndarray:
        return np.cumsum(self.triangle_count) - self.triangle_count

    def triangles_of(self, index: int) -> np.ndarray:
        start = int(self.triangle_start[index])
        return self.triangles[start : start + int(self.triangle_count[index])]


def _polygon_of_points(polygons: PackedPolygons) -> np.ndarray:
    ring_polygon = np.repeat(np.arange(len(polygons), dtype=np.int64), polygons.ring_count)
    return np.repeat(ring_polygon, polygons.ring_len)


def _keys(polygon: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """One 24-byte key per (polygon, x, y) (0.0 and -0.0 alike)."""
    rows = np.empty((len(xy), 3), dtype=np.float64)
    rows[:, 0] = polygon
    rows[:, 1:] = xy + 0.0
    return np.ascontiguousarray(rows).view(np.dtype((np.void, 24))).ravel()


def _ground_at(
    polygons: PackedPolygons,
    ground_points: np.ndarray,
    vertex_polygon: np.ndarray,
    xy: np.ndarray,
) -> np.ndarray:
    """The ground z of the input point with the same polygon and x, y as each vertex; NaN
    where there is none."""
    keys = _keys(_polygon_of_points(polygons), polygons.points[:, :2])
    unique, first = np.unique(keys, return_index=True)
    wanted = _keys(vertex_polygon, xy)
    position = np.searchsorted(unique, wanted).clip(0, max(len(unique) - 1, 0))
    out = np.full(len(xy), np.nan)
    if not len(unique):
        return out
    found = unique[position] == wanted
    out[found] = np.asarray(ground_points, dtype=np.float64)[first[position[found]]]
    return out


def _fail(errors: dict[int, str], polygons: np.ndarray, reason: str) -> None:
    for index in np.unique(polygons).tolist():
        errors.setdefault(int(index), reason)


def build_solids(
    polygons: PackedPolygons,
    ground: float | np.ndarray = 0.0,
    ground_points: np.ndarray | None = None,
    *,
    rule: str = "first",
    planar_tolerance: float = 0.0,
    invalid: str = "fail",
) -> PackedSolids:
    """One closed solid per footprint of ``polygons``, whose rings' z is the roof z.

    The floor is at ``ground`` (a number, or one per footprint), or, with ``ground_points``
    (one z per row of ``polygons.points``), at the ground z of each vertex, so that the walls
    follow the terrain. A footprint fails (its reason in ``errors``) where the engine cannot
    triangulate it, where the roof is not above the ground at every vertex, or where its
    triangles do not make a simple surface (rings kept as given that overlap). An empty
    footprint (no area) has no triangles and no error.
    """
    count = len(polygons)
    packed = triangulate_packed(
        polygons, rule=rule, planar_tolerance=planar_tolerance, on_error="return", invalid=invalid
    )
    errors: dict[int, str] = {index: str(error) for index, error in packed.errors.items()}
    top = np.ascontiguousarray(packed.vertices, dtype=np.float64).reshape(-1, 3)
    vertex_polygon = np.repeat(np.arange(count, dtype=np.int64), packed.vertex_count)
    triangle_polygon = np.repeat(np.arange(count, dtype=np.int64), packed.triangle_count)
    roof = packed.triangles + np.repeat(packed.vertex_start, packed.triangle_count)[:, None]
    depth = np.asarray(packed.depth, dtype=np.int64)

    # the floor's z at every roof vertex
    if ground_points is not None:
        if len(ground_points) != len(polygons.points):
            raise ValueError(
                f"ground_points has {len(ground_points)} values for {len(polygons.points)} points"
            )
        floor_z = _ground_at(polygons, ground_points, vertex_polygon, top[:, :2])
    else:
        per_polygon = np.broadcast_to(np.asarray(ground, dtype=np.float64), (count,))
        floor_z = per_polygon[vertex_polygon]
    missing = ~np.isfinite(floor_z)
    if missing.any():
        _fail(errors, vertex_polygon[missing], "a roof vertex has no ground height")
    with np.errstate(invalid="ignore"):
        low = ~(top[:, 2] > floor_z) & ~missing
    if low.any():
        _fail(errors, vertex_polygon[low], "the roof is not above the ground at every vertex")

    # roof triangles counter-clockwise in XY (a roof the engine worked on in a steep plane
    # may come out clockwise)
    corners = top[roof] if len(roof) else np.zeros((0, 3, 3))
    cross = (corners[:, 1, 0] - corners[:, 0, 0]) * (corners[:, 2, 1] - corners[:, 0, 1]) - (
        corners[:, 1, 1] - corners[:, 0, 1]
    ) * (corners[:, 2, 0] - corners[:, 0, 0])
    if (cross < 0).any():
        _fail(errors, triangle_polygon[cross < 0], "the roof faces down (too steep a roof?)")

    # boundary edges: directed edges of the roof whose reverse is no roof edge
    vertex_count = max(len(top), 1)
    edges = np.concatenate([roof[:, [0, 1]], roof[:, [1, 2]], roof[:, [2, 0]]])
    edge_polygon = np.tile(triangle_polygon, 3)
    forward = edges[:, 0] * vertex_count + edges[:, 1]
    backward = edges[:, 1] * vertex_count + edges[:, 0]
    ordered = np.sort(forward)
    repeated = ordered[1:] == ordered[:-1]
    if repeated.any():
        twice = np.isin(forward, ordered[1:][repeated])
        _fail(errors, edge_polygon[twice], "the roof triangles overlap (not a simple surface)")
    boundary = ~np.isin(forward, backward)
    walls = edges[boundary]
    wall_polygon = edge_polygon[boundary]

    # the solid's triangles: ground vertices are top's rows shifted by len(top)
    shift = len(top)
    a, b = walls[:, 0], walls[:, 1]
    wall_triangles = np.concatenate(
        [np.column_stack([a + shift, b + shift, b]), np.column_stack([a + shift, b, a])]
    )
    floor = roof[:, ::-1] + shift
    triangles = np.concatenate([roof, wall_triangles, floor])
    solid = np.concatenate([triangle_polygon, np.tile(wall_polygon, 2), triangle_polygon])
    surface = np.repeat(
        np.array([SURFACE_ROOF, SURFACE_WALL, SURFACE_FLOOR], dtype=np.int8),
        [len(roof), len(wall_triangles), len(floor)],
    )
    depths = np.concatenate([depth, np.full(len(wall_triangles), -1, np.int64), depth])
    bottom = top.copy()
    bottom[:, 2] = floor_z
    vertices = np.concatenate([top, bottom])

    # failed footprints out; each solid's triangles together (roof, walls, floor), in order
    keep = np.ones(len(triangles), dtype=bool)
    if errors:
        failed = np.fromiter(errors, dtype=np.int64, count=len(errors))
        keep = ~np.isin(solid, failed)
    order = np.flatnonzero(keep)
    order = order[np.lexsort((surface[order], solid[order]))]
    triangles, solid, surface, depths = (
        triangles[order], solid[order], surface[order], depths[order]
    )  # fmt: skip
    # vertices of kept triangles only, in order of first use
    used = np.zeros(len(vertices), dtype=bool)
    used[triangles.ravel()] = True
    rank = np.cumsum(used) - 1
    return PackedSolids(
        vertices[used],
        rank[triangles],
        solid,
        surface,
        depths,
        np.bincount(solid, minlength=count).astype(np.int64),
        errors,
    )


def solid_rows(solids: PackedSolids, indices: np.ndarray) -> np.ndarray:
    """The triangle rows of the solids ``indices``, in that order."""
    return ragged_index(solids.triangle_start[indices], solids.triangle_count[indices])


def is_closed(triangles: np.ndarray) -> bool:
    """Every edge of ``triangles`` (by vertex index) used exactly twice, once each way."""
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if not len(triangles):
        return False
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    base = int(edges.max()) + 1
    forward = np.sort(edges[:, 0] * base + edges[:, 1])
    backward = np.sort(edges[:, 1] * base + edges[:, 0])
    return bool((forward[1:] != forward[:-1]).all() and (forward == backward).all())
