"""bsptriangulate:buildings through processing.run and qgis_process: closed solids in GLB,
glTF, OBJ and PLY, triangles with surface types, CityJSON valid against the 2.0 schemas with
every Solid closed, heights from expressions, roof Z and a DEM, per-feature failures, cancel,
and the Swellendam buildings layer (EPSG:4326, reprojected) with no feature lost."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal, osr
from qgis.core import (
    QgsFeature,
    QgsGeometry,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)

from tests import model_checks
from tests.conftest import SHARED_DATA, QgisProcess, write_geojson
from tests.model_checks import (
    assert_valid_gltf,
    cityjson_errors,
    cityjson_solids,
    cityjson_validator,
    closed_and_oriented,
    ring_edges_closed,
    signed_volume,
    trimesh_read,
)

gltf_validator = model_checks.gltf_validator  # the session fixture, used by name

ALG = "bsptriangulate:buildings"
UTM = "EPSG:32733"
X0, Y0 = 351_000.0, 6_220_000.0
SQUARE_WITH_COURT = (
    f"POLYGON(({X0} {Y0}, {X0 + 20} {Y0}, {X0 + 20} {Y0 + 20}, {X0} {Y0 + 20}, {X0} {Y0}),"
    f"({X0 + 5} {Y0 + 5}, {X0 + 5} {Y0 + 15}, {X0 + 15} {Y0 + 15}, {X0 + 15} {Y0 + 5},"
    f" {X0 + 5} {Y0 + 5}))"
)
ELL = (
    f"POLYGON(({X0 + 40} {Y0}, {X0 + 52} {Y0}, {X0 + 52} {Y0 + 5}, {X0 + 45} {Y0 + 5},"
    f" {X0 + 45} {Y0 + 14}, {X0 + 40} {Y0 + 14}, {X0 + 40} {Y0}))"
)
TWO_PARTS = (
    f"MULTIPOLYGON((({X0} {Y0 + 40}, {X0 + 8} {Y0 + 40}, {X0 + 8} {Y0 + 48}, {X0} {Y0 + 48},"
    f" {X0} {Y0 + 40})),(({X0 + 20} {Y0 + 40}, {X0 + 26} {Y0 + 40}, {X0 + 26} {Y0 + 46},"
    f" {X0 + 20} {Y0 + 40})))"
)
BOW_TIE = f"POLYGON(({X0} {Y0 - 30}, {X0 + 10} {Y0 - 20}, {X0 + 10} {Y0 - 30}, {X0} {Y0 - 20}, {X0} {Y0 - 30}))"  # noqa: E501
AREAS = {1: 400.0 - 100.0, 2: 12 * 5 + 5 * 9, 3: 64.0 + 18.0}

pytestmark = pytest.mark.usefixtures("provider")


class RecordingFeedback(QgsProcessingFeedback):
    def __init__(self) -> None:
        super().__init__()
        self.errors: list[str] = []
        self.infos: list[str] = []
        self.progress: list[float] = []
        self.progressChanged.connect(self.progress.append)

    def reportError(self, error: str, fatalError: bool = False) -> None:  # noqa: N803
        self.errors.append(error)

    def pushInfo(self, info: str) -> None:
        self.infos.append(info)


def layer_of(wkts: list[str | None], crs: str = UTM, geometry: str = "MultiPolygon"):
    layer = QgsVectorLayer(
        f"{geometry}?crs={crs}&field=name:string&field=height:double&field=base:double",
        "footprints",
        "memory",
    )
    features = []
    for index, wkt in enumerate(wkts):
        feature = QgsFeature(layer.fields())
        feature.setAttributes([f"b{index + 1}", 3.0 * (index + 1), 100.0 + index])
        if wkt is not None:
            feature.setGeometry(QgsGeometry.fromWkt(wkt))
        features.append(feature)
    assert layer.dataProvider().addFeatures(features)
    return layer


def run(parameters: dict, feedback: QgsProcessingFeedback | None = None) -> dict:
    import processing

    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    return processing.run(
        ALG, parameters, feedback=feedback or RecordingFeedback(), context=context
    )


def triangles_of(result: dict) -> list[QgsFeature]:
    return list(result["OUTPUT_TRIANGLES"].getFeatures())


def solid_arrays(rows: list[QgsFeature], building: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (merged by coordinates) and triangles of one building's triangle features."""
    corners = []
    for row in rows:
        if row["building_id"] != building:
            continue
        ring = row.geometry().constGet().exteriorRing()
        corners.append([(ring.xAt(i), ring.yAt(i), ring.zAt(i)) for i in range(3)])
    corners = np.array(corners).reshape(-1, 3)
    vertices, inverse = np.unique(corners, axis=0, return_inverse=True)
    return vertices, inverse.reshape(-1, 3)


