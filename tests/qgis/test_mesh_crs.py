"""A mesh written by bsptriangulate:triangulate and opened later, as a user would (a new
QgsMeshLayer on the file, nothing set by hand), has the input's CRS and its face values: by its
path, and by the URI QGIS desktop's Add Mesh Layer gives it (``PLY:"<path>"``). Opened by its
path it has its style too (the <name>.qml beside it). PLY carries the CRS and the face values;
2DM, as MDAL reads it, carries neither a CRS nor named face values."""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsFeature,
    QgsGeometry,
    QgsMeshDatasetIndex,
    QgsMeshLayer,
    QgsProcessingContext,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)

ALG = "bsptriangulate:triangulate"
# A concave polygon with two islands (14 triangles) and a square with a triangular hole (7),
# with z
TWO_FEATURES = [
    "POLYGON Z((0 0 1, 20 0 2, 20 20 3, 10 8 4, 0 20 5, 0 0 1),"
    "(2 2 1, 6 2 1, 6 5 1, 2 5 1, 2 2 1),(14 3 2, 17 2.5 2, 15 6 2, 14 3 2))",
    "POLYGON Z((30 0 7, 40 0 8, 40 10 9, 30 10 8, 30 0 7),(33 3 8, 36 3 8, 36 6 8, 33 3 8))",
]
# A custom CRS (no authority id) must survive as well as EPSG ones.
CUSTOM = "+proj=tmerc +lat_0=0 +lon_0=21 +k=0.9996 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"

pytestmark = pytest.mark.usefixtures("provider")


def _layer(crs: QgsCoordinateReferenceSystem, offset: tuple[float, float]) -> QgsVectorLayer:
    layer = QgsVectorLayer("PolygonZ?field=name:string", "input", "memory")
    layer.setCrs(crs)
    features = []
    for index, wkt in enumerate(TWO_FEATURES):
        feature = QgsFeature(layer.fields())
        geometry = QgsGeometry.fromWkt(wkt)
        geometry.translate(*offset)
        feature.setGeometry(geometry)
        feature.setAttributes([f"f{index}"])
        features.append(feature)
    assert layer.dataProvider().addFeatures(features)
    return layer


def _run(layer: QgsVectorLayer, mesh: Path) -> dict:
    import processing

    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    parameters = {
        "INPUT": layer,
        "ELEVATION_SOURCE": 1,
        "OUTPUT_MESH": str(mesh),
        "OUTPUT_TRIANGLES": "memory:",
    }
    return processing.run(ALG, parameters, feedback=QgsProcessingFeedback(), context=context)


def _open_later(path: Path, uri: str | None = None) -> QgsMeshLayer:
    """The file opened later: a new layer (default style loaded), in no project; ``uri`` as
    QGIS desktop's Add Mesh Layer gives it, else the path."""
    assert not any(
        layer.source() == str(path) for layer in QgsProject.instance().mapLayers().values()
    )
    layer = QgsMeshLayer(uri or str(path), path.stem, "mdal")
    assert layer.isValid(), layer.error().summary()
    return layer


def _groups(layer: QgsMeshLayer) -> dict[str, np.ndarray]:
    groups = {}
    for group in layer.datasetGroupsIndexes():
        meta = layer.datasetGroupMetadata(QgsMeshDatasetIndex(group))
        count = layer.meshFaceCount() if meta.dataType() == meta.DataOnFaces else 0
        block = layer.datasetValues(QgsMeshDatasetIndex(group, 0), 0, count)
        groups[meta.name()] = np.array([block.value(i).scalar() for i in range(block.count())])
    return groups


