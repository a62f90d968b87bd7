"""bsptriangulate:triangulate through processing.run / runAndLoadResults on generated and real
layers: counts, attributes, elevation sources, invalid-polygon policies, mesh and style."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsFeatureRequest,
    QgsGeometry,
    QgsGraduatedSymbolRenderer,
    QgsMeshLayer,
    QgsPointXY,
    QgsProcessingException,
    QgsProject,
    QgsVectorLayer,
)

from tests.conftest import SHARED_DATA
from tests.qgis.helpers import (
    ALG,
    CELL,
    DEM_POLYGON,
    UTM,
    X0,
    Y0,
    RecordingFeedback,
    corners,
    plane,
    polygon_layer,
    run,
    triangle_rows,
    utm_wkt,
    write_plane_dem,
)

CONCAVE_WITH_TWO_ISLANDS = (
    "POLYGON((0 0, 20 0, 20 20, 10 8, 0 20, 0 0),"
    "(2 2, 6 2, 6 5, 2 5, 2 2),"
    "(14 3, 17 2.5, 15 6, 14 3))"
)
BOW_TIE = "POLYGON((0 0, 10 10, 10 0, 0 10, 0 0))"


pytestmark = pytest.mark.usefixtures("provider")


def assert_counts_add_up(result: dict, total: int) -> None:
    rows = triangle_rows(result)
    triangulated = len({row["feature_id"] for row in rows})
    assert result["FEATURE_COUNT"] == total
    assert result["TRIANGLE_COUNT"] == len(rows)
    assert triangulated + result["FAILED_COUNT"] + result["EMPTY_COUNT"] == total


def test_concave_polygon_with_two_islands_gives_n_plus_2h_minus_2_triangles_over_its_area():
    layer = polygon_layer([CONCAVE_WITH_TWO_ISLANDS])
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 0, "OUTPUT_TREE": "memory:"})
    rows = triangle_rows(result)
    n, h = 5 + 4 + 3, 2
    assert len(rows) == n + 2 * h - 2 == result["TRIANGLE_COUNT"]
    polygon = QgsGeometry.fromWkt(CONCAVE_WITH_TWO_ISLANDS)
    assert sum(row["area_2d"] for row in rows) == pytest.approx(polygon.area())
    union = QgsGeometry.unaryUnion([row.geometry() for row in rows])
    assert union.symDifference(polygon).area() == pytest.approx(0.0, abs=1e-9)
    assert sorted(row["order"] for row in rows) == list(range(len(rows)))
    roots = [row for row in rows if row["parent"] == -1]
    assert [(r["order"], r["depth"], r["side"]) for r in roots] == [(0, 0, 0)]
    assert {row["side"] for row in rows if row["parent"] >= 0} <= {1, 2}
    tree = list(result["OUTPUT_TREE"].getFeatures())
    assert len(tree) == len(rows) - 1
    assert result["OUTPUT_TREE"].wkbType() == 1002  # LineStringZ


def test_triangles_carry_source_attributes_with_clashing_names_prefixed():
    layer = polygon_layer([CONCAVE_WITH_TWO_ISLANDS])
    rows = triangle_rows(run({"INPUT": layer}))
    names = rows[0].fields().names()
    assert names[:4] == ["feature_id", "name", "height", "src_depth"]
    assert names[4:] == [
        "part",
        "order",
        "parent",
        "depth",
        "side",
        "area_2d",
        "area_3d",
        "min_angle",
        "slope",
        "aspect",
    ]
    source_id = next(layer.getFeatures()).id()
    assert {(r["feature_id"], r["name"], r["height"], r["src_depth"]) for r in rows} == {
        (source_id, "f0", 10.0, 7)
    }


def test_multipolygon_parts_each_get_their_own_tree():
    wkt = "MULTIPOLYGON(((0 0, 4 0, 4 4, 0 4, 0 0)), ((10 0, 16 0, 13 5, 10 0)))"
    result = run({"INPUT": polygon_layer([wkt], "MultiPolygon")})
    rows = triangle_rows(result)
    by_part = {part: [r for r in rows if r["part"] == part] for part in (0, 1)}
    assert [len(by_part[0]), len(by_part[1])] == [2, 1]
    for part_rows in by_part.values():
        assert sorted(r["order"] for r in part_rows) == list(range(len(part_rows)))
        assert [r["parent"] for r in part_rows if r["order"] == 0] == [-1]
    assert_counts_add_up(result, 1)


def test_polygon_z_keeps_each_vertex_z_with_the_geometry_source():
    wkt = "POLYGON Z((0 0 1, 10 0 2, 10 10 3, 5 4 9, 0 10 4, 0 0 1))"
    result = run({"INPUT": polygon_layer([wkt], "PolygonZ"), "ELEVATION_SOURCE": 1})
    given = {(0, 0): 1, (10, 0): 2, (10, 10): 3, (5, 4): 9, (0, 10): 4}
    rows = triangle_rows(result)
    assert len(rows) == 3
    for row in rows:
        for x, y, z in corners(row):
            assert given[(x, y)] == z


def test_null_and_empty_geometries_are_counted_as_empty_and_written_nowhere():
    layer = polygon_layer([None, "POLYGON((0 0, 1 0, 1 1, 0 0))", None])
    result = run({"INPUT": layer})
    assert result["EMPTY_COUNT"] == 2
    assert result["TRIANGLE_COUNT"] == 1
    assert_counts_add_up(result, 3)


def test_empty_layer_gives_empty_outputs_and_zero_counts(tmp_path: Path):
    mesh = tmp_path / "empty.2dm"
    result = run({"INPUT": polygon_layer([]), "OUTPUT_MESH": str(mesh)})
    assert [result[k] for k in ("FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT")] == [0, 0, 0]
    assert result["OUTPUT_TRIANGLES"].featureCount() == 0
    assert mesh.read_text().split() == ["MESH2D"]


def test_bow_tie_repaired_by_default_is_split_at_its_crossing_and_reported():
    feedback = RecordingFeedback()
    layer = polygon_layer([BOW_TIE])
    result = run({"INPUT": layer}, feedback)
    rows = triangle_rows(result)
    assert result["FAILED_COUNT"] == 0 and len(rows) == 2
    assert sum(r["area_2d"] for r in rows) == pytest.approx(50.0)
    assert any((x, y) == (5.0, 5.0) for row in rows for x, y, _z in corners(row))
    fid = next(layer.getFeatures()).id()
    assert any("Repaired" in w and str(fid) in w for w in feedback.warnings)


@pytest.mark.parametrize(
    "check", [QgsFeatureRequest.GeometrySkipInvalid, QgsFeatureRequest.GeometryAbortOnInvalid]
)
def test_bow_tie_reaches_the_repair_policy_whatever_the_context_invalid_geometry_check(check):
    result = run({"INPUT": polygon_layer([BOW_TIE])}, invalid_check=check)
    assert (result["FEATURE_COUNT"], result["FAILED_COUNT"], result["TRIANGLE_COUNT"]) == (1, 0, 2)


def test_bow_tie_with_fail_policy_fails_only_that_feature_with_its_id():
    feedback = RecordingFeedback()
    layer = polygon_layer([BOW_TIE, "POLYGON((20 0, 24 0, 24 3, 20 0))"])
    result = run({"INPUT": layer, "INVALID_POLYGONS": 1}, feedback)
    bow_tie_id = next(layer.getFeatures()).id()
    assert result["FAILED_COUNT"] == 1 and result["TRIANGLE_COUNT"] == 1
    assert [e for e in feedback.errors if f"Feature {bow_tie_id}:" in e]
    assert_counts_add_up(result, 2)


def test_self_touching_ring_triangulated_as_given_keeps_its_vertices_and_area():
    # a figure-eight ring touching itself at (7, 15): invalid, but both lobes are real area
    ring = "POLYGON((7 18, 7 15, 5 15, 7 13, 7 15, 17 17, 7 18))"
    feedback = RecordingFeedback()
    result = run({"INPUT": polygon_layer([ring]), "INVALID_POLYGONS": 2}, feedback)
    assert (result["FAILED_COUNT"], feedback.errors) == (0, [])
    rows = triangle_rows(result)
    inputs = {(7.0, 18.0), (7.0, 15.0), (5.0, 15.0), (7.0, 13.0), (17.0, 17.0)}
    for row in rows:
        assert {(x, y) for x, y, _z in corners(row)} <= inputs
    assert sum(r["area_2d"] for r in rows) == pytest.approx(17.0)


def test_bow_tie_triangulated_as_given_is_repaired_at_its_crossing():
    # the two lobes cancel in the ring's signed area: no triangulation of the ring as given can
    # keep its area, so "as given" repairs it and the crossing point becomes a vertex
    feedback = RecordingFeedback()
    result = run({"INPUT": polygon_layer([BOW_TIE]), "INVALID_POLYGONS": 2}, feedback)
    assert_counts_add_up(result, 1)
    assert (result["FAILED_COUNT"], feedback.errors) == (0, [])
    rows = triangle_rows(result)
    assert sum(r["area_2d"] for r in rows) == pytest.approx(50.0)
    inputs = {(0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0), (5.0, 5.0)}
    for row in rows:
        assert {(x, y) for x, y, _z in corners(row)} <= inputs


def test_expression_source_uses_a_field_per_feature_then_scale_and_offset():
    layer = polygon_layer(["POLYGON((0 0, 4 0, 4 4, 0 0))", "POLYGON((10 0, 14 0, 14 4, 10 0))"])
    result = run(
        {
            "INPUT": layer,
            "ELEVATION_SOURCE": 2,
            "Z_EXPRESSION": '"height" * 2',
            "Z_SCALE": 0.5,
            "Z_OFFSET": 3,
        }
    )
    heights = {f.id(): f["height"] for f in layer.getFeatures()}
    rows = triangle_rows(result)
    assert len(rows) == 2
    for row in rows:
        assert set(corners(row)[:, 2]) == {heights[row["feature_id"]] + 3}


def test_expression_returning_null_fails_that_feature():
    layer = polygon_layer(["POLYGON((0 0, 4 0, 4 4, 0 0))", "POLYGON((10 0, 14 0, 14 4, 10 0))"])
    expression = "CASE WHEN \"name\" = 'f0' THEN NULL ELSE 5 END"
    feedback = RecordingFeedback()
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 2, "Z_EXPRESSION": expression}, feedback)
    assert result["FAILED_COUNT"] == 1 and result["TRIANGLE_COUNT"] == 1
    assert any("NULL" in e for e in feedback.errors)


def test_dem_bilinear_puts_every_vertex_on_the_dem_plane(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    result = run(
        {"INPUT": polygon_layer([utm_wkt(DEM_POLYGON)]), "ELEVATION_SOURCE": 3, "DEM": str(dem)}
    )
    rows = triangle_rows(result)
    assert len(rows) == 3
    points = np.concatenate([corners(row) for row in rows])
    np.testing.assert_allclose(points[:, 2], plane(points[:, 0], points[:, 1]), atol=1e-6)


def test_dem_in_another_crs_is_sampled_at_the_reprojected_vertices(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    utm, wgs84 = QgsCoordinateReferenceSystem(UTM), QgsCoordinateReferenceSystem("EPSG:4326")
    to_wgs84 = QgsCoordinateTransform(utm, wgs84, QgsProject.instance())
    polygon = QgsGeometry.fromWkt(utm_wkt(DEM_POLYGON))
    polygon.transform(to_wgs84)
    layer = polygon_layer([polygon.asWkt(12)], crs="EPSG:4326")
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 3, "DEM": str(dem)})
    to_utm = QgsCoordinateTransform(wgs84, utm, QgsProject.instance())
    points = np.concatenate([corners(row) for row in triangle_rows(result)])
    assert len(points) == 9
    for x, y, z in points:
        projected = to_utm.transform(QgsPointXY(x, y))
        assert z == pytest.approx(plane(projected.x(), projected.y()), abs=1e-6)


def test_dem_nearest_takes_the_value_of_the_containing_cell(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    layer = polygon_layer([utm_wkt(DEM_POLYGON)])
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_INTERPOLATION": 1})
    for x, y, z in np.concatenate([corners(row) for row in triangle_rows(result)]):
        centre_x = X0 + (math.floor((x - X0) / CELL) + 0.5) * CELL
        centre_y = Y0 - (math.floor((Y0 - y) / CELL) + 0.5) * CELL
        assert z == pytest.approx(plane(centre_x, centre_y), abs=1e-6)


def test_densified_boundary_points_become_vertices_on_the_dem(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    square = [(1000, 1000), (3000, 1000), (3000, 3000), (1000, 3000)]
    parameters = {"ELEVATION_SOURCE": 3, "DEM": str(dem), "MAX_SEGMENT_LENGTH": 500}
    result = run({"INPUT": polygon_layer([utm_wkt(square)]), **parameters})
    points = np.unique(np.concatenate([corners(row) for row in triangle_rows(result)]), axis=0)
    assert len(points) == 16  # 4 edges of 2000 m in 4 pieces each
    assert result["TRIANGLE_COUNT"] == 14
    np.testing.assert_allclose(points[:, 2], plane(points[:, 0], points[:, 1]), atol=1e-6)


def nodata_vertex_dem(tmp_path: Path) -> Path:
    """The plane DEM with nodata under DEM_POLYGON's vertex (2540, 2230) (row 22, col 25)."""
    return write_plane_dem(tmp_path / "holes.tif", nodata_cells=((22, 25),))