def test_glb_solids_are_closed_with_the_volume_of_area_times_height(
    tmp_path: Path, gltf_validator
) -> None:
    layer = layer_of([SQUARE_WITH_COURT, ELL, TWO_PARTS])
    feedback = RecordingFeedback()
    result = run(
        {
            "INPUT": layer,
            "HEIGHT": '"height"',
            "GROUND": 3,
            "GROUND_EXPRESSION": '"base"',
            "OUTPUT_MESH": str(tmp_path / "b.glb"),
            "OUTPUT_TRIANGLES": "memory:",
        },
        feedback,
    )
    assert (result["FEATURE_COUNT"], result["BUILT_COUNT"]) == (3, 3)
    assert (result["FAILED_COUNT"], result["EMPTY_COUNT"]) == (0, 0)
    rows = triangles_of(result)
    assert result["TRIANGLE_COUNT"] == len(rows)
    assert {row["surface"] for row in rows} == {"roof", "wall", "floor"}
    for fid, area in AREAS.items():
        vertices, triangles = solid_arrays(rows, fid)
        assert closed_and_oriented(triangles), fid
        height = 3.0 * fid
        assert signed_volume(vertices, triangles) == pytest.approx(area * height, rel=1e-9)
        floor = [r for r in rows if r["building_id"] == fid and r["surface"] == "floor"]
        z = floor[0].geometry().constGet().exteriorRing().zAt(0)
        assert z == 100.0 + fid - 1
    assert {row["part"] for row in rows if row["building_id"] == 3} == {0, 1}
    assert_valid_gltf(gltf_validator, tmp_path / "b.glb")
    mesh = trimesh_read(tmp_path / "b.glb")
    assert len(mesh.faces) == len(rows)
    mesh.merge_vertices()  # glTF faces have their own vertices
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(sum(a * 3.0 * f for f, a in AREAS.items()), rel=1e-6)
    assert feedback.progress and feedback.progress[-1] == 100


@pytest.mark.parametrize("name", ["b.gltf", "b.obj", "b.ply"])
def test_other_model_formats_read_back_with_the_same_faces(
    tmp_path: Path, name: str, gltf_validator
) -> None:
    layer = layer_of([SQUARE_WITH_COURT, ELL])
    result = run({"INPUT": layer, "HEIGHT": "7.5", "OUTPUT_MESH": str(tmp_path / name)})
    assert result["BUILT_COUNT"] == 2
    path = tmp_path / name
    assert path.is_file()
    assert not list(tmp_path.glob(".*partial*"))
    if name.endswith(".gltf"):
        assert (tmp_path / "b.bin").is_file()
        assert_valid_gltf(gltf_validator, path)
    if name.endswith(".obj"):
        assert {p.name for p in tmp_path.iterdir()} == {"b.obj", "b.origin.json", "b.prj"}
        assert "g building_id_1 surface_roof" in path.read_text()
    mesh = trimesh_read(path)
    assert len(mesh.faces) == result["TRIANGLE_COUNT"]
    mesh.merge_vertices()
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx((AREAS[1] + AREAS[2]) * 7.5, rel=1e-6)