@pytest.mark.parametrize(
    ("crs", "offset"),
    [
        (QgsCoordinateReferenceSystem("EPSG:32733"), (351_000.0, 6_230_000.0)),
        (QgsCoordinateReferenceSystem("EPSG:4326"), (20.0, -34.0)),
        (QgsCoordinateReferenceSystem.fromProj(CUSTOM), (10_000.0, -3_700_000.0)),
    ],
    ids=["utm", "geographic", "custom"],
)
def test_ply_opened_later_has_the_input_crs_and_its_face_values(tmp_path, crs, offset):
    assert crs.isValid()
    path = tmp_path / "later.ply"
    result = _run(_layer(crs, offset), path)
    assert result["TRIANGLE_COUNT"] == 21 and result["FAILED_COUNT"] == 0
    triangles = list(result["OUTPUT_TRIANGLES"].getFeatures())
    expected = sorted((t["feature_id"], t["depth"]) for t in triangles)
    for uri in (None, f'PLY:"{path}"'):
        layer = _open_later(path, uri)
        assert layer.crs() == crs, (uri, layer.crs().toWkt(), crs.toWkt())
        assert layer.meshFaceCount() == 21
        groups = _groups(layer)
        assert list(groups) == ["Bed Elevation", "feature_id", "depth"]
        assert sorted(zip(groups["feature_id"].tolist(), groups["depth"].tolist())) == expected
    header = path.read_bytes().split(b"end_header", 1)[0].decode("utf-8")
    assert sum(line.startswith("comment crs: ") for line in header.splitlines()) == 1


def test_ply_opened_later_has_its_2d_style_and_3d_renderer_from_the_sidecar(tmp_path):
    from bsptriangulate.processing_provider.outputs import ensure_3d_renderers

    path = tmp_path / "styled.ply"
    _run(_layer(QgsCoordinateReferenceSystem("EPSG:32733"), (351_000.0, 6_230_000.0)), path)
    style = ElementTree.parse(tmp_path / "styled.qml").getroot()
    advanced = style.find("renderer-3d/symbol/advanced-settings")
    assert style.find("renderer-3d").get("type") == "mesh"
    assert advanced.get("renderer-3d-enabled") == "1" and advanced.get("vertical-scale") == "1"
    assert advanced.get("texture-type") == "1"  # coloured by z, on the 2D map's ramp
    ramp = (advanced.get("min-color-ramp-shader"), advanced.get("max-color-ramp-shader"))
    assert tuple(map(float, ramp)) == (1.0, 9.0)
    assert ensure_3d_renderers()  # QGIS desktop has them from its start
    layer = _open_later(path)
    settings = layer.rendererSettings()
    assert settings.activeScalarDatasetGroup() == 0  # Bed Elevation: the vertices' z
    scalar = settings.scalarSettings(0)
    assert (scalar.classificationMinimum(), scalar.classificationMaximum()) == (1.0, 9.0)
    shader = scalar.colorRampShader()
    assert shader.colorRampItemList()[0].color.name() == "#26734d"  # the terrain ramp's low end
    assert not settings.nativeMeshSettings().isEnabled()
    renderer = layer.renderer3D()
    assert renderer is not None and renderer.type() == "mesh"


def test_2dm_opened_later_has_no_crs_and_only_z_as_mdal_reads_it(tmp_path):
    # Why PLY is the format to give users: MDAL's 2DM driver reads no CRS (no .prj either)
    # and the face values of <name>_els.dat only when added by hand.
    path = tmp_path / "later.2dm"
    result = _run(_layer(QgsCoordinateReferenceSystem("EPSG:32733"), (351_000.0, 0.0)), path)
    assert result["TRIANGLE_COUNT"] == 21
    assert (tmp_path / "later_els.dat").is_file() and (tmp_path / "later.qml").is_file()
    layer = _open_later(path)
    assert not layer.crs().isValid()
    assert list(_groups(layer)) == ["Bed Elevation"]
    assert layer.rendererSettings().activeScalarDatasetGroup() == 0
    assert layer.addDatasets(str(tmp_path / "later_els.dat"))
    assert list(_groups(layer)) == ["Bed Elevation", "feature_id", "depth"]


def test_a_cancelled_run_leaves_no_style_sidecar(tmp_path):
    class Cancelled(QgsProcessingFeedback):
        def setProgress(self, progress: float) -> None:
            super().setProgress(progress)
            self.cancel()

    import processing
    from qgis.core import QgsProcessingException

    path = tmp_path / "cancelled.ply"
    parameters = {
        "INPUT": _layer(QgsCoordinateReferenceSystem("EPSG:32733"), (0.0, 0.0)),
        "OUTPUT_MESH": str(path),
        "OUTPUT_TRIANGLES": None,
    }
    with pytest.raises(QgsProcessingException):
        processing.run(ALG, parameters, feedback=Cancelled())
    assert sorted(p.name for p in tmp_path.iterdir()) == []