def test_dem_nodata_under_a_vertex_is_filled_along_the_ring_by_default(tmp_path: Path):
    dem = nodata_vertex_dem(tmp_path)
    layer = polygon_layer([utm_wkt(DEM_POLYGON)])
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_INTERPOLATION": 1})
    assert result["FAILED_COUNT"] == 0
    z = {(x, y): z for row in triangle_rows(result) for x, y, z in corners(row)}
    world = [(X0 + x, Y0 - y) for x, y in DEM_POLYGON]

    def nearest_cell(point):
        col, row = (point[0] - X0) // CELL, (Y0 - point[1]) // CELL
        return plane(X0 + (col + 0.5) * CELL, Y0 - (row + 0.5) * CELL)

    before, hole, after = world[2], world[3], world[4]
    d1, d2 = math.dist(before, hole), math.dist(hole, after)
    expected = nearest_cell(before) + (nearest_cell(after) - nearest_cell(before)) * d1 / (d1 + d2)
    assert z[hole] == pytest.approx(expected, abs=1e-6)
    assert z[before] == pytest.approx(nearest_cell(before), abs=1e-6)


def test_dem_nodata_under_a_vertex_fails_the_feature_when_asked(tmp_path: Path):
    dem = nodata_vertex_dem(tmp_path)
    feedback = RecordingFeedback()
    layer = polygon_layer([utm_wkt(DEM_POLYGON)])
    parameters = {"ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_INTERPOLATION": 1, "DEM_NODATA": 1}
    result = run({"INPUT": layer, **parameters}, feedback)
    assert result["FAILED_COUNT"] == 1 and result["TRIANGLE_COUNT"] == 0
    assert any("nodata" in error for error in feedback.errors)