def test_cityjson_validates_and_every_solid_is_closed(tmp_path: Path) -> None:
    layer = layer_of([SQUARE_WITH_COURT, ELL, TWO_PARTS])
    path = tmp_path / "b.city.json"
    result = run({"INPUT": layer, "HEIGHT": "6", "OUTPUT_MESH": "", "OUTPUT_CITYJSON": str(path)})
    assert result["OUTPUT_CITYJSON"] == str(path)
    document = json.loads(path.read_text())
    assert list(cityjson_validator().iter_errors(document)) == []
    assert document["metadata"]["referenceSystem"].endswith("/EPSG/0/32733")
    assert document["CityObjects"]["1"]["attributes"]["name"] == "b1"
    assert document["CityObjects"]["3"]["children"] == ["3-1", "3-2"]
    shells = cityjson_solids(document)
    assert [name for name, _ in shells] == ["1", "2", "3-1", "3-2"]
    assert all(ring_edges_closed(rings) for _name, rings in shells)


def test_roof_z_of_the_geometry_and_a_dem_ground_per_vertex(tmp_path: Path) -> None:
    dem = tmp_path / "dem.tif"
    write_sloped_dem(dem)
    z = 150.0
    wkt = (
        f"POLYGONZ(({X0} {Y0} {z}, {X0 + 20} {Y0} {z}, {X0 + 20} {Y0 + 20} {z},"
        f" {X0} {Y0 + 20} {z}, {X0} {Y0} {z}))"
    )
    layer = layer_of([wkt], geometry="PolygonZ")
    result = run(
        {
            "INPUT": layer,
            "HEIGHT_SOURCE": 1,
            "GROUND": 1,
            "DEM": str(dem),
            "OUTPUT_TRIANGLES": "memory:",
            "OUTPUT_MESH": "",
        }
    )
    assert result["BUILT_COUNT"] == 1
    rows = triangles_of(result)
    vertices, triangles = solid_arrays(rows, 1)
    assert closed_and_oriented(triangles)
    low = vertices[vertices[:, 2] < z]
    # the DEM is the plane z = 100 + 0.1 (x - X0): the floor follows it
    np.testing.assert_allclose(low[:, 2], 100.0 + 0.1 * (low[:, 0] - X0), atol=1e-6)
    assert signed_volume(vertices, triangles) == pytest.approx(400.0 * (150 - 101.0), rel=1e-9)


def test_dem_lowest_ground_gives_a_flat_floor(tmp_path: Path) -> None:
    dem = tmp_path / "dem.tif"
    write_sloped_dem(dem)
    result = run(
        {
            "INPUT": layer_of([ELL]),
            "HEIGHT": "5",
            "GROUND": 0,
            "DEM": str(dem),
            "OUTPUT_TRIANGLES": "memory:",
            "OUTPUT_MESH": "",
        }
    )
    vertices, triangles = solid_arrays(triangles_of(result), 1)
    lowest = 100.0 + 0.1 * 40
    assert sorted(set(vertices[:, 2].round(9))) == [lowest, lowest + 5]
    assert signed_volume(vertices, triangles) == pytest.approx(AREAS[2] * 5, rel=1e-9)


def write_sloped_dem(path: Path) -> None:
    """A DEM over the test footprints: z = 100 + 0.1 (x - X0) at cell centres, 1 m cells."""
    cols, rows = 200, 200
    left, top = X0 - 50.0, Y0 + 150.0
    x = left + 0.5 + np.arange(cols)
    data = np.tile(100.0 + 0.1 * (x - X0), (rows, 1)).astype(np.float32)
    dataset = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Float32)
    dataset.SetGeoTransform((left, 1.0, 0.0, top, 0.0, -1.0))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32733)
    dataset.SetProjection(srs.ExportToWkt())
    dataset.GetRasterBand(1).WriteArray(data)
    dataset = None


