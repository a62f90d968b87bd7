"""bsptriangulate:triangulate as typed in the QGIS Python console: help text, file paths in and
out, selected features only, a bare field name as Z expression, and cancelling mid-run."""

from __future__ import annotations

from pathlib import Path

import pytest
from osgeo import ogr, osr
from qgis.core import (
    QgsApplication,
    QgsProcessingFeatureSourceDefinition,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)

ALG = "bsptriangulate:triangulate"


pytestmark = pytest.mark.usefixtures("provider")


def write_gpkg(path: Path, wkts: list[str]) -> Path:
    """A GeoPackage polygon layer ``parcels`` (EPSG:32733) with a ``height`` field."""
    dataset = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32733)
    layer = dataset.CreateLayer("parcels", srs, ogr.wkbPolygon)
    layer.CreateField(ogr.FieldDefn("height", ogr.OFTReal))
    for index, wkt in enumerate(wkts):
        feature = ogr.Feature(layer.GetLayerDefn())
        feature.SetField("height", 5.0 * (index + 1))
        feature.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
        layer.CreateFeature(feature)
    dataset = None
    return path


def small_triangles(count: int) -> list[str]:
    return [f"POLYGON(({i * 10} 0, {i * 10 + 5} 0, {i * 10} 5, {i * 10} 0))" for i in range(count)]


SQUARE_WITH_HOLE = "POLYGON((0 0, 10 0, 10 10, 0 10, 0 0), (3 3, 7 3, 5 6, 3 3))"


def test_algorithm_help_names_every_parameter_and_output(capsys):
    import processing

    processing.algorithmHelp(ALG)
    text = capsys.readouterr().out
    algorithm = QgsApplication.processingRegistry().algorithmById(ALG)
    for definition in [*algorithm.parameterDefinitions(), *algorithm.outputDefinitions()]:
        assert definition.name() in text


def test_geopackage_paths_in_and_out_keep_the_source_fid_out_of_the_primary_key(tmp_path: Path):
    import processing

    source = write_gpkg(tmp_path / "parcels.gpkg", [SQUARE_WITH_HOLE, *small_triangles(2)])
    result = processing.run(
        ALG,
        {
            "INPUT": str(source),
            "OUTPUT_TRIANGLES": str(tmp_path / "triangles.gpkg"),
            "OUTPUT_TREE": str(tmp_path / "tree.gpkg"),
            "OUTPUT_MESH": str(tmp_path / "parcels.2dm"),
        },
    )
    assert result["OUTPUT_MESH"] == str(tmp_path / "parcels.2dm")
    assert result["TRIANGLE_COUNT"] == (4 + 3 + 2 * 1 - 2) + 1 + 1
    triangles = QgsVectorLayer(result["OUTPUT_TRIANGLES"], "triangles", "ogr")
    assert triangles.featureCount() == result["TRIANGLE_COUNT"]
    rows = list(triangles.getFeatures())
    assert {row["src_fid"] for row in rows} == {1, 2, 3}
    assert all(row["src_fid"] == row["feature_id"] for row in rows)
    tree = QgsVectorLayer(result["OUTPUT_TREE"], "tree", "ogr")
    assert tree.featureCount() == result["TRIANGLE_COUNT"] - 3  # one root per polygon


def test_selected_features_only_reads_just_the_selection(tmp_path: Path):
    import processing

    layer = QgsVectorLayer(str(write_gpkg(tmp_path / "p.gpkg", small_triangles(5))), "p", "ogr")
    QgsProject.instance().addMapLayer(layer)
    try:
        layer.selectByIds([2, 4])
        source = QgsProcessingFeatureSourceDefinition(layer.id(), selectedFeaturesOnly=True)
        result = processing.run(ALG, {"INPUT": source, "OUTPUT_TRIANGLES": "memory:"})
    finally:
        QgsProject.instance().removeMapLayer(layer.id())
    assert result["FEATURE_COUNT"] == 2
    rows = list(result["OUTPUT_TRIANGLES"].getFeatures())
    assert sorted(row["feature_id"] for row in rows) == [2, 4]


def test_a_bare_field_name_is_a_z_expression(tmp_path: Path):
    import processing

    source = write_gpkg(tmp_path / "p.gpkg", small_triangles(3))
    result = processing.run(
        ALG,
        {
            "INPUT": str(source),
            "ELEVATION_SOURCE": 2,
            "Z_EXPRESSION": "height",
            "OUTPUT_TRIANGLES": "memory:",
        },
    )
    for row in result["OUTPUT_TRIANGLES"].getFeatures():
        ring = row.geometry().constGet().exteriorRing()
        assert {ring.zAt(i) for i in range(4)} == {row["height"]}


def test_cancelling_at_the_first_progress_report_leaves_partial_but_consistent_outputs(
    tmp_path: Path,
):
    import processing
    from bsptriangulate.processing_provider.triangulate_algorithm import TriangulateAlgorithm

    # more features than one engine call takes, so the run has a later chunk to cancel
    count = 2 * max(TriangulateAlgorithm.CHUNK_FEATURES, TriangulateAlgorithm.BATCH_FEATURES)
    feedback = QgsProcessingFeedback()
    feedback.progressChanged.connect(lambda _progress: feedback.cancel())
    source = write_gpkg(tmp_path / "many.gpkg", small_triangles(count))
    result = processing.run(
        ALG, {"INPUT": str(source), "OUTPUT_TRIANGLES": "memory:"}, feedback=feedback
    )
    assert feedback.isCanceled()
    assert 0 < result["FEATURE_COUNT"] < count
    assert result["TRIANGLE_COUNT"] == result["OUTPUT_TRIANGLES"].featureCount()
    assert result["TRIANGLE_COUNT"] == result["FEATURE_COUNT"]  # one triangle per feature