def test_dem_band_beyond_the_band_count_is_refused_before_running(tmp_path: Path):
    dem = write_plane_dem(tmp_path / "plane.tif")
    layer = polygon_layer([utm_wkt(DEM_POLYGON)])
    with pytest.raises(QgsProcessingException, match="band"):
        run({"INPUT": layer, "ELEVATION_SOURCE": 3, "DEM": str(dem), "DEM_BAND": 2})


def test_mesh_file_shares_identical_vertices_and_holds_feature_and_depth(tmp_path: Path):
    wkt = "MULTIPOLYGON(((0 0, 4 0, 4 4, 0 4, 0 0)), ((4 0, 8 0, 8 4, 4 4, 4 0)))"
    mesh_path = tmp_path / "out.2dm"
    result = run({"INPUT": polygon_layer([wkt], "MultiPolygon"), "OUTPUT_MESH": str(mesh_path)})
    lines = mesh_path.read_text().splitlines()
    assert sum(line.startswith("ND ") for line in lines) == 6  # 8 part vertices, 2 shared
    assert sum(line.startswith("E3T ") for line in lines) == result["TRIANGLE_COUNT"] == 4
    layer = QgsMeshLayer(str(mesh_path), "mesh", "mdal")
    assert layer.isValid() and layer.dataProvider().faceCount() == 4
    assert layer.dataProvider().addDataset(str(tmp_path / "out_els.dat"))
    names = {
        layer.dataProvider().datasetGroupMetadata(i).name()
        for i in range(layer.dataProvider().datasetGroupCount())
    }
    assert {"feature_id", "depth"} <= names