def test_failures_are_reported_per_feature_and_counted() -> None:
    layer = layer_of([SQUARE_WITH_COURT, BOW_TIE, None, ELL])
    feedback = RecordingFeedback()
    result = run(
        {
            "INPUT": layer,
            "HEIGHT": "if(\"name\" = 'b4', -2, 5)",
            "INVALID_POLYGONS": 1,
            "OUTPUT_TRIANGLES": "memory:",
            "OUTPUT_MESH": "",
        },
        feedback,
    )
    assert result["FEATURE_COUNT"] == 4
    assert (result["BUILT_COUNT"], result["FAILED_COUNT"], result["EMPTY_COUNT"]) == (1, 2, 1)
    assert [e.split(":")[0] for e in feedback.errors] == ["Feature 2", "Feature 4"]
    assert "above the ground" in feedback.errors[1]
    assert {row["building_id"] for row in triangles_of(result)} == {1}


def test_height_expression_null_fails_the_feature() -> None:
    feedback = RecordingFeedback()
    result = run(
        {"INPUT": layer_of([ELL]), "HEIGHT": "NULL", "OUTPUT_TRIANGLES": "memory:"}, feedback
    )
    assert result["FAILED_COUNT"] == 1 and "NULL" in feedback.errors[0]


def test_nothing_to_write_and_bad_extension_are_refused(tmp_path: Path) -> None:
    with pytest.raises(QgsProcessingException):
        run({"INPUT": layer_of([ELL]), "OUTPUT_MESH": ""})
    with pytest.raises(QgsProcessingException):
        run({"INPUT": layer_of([ELL]), "OUTPUT_MESH": str(tmp_path / "b.2dm")})


class CancelAfterFirstBatch(RecordingFeedback):
    def __init__(self) -> None:
        super().__init__()
        self.progressChanged.connect(lambda _value: self.cancel())


def test_cancel_leaves_no_output(tmp_path: Path) -> None:
    from bsptriangulate.processing_provider.buildings_algorithm import BuildingsAlgorithm

    wkts = [ELL] * 5
    original = BuildingsAlgorithm.BATCH_FEATURES
    BuildingsAlgorithm.BATCH_FEATURES = 2
    try:
        with pytest.raises(QgsProcessingException, match="Cancelled"):
            run(
                {
                    "INPUT": layer_of(wkts),
                    "OUTPUT_MESH": str(tmp_path / "b.glb"),
                    "OUTPUT_CITYJSON": str(tmp_path / "b.city.json"),
                    "OUTPUT_TRIANGLES": str(tmp_path / "t.gpkg"),
                },
                CancelAfterFirstBatch(),
            )
    finally:
        BuildingsAlgorithm.BATCH_FEATURES = original
    assert list(tmp_path.iterdir()) == []


def test_swellendam_buildings_with_dem_ground_lose_no_feature(
    tmp_path: Path, gltf_validator
) -> None:
    source = SHARED_DATA / "swellendam" / "training_data.gpkg"
    dem = SHARED_DATA / "swellendam" / "srtm_41_19.tif"
    if not source.is_file():
        pytest.skip(f"{source} is not there")
    feedback = RecordingFeedback()
    city = tmp_path / "swellendam.city.json"
    result = run(
        {
            "INPUT": f"{source}|layername=buildings",
            "HEIGHT": "6",
            "GROUND": 0,
            "DEM": str(dem),
            "OUTPUT_MESH": str(tmp_path / "swellendam.glb"),
            "OUTPUT_CITYJSON": str(city),
        },
        feedback,
    )
    read = result["FEATURE_COUNT"]
    assert read == 4708
    assert result["BUILT_COUNT"] + result["FAILED_COUNT"] + result["EMPTY_COUNT"] == read
    assert result["BUILT_COUNT"] >= 4700
    assert any("EPSG:32733" in info and "reprojected" in info for info in feedback.infos)
    mesh = trimesh_read(tmp_path / "swellendam.glb")
    assert len(mesh.faces) == result["TRIANGLE_COUNT"]
    assert_valid_gltf(gltf_validator, tmp_path / "swellendam.glb")
    document = json.loads(city.read_text())
    assert cityjson_errors(document) == []
    shells = cityjson_solids(document)
    assert len({name.split("-")[0] for name, _ in shells}) == result["BUILT_COUNT"]
    assert all(ring_edges_closed(rings) for _name, rings in shells)


