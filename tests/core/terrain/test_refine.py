"""Interior points from a DEM until the mesh is within a tolerance at every inside cell."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import shapely

import bsp_triangulate
from bsp_triangulate.terrain.refine import CellGrid, cells_inside, locate_cells, refine, refine_many

RULES = ("first", "elevation", "delaunay")
CELL = 10.0
SIZE = 48  # cells per side of the synthetic DEM


def engine(*args, **kwargs):
    """The engine, looked up at call time."""
    return bsp_triangulate.triangulate_many(*args, **kwargs)


def hill_grid(nodata_patch: bool = False) -> CellGrid:
    """A Gaussian hill and a ridge on SIZE x SIZE cells of CELL m, origin (0, SIZE * CELL)."""
    centres = (np.arange(SIZE) + 0.5) * CELL
    x, y = np.meshgrid(centres, centres[::-1])
    values = 80.0 * np.exp(-((x - 200) ** 2 + (y - 260) ** 2) / (2 * 90.0**2))
    values += 15.0 * np.abs(np.sin(x / 37.0)) + 0.02 * y
    if nodata_patch:
        values[10:14, 30:36] = -9999.0
    return CellGrid.from_array(values, (0.0, CELL, 0.0, SIZE * CELL, 0.0, -CELL), -9999.0)


def with_z(rings: list[np.ndarray], grid: CellGrid) -> list[np.ndarray]:
    """Rings with z bilinear from the grid (as the DEM elevation source gives it)."""
    from bsp_triangulate.terrain.raster_sampling import fill_along_ring, sample_grid

    values = grid.values
    geotransform = (grid.x0, grid.dx, 0.0, grid.y0, 0.0, -grid.dy)
    out = []
    for ring in rings:
        ring = np.asarray(ring, dtype=np.float64)[:, :2]
        z = sample_grid(values, geotransform, ring[:, 0], ring[:, 1])
        out.append(np.column_stack([ring, fill_along_ring(z, ring)]))
    return out


def square_with_islands() -> list[np.ndarray]:
    outer = np.array([[13.0, 17.0], [461.0, 9.0], [455.0, 470.0], [230.0, 300.0], [7.0, 452.0]])
    island = np.array([[100.0, 100.0], [100.0, 180.0], [190.0, 175.0], [180.0, 105.0]])
    triangle = np.array([[300.0, 60.0], [330.0, 140.0], [400.0, 70.0]])
    return [outer, island, triangle]


def inside_cells(rings: list[np.ndarray], grid: CellGrid) -> tuple[np.ndarray, np.ndarray]:
    """(x, y, value) of the cell centres strictly inside (shapely), with a value."""
    polygon = shapely.Polygon(rings[0][:, :2], [ring[:, :2] for ring in rings[1:]])
    rows, cols = np.indices(grid.shape)
    x, y = grid.centre_x(cols.ravel()), grid.centre_y(rows.ravel())
    keep = shapely.contains_xy(polygon, x, y) & np.isfinite(grid.values.ravel())
    return np.column_stack([x[keep], y[keep]]), grid.values.ravel()[keep]


def surface(vertices: np.ndarray, triangles: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The mesh's z at each point by brute force over all triangles (NaN where none)."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    px, py = xy[:, :1], xy[:, 1:2]
    wb = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / det
    wc = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
    wa = 1 - wb - wc
    inside = (wa >= -1e-9) & (wb >= -1e-9) & (wc >= -1e-9)
    z = wa * a[:, 2] + wb * b[:, 2] + wc * c[:, 2]
    found = inside.any(axis=1)
    first = inside.argmax(axis=1)
    return np.where(found, z[np.arange(len(xy)), first], np.nan)


def final_mesh(rings, result, rule):
    [mesh] = engine([rings], points=[result.points], rule=rule, plane="xy", on_error="raise")
    return mesh


@pytest.mark.parametrize("rule", RULES)
def test_bound_holds_at_every_inside_cell(rule):
    grid = hill_grid()
    rings = with_z(square_with_islands(), grid)
    tolerance = 1.0
    result = refine(rings, grid, tolerance, engine=engine, rule=rule, plane="xy")
    assert result.within and not result.capped and result.error is None
    assert result.max_error <= tolerance
    assert result.added > 10
    xy, values = inside_cells(rings, grid)
    assert result.cells == len(values)
    mesh = final_mesh(rings, result, rule)
    z = surface(mesh.vertices, mesh.triangles, xy)
    assert not np.isnan(z).any()
    assert np.abs(z - values).max() <= tolerance
    # every added point is a cell centre with its cell's value
    cols = (result.points[:, 0] - grid.x0) / grid.dx - 0.5
    rows = (grid.y0 - result.points[:, 1]) / grid.dy - 0.5
    assert np.array_equal(cols, np.round(cols)) and np.array_equal(rows, np.round(rows))
    assert np.array_equal(result.points[:, 2], grid.values[rows.astype(int), cols.astype(int)])


def test_cap_is_respected_and_reported():
    grid = hill_grid()
    rings = with_z(square_with_islands(), grid)
    result = refine(rings, grid, 0.5, 7, engine=engine, plane="xy")
    assert result.capped and not result.within
    assert result.added <= 7 and len(result.points) <= 7
    assert result.max_error > 0.5
    xy, values = inside_cells(rings, grid)
    mesh = final_mesh(rings, result, "first")
    z = surface(mesh.vertices, mesh.triangles, xy)
    assert np.abs(z - values).max() == pytest.approx(result.max_error)


def test_groups_share_their_cap():
    grid = hill_grid()
    left = with_z([np.array([[5.0, 5.0], [230.0, 5.0], [230.0, 470.0], [5.0, 470.0]])], grid)
    right = with_z([np.array([[250.0, 5.0], [470.0, 5.0], [470.0, 470.0], [250.0, 470.0]])], grid)
    results = refine_many(
        [left, right], [grid, grid], 0.5, 12, engine=engine, groups=[0, 0], plane="xy"
    )
    assert sum(r.added for r in results) <= 12
    assert all(r.capped for r in results)


def test_survey_points_are_kept():
    grid = hill_grid()
    rings = with_z(square_with_islands(), grid)
    survey = np.array([[50.0, 60.0, 123.0], [420.0, 420.0, -5.0], [600.0, 600.0, 1.0]])
    result = refine(rings, grid, 2.0, engine=engine, fixed=survey, plane="xy")
    assert np.array_equal(result.points[:3], survey)
    mesh = final_mesh(rings, result, "first")
    assert mesh.point_ids[0] >= 0 and mesh.point_ids[1] >= 0
    assert mesh.point_ids[2] == -1  # outside the polygon
    assert np.array_equal(mesh.vertices[mesh.point_ids[:2]], survey[:2])


def test_tiny_polygon_without_cells():
    grid = hill_grid()
    rings = with_z([np.array([[11.0, 11.0], [14.0, 11.0], [12.0, 14.0]])], grid)
    fixed = np.array([[12.0, 12.0, 3.0]])
    result = refine(rings, grid, 0.1, engine=engine, fixed=fixed)
    assert result.cells == 0 and result.rounds == 0 and result.within
    assert np.array_equal(result.points, fixed)


def test_nodata_cells_are_skipped():
    grid = hill_grid(nodata_patch=True)
    rings = with_z([np.array([[5.0, 5.0], [470.0, 5.0], [470.0, 470.0], [5.0, 470.0]])], grid)
    result = refine(rings, grid, 1.0, engine=engine, plane="xy")
    xy, values = inside_cells(rings, grid)
    assert result.cells == len(values) == 46 * 46 - 24
    assert result.within
    mesh = final_mesh(rings, result, "first")
    assert np.abs(surface(mesh.vertices, mesh.triangles, xy) - values).max() <= 1.0
    assert np.isfinite(result.points[:, 2]).all()


def test_cells_inside_agree_with_shapely():
    grid = hill_grid()
    rng = np.random.default_rng(3)
    for _ in range(30):
        angles = np.sort(rng.uniform(0, 2 * np.pi, 9))
        radius = rng.uniform(60, 220, 9)
        outer = np.column_stack([240 + radius * np.cos(angles), 240 + radius * np.sin(angles)])
        # vertices on cell centres make edges through centres (on the boundary: not inside)
        outer[::3] = np.round(outer[::3] / CELL - 0.5) * CELL + CELL / 2
        island = np.array([[225.0, 225.0], [225.0, 255.0], [255.0, 255.0], [255.0, 225.0]])
        rings = [outer, island]
        polygon = shapely.Polygon(outer, [island])
        if not polygon.is_valid:
            continue
        rows, cols = cells_inside(rings, grid)
        got = set(zip(rows.tolist(), cols.tolist()))
        all_rows, all_cols = np.indices(grid.shape)
        x, y = grid.centre_x(all_cols.ravel()), grid.centre_y(all_rows.ravel())
        keep = shapely.contains_xy(polygon, x, y)
        want = set(zip(all_rows.ravel()[keep].tolist(), all_cols.ravel()[keep].tolist()))
        assert got == want


def test_locate_cells_z_does_not_depend_on_the_corners_order():
    rng = np.random.default_rng(5)
    grid = hill_grid()
    corners = np.concatenate(
        [rng.uniform(0, SIZE * CELL, (200, 3, 2)), rng.normal(size=(200, 3, 1)) * 1e3], -1
    )
    first = locate_cells(corners, [grid])
    for order in ([1, 2, 0], [2, 1, 0], [0, 2, 1]):
        again = locate_cells(corners[:, order], [grid])
        for column, expected in zip(again, first):
            np.testing.assert_array_equal(column, expected)


def test_locate_cells_finds_every_centre_once_per_triangle():
    grid = hill_grid()
    # two triangles tiling a square whose diagonal passes through cell centres
    corners = np.array(
        [
            [[0.0, 0.0, 0.0], [100.0, 0.0, 10.0], [100.0, 100.0, 20.0]],
            [[0.0, 0.0, 0.0], [100.0, 100.0, 20.0], [0.0, 100.0, 10.0]],
        ]
    )
    tri, row, col, z = locate_cells(corners, [grid])
    x, y = grid.centre_x(col), grid.centre_y(row)
    assert set(zip(row.tolist(), col.tolist())) == {
        (r, c) for r in range(38, 48) for c in range(10)
    }
    assert np.allclose(z, 0.1 * x + 0.1 * y)
    on_diagonal = x == y
    assert np.bincount(tri[on_diagonal]).tolist() == [10, 10]


def box_weights(corners: np.ndarray, grid: CellGrid) -> tuple[np.ndarray, ...]:
    """locate_cells' answer from every centre of each triangle's bounding box: the same
    weights (corners in (x, y) order), no row spans."""
    found = []
    for t, corner in enumerate(corners):
        corner = corner[np.lexsort((corner[:, 1], corner[:, 0]))]
        c0, c1 = grid.column_range(corner[:, 0].min(), corner[:, 0].max())
        r0, r1 = grid.row_range(corner[:, 1].min(), corner[:, 1].max())
        row, col = (
            a.ravel()
            for a in np.meshgrid(np.arange(r0, r1 + 1), np.arange(c0, c1 + 1), indexing="ij")
        )
        px, py = grid.x0 + (col + 0.5) * grid.dx, grid.y0 - (row + 0.5) * grid.dy
        a, b, c = corner
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        with np.errstate(invalid="ignore", divide="ignore"):
            wb = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
            wc = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
            wa = 1.0 - wb - wc
            z = wa * a[2] + wb * b[2] + wc * c[2]
        hit = (det != 0) & (np.minimum(np.minimum(wa, wb), wc) >= -1e-9)
        found.append((np.full(int(hit.sum()), t), row[hit], col[hit], z[hit]))
    return tuple(np.concatenate(column) for column in zip(*found))


@pytest.mark.parametrize("shape", ["random", "lattice", "flat slivers", "short edges"])
def test_locate_cells_row_spans_miss_no_centre_of_the_box(shape: str):
    rng = np.random.default_rng(7)
    grid = CellGrid(5e5 + 0.25, 6.2e6, 30.0, 30.0, rng.normal(size=(60, 80)))
    n = 300
    low = np.array([grid.x0, grid.y0 - 60 * grid.dy])
    extent = np.array([80 * grid.dx, 60 * grid.dy])
    if shape == "random":
        xy = low + rng.uniform(-0.1, 1.1, (n, 3, 2)) * extent
    elif shape == "lattice":  # corners on centres and cell corners: edges through centres
        steps = rng.integers(0, 60, (n, 3, 2)) + rng.choice([0.0, 0.5], (n, 3, 2))
        xy = np.stack([grid.x0 + steps[..., 0] * grid.dx, grid.y0 - steps[..., 1] * grid.dy], -1)
    elif shape == "flat slivers":
        a = low + rng.uniform(0, 1, (n, 2)) * extent
        b = a + np.column_stack([rng.uniform(-1, 1, n) * extent[0], rng.normal(size=n) * 1e-7])
        c = a + np.column_stack([rng.uniform(-1, 1, n) * extent[0], rng.normal(size=n) * 30])
        xy = np.stack([a, b, c], 1)
    else:
        a = low + rng.uniform(0, 1, (n, 2)) * extent
        b = a + rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-9, 1, (n, 1))
        b[:20] = a[:20]
        xy = np.stack([a, b, low + rng.uniform(0, 1, (n, 2)) * extent], 1)
    corners = np.concatenate([xy, rng.normal(size=(n, 3, 1))], -1)
    got, want = locate_cells(corners, [grid]), box_weights(corners, grid)
    for column, expected in zip(got, want):
        np.testing.assert_array_equal(column, expected)


def both_ways(monkeypatch: pytest.MonkeyPatch, run: Callable[[], object]) -> list:
    """``run()`` with the rounds by insertion, then with every round triangulated again."""
    from bsp_triangulate.terrain import refine as refine_module

    runs = []
    for insertion in (True, False):
        monkeypatch.setattr(refine_module, "_by_insertion", lambda options, on=insertion: on)
        runs.append(run())
    return runs


def assert_same_refinement(inserted, triangulated) -> None:
    """The same points, rounds and outcome."""
    assert inserted.rounds == triangulated.rounds
    assert inserted.added == triangulated.added
    assert inserted.capped == triangulated.capped
    assert inserted.within == triangulated.within
    assert inserted.max_error == triangulated.max_error
    np.testing.assert_array_equal(inserted.points, triangulated.points)


@pytest.mark.parametrize("clockwise", [False, True])
def test_rule_delaunay_rounds_by_insertion_equal_rounds_by_triangulation(
    clockwise: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the cell centres are exactly cocircular in fours: the ties must fall alike both ways
    grid = hill_grid()
    rings = with_z(square_with_islands(), grid)
    if clockwise:
        rings = [ring[::-1] for ring in rings]
    survey = np.array([[50.0, 60.0, 123.0], [333.3, 222.2, 40.0]])
    inserted, triangulated = both_ways(
        monkeypatch,
        lambda: refine(rings, grid, 0.5, engine=engine, fixed=survey, rule="delaunay", plane="xy"),
    )
    assert_same_refinement(inserted, triangulated)
    assert inserted.rounds > 3 and inserted.added > 50 and inserted.within


def test_rule_delaunay_by_insertion_with_groups_and_finished_polygons(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # polygons that finish early, a shared cap and a flat one: the same as triangulating again
    grid = hill_grid()
    squares = [
        [np.array([[x, y], [x + w, y], [x + w, y + w], [x, y + w]], dtype=float)]
        for x, y, w in ((5, 5, 60), (250, 5, 200), (5, 250, 220), (300, 300, 30), (80, 80, 90))
    ]
    polygons = [with_z(rings, grid) for rings in squares]
    runs = both_ways(
        monkeypatch,
        lambda: refine_many(
            polygons,
            [grid] * len(polygons),
            0.7,
            40,
            engine=engine,
            groups=[0, 1, 1, 2, 3],
            rule="delaunay",
            plane="xy",
        ),
    )
    for inserted, triangulated in zip(*runs):
        assert_same_refinement(inserted, triangulated)
    assert sum(r.added for r in runs[0][1:3]) <= 40
    assert any(r.capped for r in runs[0]) and any(r.within for r in runs[0])


def test_a_polygon_without_its_mesh_is_triangulated_again_each_round(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a first triangulation that is not locally Delaunay (an island's fallback bridge) gets
    # no mesh: that polygon is refined by triangulating again, to the same points
    from bsp_triangulate.geometry.delaunay_mesh import DelaunayMesh

    grid = hill_grid()
    rings = with_z(square_with_islands(), grid)
    expected = refine(rings, grid, 1.0, engine=engine, rule="delaunay", plane="xy")
    monkeypatch.setattr(DelaunayMesh, "make_delaunay", lambda self: 1)
    result = refine(rings, grid, 1.0, engine=engine, rule="delaunay", plane="xy")
    assert result.within and result.rounds == expected.rounds > 3
    np.testing.assert_array_equal(result.points, expected.points)


@pytest.mark.parametrize("clockwise", [False, True])
def test_the_refinement_mesh_handed_to_the_engine_gives_the_same_result(
    clockwise: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    from bsp_triangulate.tree import one_polygon

    grid = hill_grid()
    rings = with_z(square_with_islands(), grid)
    if clockwise:
        rings = [ring[::-1] for ring in rings]
    survey = np.array([[50.0, 60.0, 123.0], [333.3, 222.2, 40.0], [900.0, 900.0, 1.0]])
    result = refine(rings, grid, 0.7, engine=engine, fixed=survey, rule="delaunay", plane="xy")
    assert result.mesh is not None
    options = {"rule": "delaunay", "plane": "xy"}
    plain = bsp_triangulate.triangulate(rings, points=result.points, **options)
    inserted = []
    original = one_polygon._delaunay_mesh
    monkeypatch.setattr(
        one_polygon, "_delaunay_mesh", lambda *a: inserted.append(1) or original(*a)
    )
    hinted = bsp_triangulate.triangulate(rings, points=result.points, mesh=result.mesh, **options)
    assert not inserted  # the hint was used
    for name in ("vertices", "triangles", "parent", "depth", "side", "point_ids"):
        np.testing.assert_array_equal(getattr(hinted, name), getattr(plain, name), name)
    # a wrong hint is ignored: flipped triangles, a missing one, another polygon's
    for bad in (result.mesh[:, [1, 0, 2]], result.mesh[1:], np.array([[0, 1, 2]])):
        again = bsp_triangulate.triangulate(rings, points=result.points, mesh=bad, **options)
        np.testing.assert_array_equal(again.triangles, plain.triangles)
    packed = bsp_triangulate.triangulate_packed(
        bsp_triangulate.PackedPolygons.of([rings]),
        points=(result.points, np.array([len(result.points)])),
        meshes=(result.mesh, np.array([len(result.mesh)])),
        **options,
    )
    np.testing.assert_array_equal(packed.triangles, plain.triangles)


def test_rule_delaunay_by_insertion_on_random_polygons_with_islands(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # many polygons refined at once (one mesh set), clockwise rings among them: inserting
    # each round's points gives what triangulating again gives. The cell centres are
    # cocircular in fours: a point's bridge with another vertex exactly on its diametral
    # circle must still be an edge of the triangulation (seed 1032 has one)
    import random

    from tests.core.random_polygons import random_polygon

    rnd = random.Random(1032)
    grid = hill_grid()
    polygons = []
    for k in range(12):
        rings = random_polygon(rnd, islands=k % 3, touching=1 if k % 4 == 0 else 0)
        shift = np.array([rnd.uniform(80.0, 400.0), rnd.uniform(80.0, 400.0)])
        if k % 4 == 0:
            continue  # touching islands: their shared point is two vertices of one place
        polygons.append(
            with_z([np.asarray(r, dtype=float)[:, :2] * 3.0 + shift for r in rings], grid)
        )
    runs = both_ways(
        monkeypatch,
        lambda: refine_many(
            polygons, [grid] * len(polygons), 0.4, 300, engine=engine, rule="delaunay", plane="xy"
        ),
    )
    for inserted, triangulated in zip(*runs):
        assert_same_refinement(inserted, triangulated)
    assert sum(r.added for r in runs[0]) > 300
