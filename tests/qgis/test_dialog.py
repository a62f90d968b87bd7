"""The toolbox dialog of bsptriangulate:triangulate builds offscreen with a widget per
parameter and turns its widgets' values back into the algorithm's parameters."""

from __future__ import annotations

import pytest
from qgis.core import (
    QgsApplication,
    QgsFeature,
    QgsGeometry,
    QgsProcessingContext,
    QgsProject,
    QgsVectorLayer,
)

ALG = "bsptriangulate:triangulate"


pytestmark = pytest.mark.usefixtures("provider")


@pytest.fixture()
def polygons():
    """A polygon layer in the project, so the dialog's source widget has something to pick."""
    layer = QgsVectorLayer("Polygon?crs=EPSG:32733&field=height:double", "parcels", "memory")
    feature = QgsFeature(layer.fields())
    feature.setAttributes([12.5])
    feature.setGeometry(QgsGeometry.fromWkt("POLYGON((0 0, 10 0, 10 10, 0 0))"))
    layer.dataProvider().addFeatures([feature])
    QgsProject.instance().addMapLayer(layer)
    yield layer
    QgsProject.instance().removeMapLayer(layer.id())


@pytest.fixture()
def dialog(polygons, qgis_parent, monkeypatch):
    from processing.gui import ParametersPanel
    from processing.gui.AlgorithmDialog import AlgorithmDialog

    # pytest-qgis's stand-in iface has no browserModel(); the panel skips iface when None.
    monkeypatch.setattr(ParametersPanel, "iface", None)

    algorithm = QgsApplication.processingRegistry().createAlgorithmById(ALG)
    assert algorithm is not None
    widget = AlgorithmDialog(algorithm, parent=qgis_parent)
    yield widget
    widget.close()
    widget.deleteLater()


def test_dialog_has_a_widget_for_every_parameter(dialog):
    panel = dialog.mainWidget()
    names = {p.name() for p in dialog.algorithm().parameterDefinitions()}
    assert set(panel.wrappers) == names
    for name, wrapper in panel.wrappers.items():
        assert wrapper.wrappedWidget() is not None, name


def test_dialog_defaults_give_the_documented_default_parameters(dialog, polygons):
    parameters = dialog.createProcessingParameters()
    assert parameters["INPUT"] in (polygons.id(), polygons.source(), polygons)
    expected = {
        "ELEVATION_SOURCE": 4,
        "DEM_INTERPOLATION": 0,
        "DEM_NODATA": 0,
        "APEX_RULE": 0,
        "INVALID_POLYGONS": 0,
        "Z_OFFSET": 0.0,
        "Z_SCALE": 1.0,
        "MAX_SEGMENT_LENGTH": 0.0,
        "PLANAR_TOLERANCE": 0.0,
    }
    assert {name: parameters[name] for name in expected} == expected
    assert "OUTPUT_TREE" not in parameters or parameters["OUTPUT_TREE"] is None


def project_context() -> QgsProcessingContext:
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    return context


def test_values_set_in_the_dialog_become_the_run_parameters(dialog):
    context = project_context()
    panel = dialog.mainWidget()
    panel.wrappers["ELEVATION_SOURCE"].setParameterValue(2, context)
    panel.wrappers["Z_EXPRESSION"].setParameterValue('"height" + 1', context)
    panel.wrappers["APEX_RULE"].setParameterValue(1, context)
    parameters = dialog.createProcessingParameters()
    assert parameters["ELEVATION_SOURCE"] == 2
    assert parameters["Z_EXPRESSION"] == '"height" + 1'
    assert parameters["APEX_RULE"] == 1
    algorithm = dialog.algorithm()
    ok, message = algorithm.checkParameterValues(parameters, context)
    assert ok, message


def test_dialog_refuses_a_dem_source_without_a_dem(dialog):
    context = project_context()
    panel = dialog.mainWidget()
    panel.wrappers["ELEVATION_SOURCE"].setParameterValue(3, context)
    parameters = dialog.createProcessingParameters()
    ok, message = dialog.algorithm().checkParameterValues(parameters, context)
    assert not ok and "DEM" in message