def test_ply_mesh_output_loads_with_its_face_values(tmp_path: Path):
    mesh_path = tmp_path / "out.ply"
    result = run(
        {"INPUT": polygon_layer([CONCAVE_WITH_TWO_ISLANDS]), "OUTPUT_MESH": str(mesh_path)}
    )
    layer = QgsMeshLayer(str(mesh_path), "mesh", "mdal")
    assert layer.isValid()
    assert layer.dataProvider().faceCount() == result["TRIANGLE_COUNT"] == 14
    names = {
        layer.dataProvider().datasetGroupMetadata(i).name()
        for i in range(layer.dataProvider().datasetGroupCount())
    }
    assert {"feature_id", "depth"} <= names


@pytest.mark.parametrize("skipped", [None, ""])
def test_mesh_only_run_skips_the_triangles_output_and_still_counts(tmp_path: Path, skipped):
    mesh_path = tmp_path / "only.2dm"
    layer = polygon_layer([CONCAVE_WITH_TWO_ISLANDS, None])
    result = run({"INPUT": layer, "OUTPUT_MESH": str(mesh_path), "OUTPUT_TRIANGLES": skipped})
    assert "OUTPUT_TRIANGLES" not in result
    assert (result["FEATURE_COUNT"], result["TRIANGLE_COUNT"], result["EMPTY_COUNT"]) == (2, 14, 1)
    lines = mesh_path.read_text().splitlines()
    assert sum(line.startswith("E3T ") for line in lines) == 14