def test_qgis_process_lists_and_runs_buildings(
    qgis_process: QgisProcess, qgis_process_list: dict, tmp_path: Path
) -> None:
    algorithms = qgis_process_list["providers"]["bsptriangulate"]["algorithms"]
    assert ALG in algorithms
    ring = [(X0, Y0), (X0 + 10, Y0), (X0 + 10, Y0 + 6), (X0, Y0 + 6), (X0, Y0)]
    source = write_geojson(tmp_path / "f.geojson", [[ring]], 32733)
    mesh = tmp_path / "f.glb"
    results = qgis_process.run_json(
        "run", ALG, "--", f"INPUT={source}", "HEIGHT=4", f"OUTPUT_MESH={mesh}"
    )["results"]
    assert (results["FEATURE_COUNT"], results["BUILT_COUNT"]) == (1, 1)
    assert results["TRIANGLE_COUNT"] == 2 + 8 + 2
    read = trimesh_read(mesh)
    read.merge_vertices()
    assert read.is_watertight and read.volume == pytest.approx(240.0, rel=1e-6)


@pytest.fixture()
def dialog(qgis_parent, monkeypatch):
    from processing.gui import ParametersPanel
    from processing.gui.AlgorithmDialog import AlgorithmDialog
    from qgis.core import QgsApplication

    layer = layer_of([ELL])
    QgsProject.instance().addMapLayer(layer)
    # pytest-qgis's stand-in iface has no browserModel(); the panel skips iface when None.
    monkeypatch.setattr(ParametersPanel, "iface", None)
    algorithm = QgsApplication.processingRegistry().createAlgorithmById(ALG)
    widget = AlgorithmDialog(algorithm, parent=qgis_parent)
    yield widget
    widget.close()
    widget.deleteLater()
    QgsProject.instance().removeMapLayer(layer.id())


def test_dialog_has_a_widget_per_parameter_and_the_documented_defaults(dialog) -> None:
    panel = dialog.mainWidget()
    names = {p.name() for p in dialog.algorithm().parameterDefinitions()}
    assert set(panel.wrappers) == names
    parameters = dialog.createProcessingParameters()
    assert parameters["HEIGHT_SOURCE"] == 0 and parameters["HEIGHT"] == "10"
    assert parameters["GROUND"] == 2 and parameters["GROUND_VALUE"] == 0.0
    assert parameters["ROOF_PLANAR_TOLERANCE"] == 0.0 and parameters["APEX_RULE"] == 0


def test_buildings_run_as_a_step_of_a_model(tmp_path: Path) -> None:
    import processing
    from qgis.core import (
        QgsProcessingModelAlgorithm,
        QgsProcessingModelChildAlgorithm,
        QgsProcessingModelChildParameterSource,
        QgsProcessingModelOutput,
        QgsProcessingModelParameter,
        QgsProcessingParameterFeatureSource,
    )

    model = QgsProcessingModelAlgorithm("footprints to glb", "tests")
    model.addModelParameter(
        QgsProcessingParameterFeatureSource("footprints", "Footprints"),
        QgsProcessingModelParameter("footprints"),
    )
    child = QgsProcessingModelChildAlgorithm(ALG)
    child.setChildId("buildings")
    child.addParameterSources(
        "INPUT", [QgsProcessingModelChildParameterSource.fromModelParameter("footprints")]
    )
    child.addParameterSources(
        "HEIGHT", [QgsProcessingModelChildParameterSource.fromStaticValue("8")]
    )
    output = QgsProcessingModelOutput("model", "3D model")
    output.setChildOutputName("OUTPUT_MESH")
    child.setModelOutputs({"model": output})
    model.addChildAlgorithm(child)
    path = tmp_path / "m.glb"
    result = processing.run(
        model, {"footprints": layer_of([ELL, SQUARE_WITH_COURT]), "buildings:model": str(path)}
    )
    # the key of a model's output differs between QGIS versions: find it by its value
    assert path.exists() and str(path) in {str(value) for value in result.values()}, result
    mesh = trimesh_read(path)
    mesh.merge_vertices()
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx((AREAS[1] + AREAS[2]) * 8, rel=1e-6)
