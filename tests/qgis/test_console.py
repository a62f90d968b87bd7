"""bsptriangulate:triangulate as typed in the QGIS Python console: help text, file paths in and
out, selected features only, a bare field name as Z expression, and cancelling mid-run
(which raises and leaves no output behind)."""

from __future__ import annotations

from pathlib import Path

import pytest
from osgeo import ogr, osr
from qgis.core import (
    QgsApplication,
    QgsProcessingContext,
    QgsProcessingException,
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


def cancel_at_first_progress() -> QgsProcessingFeedback:
    feedback = QgsProcessingFeedback()
    feedback.progressChanged.connect(lambda _progress: feedback.cancel())
    return feedback


@pytest.fixture(scope="module")
def many_polygons(tmp_path_factory) -> Path:
    """More small triangles than one engine call or batch takes: a cancel has work to cut."""
    from bsptriangulate.processing_provider.triangulate_algorithm import TriangulateAlgorithm

    count = 2 * max(TriangulateAlgorithm.CHUNK_FEATURES, TriangulateAlgorithm.BATCH_FEATURES)
    return write_gpkg(tmp_path_factory.mktemp("source") / "many.gpkg", small_triangles(count))


def test_cancelling_at_the_first_progress_report_raises_and_leaves_no_output_files(
    tmp_path: Path, many_polygons: Path
):
    import processing

    feedback = cancel_at_first_progress()
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    with pytest.raises(QgsProcessingException, match="Cancelled"):
        processing.run(
            ALG,
            {
                "INPUT": str(many_polygons),
                "OUTPUT_MESH": str(tmp_path / "many.2dm"),
                "OUTPUT_TRIANGLES": str(tmp_path / "triangles.gpkg"),
                "OUTPUT_TREE": str(tmp_path / "tree.shp"),
            },
            feedback=feedback,
            context=context,
        )
    assert feedback.isCanceled()
    assert not QgsVectorLayer(str(tmp_path / "triangles.gpkg"), "triangles", "ogr").isValid()
    # no mesh, no companion, no staging folder, no shapefile parts
    assert list(tmp_path.iterdir()) == []
    assert context.layersToLoadOnCompletion() == {}


def test_cancelling_a_run_into_memory_layers_leaves_nothing_to_load(many_polygons: Path):
    import processing

    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    with pytest.raises(QgsProcessingException):
        processing.run(
            ALG,
            {"INPUT": str(many_polygons), "OUTPUT_TRIANGLES": "memory:", "OUTPUT_TREE": "memory:"},
            feedback=cancel_at_first_progress(),
            context=context,
        )
    assert context.layersToLoadOnCompletion() == {}
    # only the input, loaded from its path, is left in the run's layer store
    layers = context.temporaryLayerStore().mapLayers().values()
    assert [layer.providerType() for layer in layers] == ["ogr"]


def test_cancelling_keeps_an_earlier_mesh_and_the_other_layers_of_an_existing_geopackage(
    tmp_path: Path, many_polygons: Path
):
    import processing

    mesh = tmp_path / "earlier.2dm"
    results = write_gpkg(tmp_path / "results.gpkg", [SQUARE_WITH_HOLE])
    earlier = processing.run(
        ALG,
        {
            "INPUT": str(write_gpkg(tmp_path / "earlier.gpkg", [SQUARE_WITH_HOLE])),
            "OUTPUT_MESH": str(mesh),
            "OUTPUT_TRIANGLES": f"ogr:dbname='{results}' table=\"triangles\"",
        },
    )
    assert earlier["TRIANGLE_COUNT"] == 4 + 3 + 2 * 1 - 2
    mesh_bytes = mesh.read_bytes()
    with pytest.raises(QgsProcessingException):
        processing.run(
            ALG,
            {
                "INPUT": str(many_polygons),
                "OUTPUT_MESH": str(mesh),
                "OUTPUT_TRIANGLES": f"ogr:dbname='{results}' table=\"many\"",
            },
            feedback=cancel_at_first_progress(),
        )
    assert mesh.read_bytes() == mesh_bytes
    layers = {layer.GetName() for layer in ogr.Open(str(results))}
    assert layers == {"parcels", "triangles"}
    assert sorted(path.name for path in tmp_path.iterdir()) == [
        "earlier.2dm",
        "earlier.gpkg",
        "earlier.qml",
        "earlier_els.dat",
        "results.gpkg",
    ]


def test_cancelling_drops_the_table_it_created_in_a_database_and_keeps_the_others(
    tmp_path: Path, many_polygons: Path
):
    import processing
    from qgis.core import QgsProviderRegistry

    database = tmp_path / "results.sqlite"
    # the data source closes as soon as it is dropped
    ogr.GetDriverByName("SQLite").CreateDataSource(str(database), options=["SPATIALITE=YES"])
    destination = f"spatialite:dbname='{database}' table=\"{{}}\" (geom)"
    metadata = QgsProviderRegistry.instance().providerMetadata("spatialite")
    connection = metadata.createConnection(f"dbname='{database}'", {})
    before = {table.tableName() for table in connection.tables()}
    kept = processing.run(
        ALG,
        {
            "INPUT": str(write_gpkg(tmp_path / "one.gpkg", [SQUARE_WITH_HOLE])),
            "OUTPUT_MESH": None,
            "OUTPUT_TRIANGLES": destination.format("kept"),
        },
    )
    assert kept["TRIANGLE_COUNT"] == 7
    with pytest.raises(QgsProcessingException, match="Cancelled"):
        processing.run(
            ALG,
            {
                "INPUT": str(many_polygons),
                "OUTPUT_MESH": None,
                "OUTPUT_TRIANGLES": destination.format("cancelled"),
            },
            feedback=cancel_at_first_progress(),
        )
    tables = {table.tableName() for table in connection.tables()}
    assert tables - before == {"kept"}
    layer = QgsVectorLayer(f"dbname='{database}' table=\"kept\" (geom)", "kept", "spatialite")
    assert layer.featureCount() == 7
    del layer, connection  # (held until exit, a SpatiaLite connection crashes QGIS's shutdown)


def test_a_complete_run_replaces_an_earlier_mesh_file_and_leaves_no_staging_folder(
    tmp_path: Path,
):
    import processing

    mesh = tmp_path / "parcels.2dm"
    mesh.write_text("not a mesh\n")
    result = processing.run(
        ALG,
        {
            "INPUT": str(write_gpkg(tmp_path / "parcels.gpkg", small_triangles(3))),
            "OUTPUT_MESH": str(mesh),
            "OUTPUT_TRIANGLES": "memory:",
        },
    )
    assert result["TRIANGLE_COUNT"] == result["FEATURE_COUNT"] == 3
    assert result["OUTPUT_TRIANGLES"].featureCount() == 3
    lines = mesh.read_text().splitlines()
    assert lines[0] == "MESH2D"
    assert sum(line.startswith("E3T ") for line in lines) == 3
    assert sorted(path.name for path in tmp_path.iterdir()) == [
        "parcels.2dm",
        "parcels.gpkg",
        "parcels.qml",
        "parcels_els.dat",
    ]