def test_run_without_mesh_and_without_triangles_is_refused_before_running():
    layer = polygon_layer([CONCAVE_WITH_TWO_ISLANDS])
    with pytest.raises(QgsProcessingException):
        run({"INPUT": layer, "OUTPUT_MESH": None, "OUTPUT_TRIANGLES": None})


def test_run_and_load_results_adds_styled_triangles_and_the_mesh_with_the_input_crs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import processing
    from processing.gui import Postprocessing

    # pytest-qgis's stand-in iface is a MagicMock, which QGIS 3.44's result loading refuses
    monkeypatch.setattr(Postprocessing, "iface", None, raising=False)

    project = QgsProject.instance()
    project.removeAllMapLayers()
    layer = polygon_layer([CONCAVE_WITH_TWO_ISLANDS])
    parameters = {
        "INPUT": layer,
        "OUTPUT_TRIANGLES": "TEMPORARY_OUTPUT",
        "OUTPUT_MESH": str(tmp_path / "loaded.2dm"),
    }
    result = processing.runAndLoadResults(ALG, parameters, feedback=RecordingFeedback())
    loaded = list(project.mapLayers().values())
    meshes = [m for m in loaded if isinstance(m, QgsMeshLayer)]
    vectors = [v for v in loaded if isinstance(v, QgsVectorLayer)]
    assert len(meshes) == 1 and len(vectors) == 1
    assert meshes[0].crs().authid() == UTM
    assert meshes[0].dataProvider().faceCount() == result["TRIANGLE_COUNT"]
    assert vectors[0].crs().authid() == UTM
    assert vectors[0].featureCount() == result["TRIANGLE_COUNT"]
    renderer = vectors[0].renderer()
    assert isinstance(renderer, QgsGraduatedSymbolRenderer)
    assert renderer.classAttribute() == "depth"
    assert vectors[0].labelsEnabled()
    assert vectors[0].labeling().settings().fieldName == "order"
    project.removeAllMapLayers()


FARMS = SHARED_DATA / "swellendam" / "farms_33S.shp"
SRTM = SHARED_DATA / "swellendam" / "srtm_41_19.tif"


