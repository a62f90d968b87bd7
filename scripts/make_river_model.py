"""Write tests/data/river_mesh.model3: a graphical-modeler model that reprojects river lines to
UTM 33S, buffers them and triangulates the buffers over a DEM into a 3D mesh.

Run with the dev venv: .venv/bin/python scripts/make_river_model.py
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("QGIS_CUSTOM_CONFIG_PATH", tempfile.mkdtemp(prefix="bsptri-model-"))

from qgis.core import (
    QgsApplication,
    QgsCoordinateReferenceSystem,
    QgsProcessing,
    QgsProcessingModelAlgorithm,
    QgsProcessingModelChildAlgorithm,
    QgsProcessingModelChildParameterSource,
    QgsProcessingModelOutput,
    QgsProcessingModelParameter,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
)
from qgis.PyQt.QtCore import QPointF

ROOT = Path(__file__).resolve().parent.parent
TARGET = ROOT / "tests" / "data" / "river_mesh.model3"
UTM_33S = "EPSG:32733"


def child(
    model: QgsProcessingModelAlgorithm, child_id: str, algorithm_id: str, y: float
) -> QgsProcessingModelChildAlgorithm:
    step = QgsProcessingModelChildAlgorithm(algorithm_id)
    step.setChildId(child_id)
    step.setDescription(child_id.replace("_", " ").capitalize())
    step.setPosition(QPointF(400, y))
    return step


def static(value) -> list[QgsProcessingModelChildParameterSource]:
    return [QgsProcessingModelChildParameterSource.fromStaticValue(value)]


def from_model(name: str) -> list[QgsProcessingModelChildParameterSource]:
    return [QgsProcessingModelChildParameterSource.fromModelParameter(name)]


def from_child(child_id: str, output: str) -> list[QgsProcessingModelChildParameterSource]:
    return [QgsProcessingModelChildParameterSource.fromChildOutput(child_id, output)]


def add_input(model: QgsProcessingModelAlgorithm, definition, y: float) -> None:
    component = QgsProcessingModelParameter(definition.name())
    component.setPosition(QPointF(100, y))
    model.addModelParameter(definition, component)


def build_model() -> QgsProcessingModelAlgorithm:
    """The model: rivers -> reproject to UTM 33S -> buffer -> triangulate over the DEM."""
    model = QgsProcessingModelAlgorithm("River mesh", "BSP Triangulate examples")
    model.setHelpContent(
        {
            "ALG_DESC": "Buffers river lines in UTM 33S and triangulates the buffers into a 3D "
            "mesh whose vertices take their elevation from a DEM; apexes are chosen by "
            "elevation, as for streams running over terrain."
        }
    )
    add_input(
        model,
        QgsProcessingParameterFeatureSource(
            "rivers", "River lines", [QgsProcessing.SourceType.TypeVectorLine]
        ),
        100,
    )
    add_input(model, QgsProcessingParameterRasterLayer("dem", "DEM"), 200)
    add_input(
        model,
        QgsProcessingParameterNumber(
            "buffer_distance",
            "Buffer distance (m)",
            QgsProcessingParameterNumber.Type.Double,
            100.0,
            minValue=0.1,
        ),
        300,
    )

    reproject = child(model, "reproject", "native:reprojectlayer", 100)
    reproject.addParameterSources("INPUT", from_model("rivers"))
    reproject.addParameterSources("TARGET_CRS", static(QgsCoordinateReferenceSystem(UTM_33S)))
    model.addChildAlgorithm(reproject)

    buffer = child(model, "buffer", "native:buffer", 200)
    buffer.addParameterSources("INPUT", from_child("reproject", "OUTPUT"))
    buffer.addParameterSources("DISTANCE", from_model("buffer_distance"))
    for name, value in (
        ("SEGMENTS", 5),
        ("END_CAP_STYLE", 0),
        ("JOIN_STYLE", 0),
        ("MITER_LIMIT", 2.0),
        ("DISSOLVE", False),
    ):
        buffer.addParameterSources(name, static(value))
    model.addChildAlgorithm(buffer)

    triangulate = child(model, "triangulate", "bsptriangulate:triangulate", 300)
    triangulate.addParameterSources("INPUT", from_child("buffer", "OUTPUT"))
    triangulate.addParameterSources("ELEVATION_SOURCE", static(3))
    triangulate.addParameterSources("DEM", from_model("dem"))
    triangulate.addParameterSources("DEM_BAND", static(1))
    triangulate.addParameterSources("APEX_RULE", static(1))
    outputs = {}
    for output_name, parameter in (("mesh", "OUTPUT_MESH"), ("triangles", "OUTPUT_TRIANGLES")):
        output = QgsProcessingModelOutput(output_name)
        output.setChildId("triangulate")
        output.setChildOutputName(parameter)
        output.setDescription(f"River {output_name}")
        outputs[output_name] = output
    triangulate.setModelOutputs(outputs)
    model.addChildAlgorithm(triangulate)
    return model


def main() -> None:
    app = QgsApplication([], False)
    app.initQgis()
    sys.path[:0] = [str(ROOT), str(Path(app.pkgDataPath()) / "python" / "plugins")]
    from processing.core.Processing import Processing

    Processing.initialize()
    from tests.conftest import load_plugin_package

    plugin = load_plugin_package().classFactory(None)
    plugin.initProcessing()
    model = build_model()
    TARGET.parent.mkdir(parents=True, exist_ok=True)
    if not model.toFile(str(TARGET)):
        raise SystemExit(f"cannot write {TARGET}")
    print(TARGET)


if __name__ == "__main__":
    main()
