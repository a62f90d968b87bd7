"""The layers bsptriangulate:triangulate loads into the project: the triangles' legend is their
map (one classification, the same in the Layers panel and the renderer), labels only where they
can be read, and the mesh with a 2D style and a 3D renderer."""

from __future__ import annotations

import pytest
from qgis.core import (
    QgsFeature,
    QgsGeometry,
    QgsGraduatedSymbolRenderer,
    QgsLayerTreeModel,
    QgsMeshLayer,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)
from qgis.PyQt.QtCore import Qt

from tests.conftest import SHARED_DATA

ALG = "bsptriangulate:triangulate"
FARMS = SHARED_DATA / "swellendam" / "farms_33S.shp"

pytestmark = pytest.mark.usefixtures("provider")


def _outputs():
    from bsptriangulate.processing_provider import outputs

    return outputs


def test_depth_classes_double_up_to_the_deepest_level():
    depth_classes = _outputs().depth_classes
    assert depth_classes(0) == [(0, 0)]
    assert depth_classes(1) == [(0, 0), (1, 1)]
    assert depth_classes(5) == [(0, 0), (1, 1), (2, 3), (4, 5)]
    assert depth_classes(271)[-3:] == [(64, 127), (128, 255), (256, 271)]


def test_label_scale_is_where_a_typical_triangle_is_about_12_mm_wide():
    label_scale = _outputs().label_scale
    assert label_scale(100.0) == 5_000.0  # 100 m / 12 mm = 1:8333, rounded down
    assert label_scale(3.0) == 200.0
    assert label_scale(None) == label_scale(float("nan")) == _outputs().DEFAULT_LABEL_SCALE


def _legend_labels(project: QgsProject, layer) -> list[str]:
    """What the Layers panel shows under the layer."""
    model = QgsLayerTreeModel(project.layerTreeRoot())
    node = project.layerTreeRoot().findLayer(layer.id())
    return [n.data(Qt.DisplayRole) for n in model.layerLegendNodes(node)]


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    """The farms run as a desktop user runs it: runAndLoadResults, PLY mesh and triangles."""
    import processing

    project = QgsProject.instance()
    project.removeAllMapLayers()
    farms = QgsVectorLayer(str(FARMS), "farms", "ogr")
    assert farms.isValid()
    mesh = tmp_path_factory.mktemp("styles") / "farms.ply"
    parameters = {"INPUT": farms, "OUTPUT_MESH": str(mesh), "OUTPUT_TRIANGLES": "TEMPORARY_OUTPUT"}
    with pytest.MonkeyPatch.context() as patch:
        # QGIS 3.40+ lays out loaded layers in iface's layer tree view when there is an iface;
        # pytest-qgis's stand-in iface has no real view: load into the project's tree alone
        from processing.gui import Postprocessing

        patch.setattr(Postprocessing, "iface", None, raising=False)
        result = processing.runAndLoadResults(ALG, parameters, feedback=QgsProcessingFeedback())
    layers = list(project.mapLayers().values())
    triangles = next(layer for layer in layers if isinstance(layer, QgsVectorLayer))
    meshes = [layer for layer in layers if isinstance(layer, QgsMeshLayer)]
    yield project, result, triangles, meshes
    project.removeAllMapLayers()


def test_triangle_legend_and_renderer_are_the_same_doubling_depth_classes(loaded):
    project, result, triangles, _meshes = loaded
    assert triangles.featureCount() == result["TRIANGLE_COUNT"] > 10_000
    renderer = triangles.renderer()
    assert isinstance(renderer, QgsGraduatedSymbolRenderer)
    assert renderer.classAttribute() == "depth"
    depths = [f["depth"] for f in triangles.getFeatures()]
    classes = _outputs().depth_classes(max(depths))
    ranges = renderer.ranges()
    assert [(r.lowerValue(), r.upperValue()) for r in ranges] == classes
    assert _legend_labels(project, triangles) == [r.label() for r in ranges]
    # every triangle in exactly one class, and no class holding nearly all of them
    counts = [sum(low <= d <= high for d in depths) for low, high in classes]
    assert sum(counts) == len(depths)
    assert max(counts) < 0.5 * len(depths)
    colours = {r.symbol().color().name() for r in ranges}
    assert len(colours) == len(ranges)


def test_triangle_labels_only_at_readable_scales_inside_their_triangle(loaded):
    _project, _result, triangles, _meshes = loaded
    assert triangles.labelsEnabled()
    settings = triangles.labeling().settings()
    assert settings.fieldName == "order"
    assert settings.scaleVisibility
    # farm triangles are tens to hundreds of metres wide: labels from about 1:1000 to 1:10 000
    assert 500 <= settings.minimumScale <= 10_000 and settings.maximumScale == 0
    assert settings.fitInPolygonOnly and not settings.displayAll


def test_loaded_mesh_has_the_input_crs_a_2d_style_and_a_3d_renderer(loaded):
    _project, _result, _triangles, meshes = loaded
    assert len(meshes) == 1
    mesh = meshes[0]
    assert mesh.crs().authid() == "EPSG:32733"
    settings = mesh.rendererSettings()
    assert settings.activeScalarDatasetGroup() == 0
    scalar = settings.scalarSettings(0)
    # z = 0 everywhere (no elevation source): the ramp still spans a range
    assert (scalar.classificationMinimum(), scalar.classificationMaximum()) == (0.0, 1.0)
    assert scalar.colorRampShader().colorRampItemList()[0].color.name() == "#26734d"
    renderer = mesh.renderer3D()
    assert renderer is not None and renderer.type() == "mesh"


def test_style_file_alone_gives_the_same_classification_kind(tmp_path):
    # A user applying styles/triangles.qml by hand gets doubling classes and scale-limited
    # labels too (with fixed bounds: the post-processor fits them to the data).
    layer = QgsVectorLayer("Polygon?field=depth:integer&field=order:integer", "t", "memory")
    feature = QgsFeature(layer.fields())
    feature.setGeometry(QgsGeometry.fromWkt("POLYGON((0 0, 1 0, 0 1, 0 0))"))
    feature.setAttributes([3, 0])
    layer.dataProvider().addFeatures([feature])
    _message, ok = layer.loadNamedStyle(str(_outputs().STYLE_PATH))
    assert ok
    bounds = [(r.lowerValue(), r.upperValue()) for r in layer.renderer().ranges()]
    assert bounds[:4] == [(0, 0), (1, 1), (2, 3), (4, 7)]
    settings = layer.labeling().settings()
    assert settings.scaleVisibility and settings.minimumScale > 0
    assert settings.fitInPolygonOnly and not settings.displayAll