def test_swellendam_farms_on_srtm_account_for_every_feature_with_z_in_the_dem_range():
    farms = QgsVectorLayer(str(FARMS), "farms", "ogr")
    assert farms.isValid() and farms.featureCount() == 2008
    invalid = sum(not f.geometry().isGeosValid() for f in farms.getFeatures())
    feedback = RecordingFeedback()
    result = run({"INPUT": farms, "ELEVATION_SOURCE": 3, "DEM": str(SRTM)}, feedback)
    assert_counts_add_up(result, 2008)
    repaired = f"Repaired invalid geometries of {invalid} feature"
    assert invalid == 16 and any(w.startswith(repaired) for w in feedback.warnings)
    assert result["FAILED_COUNT"] == len(feedback.errors)
    dataset = gdal.Open(str(SRTM))
    dem = dataset.GetRasterBand(1).ReadAsArray()
    low, high = float(dem.min()), float(dem.max())
    rows = triangle_rows(result)
    z = np.concatenate([corners(row)[:, 2] for row in rows])
    assert low <= z.min() and z.max() <= high
    covered: dict[int, float] = {}
    for row in rows:
        covered[row["feature_id"]] = covered.get(row["feature_id"], 0.0) + row["area_2d"]
    assert len(covered) >= 2008 - result["FAILED_COUNT"] - result["EMPTY_COUNT"]
    for farm in farms.getFeatures():
        if farm.id() in covered:
            geometry = farm.geometry()
            area = (geometry if geometry.isGeosValid() else geometry.makeValid()).area()
            assert covered[farm.id()] == pytest.approx(area, rel=1e-9), farm.id()


@pytest.mark.parametrize(("rule", "apex"), [(0, (0.0, 10.0, 1.0)), (1, (8.0, 12.0, 0.01))])
def test_apex_rule_picks_the_root_apex_of_a_pentagon_by_order_or_by_elevation(rule, apex):
    # A convex, nearly flat pentagon. Root base (0 0)-(10 0); its candidates in the paper's
    # order are (0 10 z=1), (8 12 z=0.01), (12 6 z=0.5): "first" takes the first, "elevation"
    # the one whose z is closest to the base's mean z of 0.
    wkt = "POLYGON Z((0 0 0, 10 0 0, 12 6 0.5, 8 12 0.01, 0 10 1, 0 0 0))"
    layer = polygon_layer([wkt], "PolygonZ")
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 1, "APEX_RULE": rule})
    root = next(row for row in triangle_rows(result) if row["order"] == 0)
    assert tuple(corners(root)[2]) == apex
    assert {tuple(c) for c in corners(root)[:2]} == {(0.0, 0.0, 0.0), (10.0, 0.0, 0.0)}


def test_planar_tolerance_snaps_a_slightly_warped_roof_onto_one_plane_within_the_tolerance():
    # A hexagonal roof on z = 0.1 x + 0.05 y + 5, two vertices lifted by 0.01.
    xy = [(0, 0), (8, 0), (12, 5), (8, 10), (0, 10), (-3, 5)]
    lift = [0.0, 0.01, 0.0, -0.01, 0.0, 0.0]
    ring = [(x, y, 0.1 * x + 0.05 * y + 5 + d) for (x, y), d in zip(xy, lift)]
    given = {(x, y): z for x, y, z in ring}
    wkt = "POLYGON Z((" + ", ".join(f"{x} {y} {z}" for x, y, z in [*ring, ring[0]]) + "))"
    layer = polygon_layer([wkt], "PolygonZ")
    result = run({"INPUT": layer, "ELEVATION_SOURCE": 1, "PLANAR_TOLERANCE": 0.05})
    points = np.unique(np.concatenate([corners(r) for r in triangle_rows(result)]), axis=0)
    assert len(points) == 6
    moved = [abs(z - given[(x, y)]) for x, y, z in points]
    assert max(moved) <= 0.05 and max(moved) > 0
    design = np.column_stack([points[:, 0], points[:, 1], np.ones(len(points))])
    _coefficients, residual, _rank, _sv = np.linalg.lstsq(design, points[:, 2], rcond=None)
    assert float(residual[0]) == pytest.approx(0.0, abs=1e-12)  # warped: about 1e-4
