"""Processing algorithm ``bsptriangulate:triangulate``: polygons to a 3D triangle mesh."""

from __future__ import annotations

import os
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from qgis.core import (
    QgsApplication,
    QgsCoordinateTransform,
    QgsExpression,
    QgsFeatureRequest,
    QgsFields,
    QgsProcessing,
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeatureSource,
    QgsProcessingFeedback,
    QgsProcessingOutputLayerDefinition,
    QgsProcessingOutputNumber,
    QgsProcessingParameterBand,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterDistance,
    QgsProcessingParameterEnum,
    QgsProcessingParameterExpression,
    QgsProcessingParameterFeatureSink,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
    QgsRasterLayer,
    QgsWkbTypes,
)
from qgis.PyQt.QtCore import QCoreApplication
from qgis.PyQt.QtGui import QIcon

from ..bsp_triangulate.terrain.densify import densify_ring
from . import elevation
from .engine_runs import BatchJob, EngineOptions, EngineRunner
from .geometry_io import INVALID_AS_GIVEN, FeatureRings, feature_batches
from .outputs import (
    MESH_EXTENSIONS,
    BatchMesh,
    MeshAccumulator,
    SinkCleanup,
    SinkWriter,
    TriangleStylePostProcessor,
    load_mesh_on_completion,
    tree_feature_chunks,
    tree_fields,
    triangle_feature_chunks,
    triangle_fields,
)

ICON = Path(__file__).resolve().parent.parent / "icons" / "triangulate.svg"
APEX_RULES = ("first", "elevation")
MAX_LISTED_IDS = 200
MAX_WORKERS = 64


class TriangulateAlgorithm(QgsProcessingAlgorithm):
    """Triangulates each polygon with Qiang Liu's recursive BSP-tree algorithm."""

    INPUT = "INPUT"
    ELEVATION_SOURCE = "ELEVATION_SOURCE"
    Z_EXPRESSION = "Z_EXPRESSION"
    DEM = "DEM"
    DEM_BAND = "DEM_BAND"
    DEM_INTERPOLATION = "DEM_INTERPOLATION"
    DEM_NODATA = "DEM_NODATA"
    Z_OFFSET = "Z_OFFSET"
    Z_SCALE = "Z_SCALE"
    MAX_SEGMENT_LENGTH = "MAX_SEGMENT_LENGTH"
    APEX_RULE = "APEX_RULE"
    PLANAR_TOLERANCE = "PLANAR_TOLERANCE"
    INVALID_POLYGONS = "INVALID_POLYGONS"
    WORKERS = "WORKERS"
    OUTPUT_MESH = "OUTPUT_MESH"
    OUTPUT_TRIANGLES = "OUTPUT_TRIANGLES"
    OUTPUT_TREE = "OUTPUT_TREE"
    FEATURE_COUNT = "FEATURE_COUNT"
    TRIANGLE_COUNT = "TRIANGLE_COUNT"
    FAILED_COUNT = "FAILED_COUNT"
    EMPTY_COUNT = "EMPTY_COUNT"

    BATCH_FEATURES = 10_000
    BATCH_VERTICES = 400_000
    # Engine calls within a batch: progress and cancel between them. The engine's lock-step
    # batch path needs thousands of polygons per call to be fast (40 per call: ~30x slower;
    # 50,000 stars of 40 vertices in calls of 100,000 vertices: 16 % slower than of 250,000).
    CHUNK_FEATURES = 10_000
    CHUNK_VERTICES = 250_000

    def tr(self, text: str) -> str:
        return QCoreApplication.translate("TriangulateAlgorithm", text)

    def createInstance(self) -> TriangulateAlgorithm:  # noqa: N802 - QGIS API name
        return TriangulateAlgorithm()

    def name(self) -> str:
        return "triangulate"

    def displayName(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr("Triangulate polygons (BSP tree)")

    def group(self) -> str:
        return self.tr("Triangulation")

    def groupId(self) -> str:  # noqa: N802 - QGIS API name
        return "triangulation"

    def icon(self) -> QIcon:
        return QIcon(str(ICON))

    def tags(self) -> list[str]:
        return self.tr("triangulation,mesh,tin,3d,bsp,polygon,dem,terrain").split(",")

    def shortDescription(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr("Triangulates polygons with islands into a 3D mesh (recursive BSP tree).")

    def shortHelpString(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr(
            "<p>Triangulates every polygon of the input layer with Qiang Liu's recursive "
            "BSP-tree algorithm: concave polygons, islands (holes), multi-part and 3D polygons. "
            "Every output vertex is an input vertex (or a point added by densification).</p>"
            "<h3>Parameters</h3>"
            "<p><b>Input polygon layer</b>: polygons or multipolygons, with or without Z. Curved "
            "geometries are segmentized.</p>"
            "<p><b>Elevation source</b>: where vertex z comes from. <i>None</i>: z = 0. "
            "<i>Geometry Z</i>: the geometry's own z (0 if the layer has none). "
            "<i>Expression</i>: one value per feature from the Z expression. <i>DEM</i>: "
            "sampled from a raster band at every vertex (reprojected when the DEM's CRS "
            "differs).</p>"
            "<p><b>Z expression</b>: expression (or field name) evaluated on each feature; its "
            "number is the z of all vertices of the feature.</p>"
            "<p><b>DEM</b>, <b>DEM band</b>: the elevation raster and its band (default 1).</p>"
            "<p><b>DEM interpolation</b>: bilinear between cell centres (default) or the "
            "nearest cell.</p>"
            "<p><b>Vertices on DEM nodata</b>: <i>fill</i> interpolates their z from the "
            "nearest valid vertices along the ring (default); <i>fail</i> rejects the feature. "
            "Vertices outside the DEM count as nodata.</p>"
            "<p><b>Z offset</b>, <b>Z scale</b>: final z = z × scale + offset.</p>"
            "<p><b>Maximum segment length</b>: boundary edges longer than this are split "
            "before triangulation; the new points become vertices and get their z from the "
            "elevation source. 0 = off.</p>"
            "<p><b>Apex rule</b>: <i>first</i> takes the first correct apex in the paper's "
            "order; <i>elevation</i> takes, among all correct apexes, the one whose z is "
            "closest to the mean z of the base edge (paper §4.1; suits roads and streams "
            "over terrain).</p>"
            "<p><b>Planar tolerance</b>: near-planar polygons (roofs) are snapped onto one "
            "plane when no vertex moves by more than this (paper §4.2). 0 = off.</p>"
            "<p><b>Worker processes</b>: large layers are triangulated in this many Python "
            "processes at once; 1 keeps all the work in QGIS's process. By default (0): one "
            "per core (QGIS's <i>max cores</i> setting limits it) for a mesh-only run, none "
            "when the triangles or the tree are written (writing those features takes most "
            "of such a run). A layer of one engine call (up to 250,000 vertices) always stays "
            "in QGIS's process. The workers also write a large .2dm mesh's lines (on "
            "Linux). Results are the same either way.</p>"
            "<p><b>Invalid polygons</b>: <i>repair</i> them with make valid, then triangulate "
            "(default; repaired feature ids are reported); <i>fail</i> the feature; or "
            "<i>triangulate the rings as given</i>.</p>"
            "<h3>Outputs</h3>"
            "<p><b>Mesh</b>: one .2dm (default) or .ply file for the whole layer, vertices "
            "shared where identical, z per vertex, face values feature_id and depth; loaded "
            "as a mesh layer in the input's CRS.</p>"
            "<p><b>Triangles</b> (skip it for a faster mesh-only run; at least one of the mesh "
            "and the triangles is needed): one PolygonZ feature per triangle with the source "
            "feature id "
            "and attributes (clashing names prefixed with src_), part, order (index in the "
            "BSP tree's pre-order), parent, depth, side (0 root, 1 left, 2 right), area_2d, "
            "area_3d, min_angle, slope and aspect (degrees).</p>"
            "<p><b>BSP tree</b> (optional): a line from each triangle's centroid to each "
            "child's centroid.</p>"
            "<p>A feature that cannot be triangulated is reported with its id and reason and "
            "counted in FAILED_COUNT; null and empty geometries in EMPTY_COUNT. "
            "FEATURE_COUNT = triangulated + FAILED_COUNT + EMPTY_COUNT.</p>"
            "<p>A cancelled run writes no mesh file and deletes the triangle and tree outputs "
            "it created.</p>"
        )

    def initAlgorithm(self, config: dict[str, Any] | None = None) -> None:  # noqa: N802
        self.addParameter(
            QgsProcessingParameterFeatureSource(
                self.INPUT, self.tr("Input polygon layer"), [QgsProcessing.TypeVectorPolygon]
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.ELEVATION_SOURCE,
                self.tr("Elevation source"),
                [
                    self.tr("None (z = 0)"),
                    self.tr("Geometry Z"),
                    self.tr("Expression"),
                    self.tr("DEM"),
                ],
                defaultValue=elevation.ELEVATION_GEOMETRY,
            )
        )
        self.addParameter(
            QgsProcessingParameterExpression(
                self.Z_EXPRESSION,
                self.tr("Z expression"),
                parentLayerParameterName=self.INPUT,
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterLayer(self.DEM, self.tr("DEM"), optional=True)
        )
        self.addParameter(
            QgsProcessingParameterBand(
                self.DEM_BAND,
                self.tr("DEM band"),
                defaultValue=1,
                parentLayerParameterName=self.DEM,
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.DEM_INTERPOLATION,
                self.tr("DEM interpolation"),
                [self.tr("Bilinear"), self.tr("Nearest cell")],
                defaultValue=0,
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.DEM_NODATA,
                self.tr("Vertices on DEM nodata"),
                [
                    self.tr("Fill from the nearest valid vertices along the ring"),
                    self.tr("Fail the feature"),
                ],
                defaultValue=elevation.NODATA_FILL,
            )
        )
        advanced = [
            QgsProcessingParameterNumber(
                self.Z_OFFSET,
                self.tr("Z offset"),
                QgsProcessingParameterNumber.Double,
                defaultValue=0.0,
            ),
            QgsProcessingParameterNumber(
                self.Z_SCALE,
                self.tr("Z scale"),
                QgsProcessingParameterNumber.Double,
                defaultValue=1.0,
            ),
        ]
        self.addParameter(
            QgsProcessingParameterDistance(
                self.MAX_SEGMENT_LENGTH,
                self.tr("Maximum segment length (0 = off)"),
                defaultValue=0.0,
                parentParameterName=self.INPUT,
                minValue=0.0,
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.APEX_RULE,
                self.tr("Apex rule"),
                [self.tr("First correct apex (planar)"), self.tr("Closest elevation")],
                defaultValue=0,
            )
        )
        advanced += [
            QgsProcessingParameterNumber(
                self.PLANAR_TOLERANCE,
                self.tr("Planar tolerance (0 = off)"),
                QgsProcessingParameterNumber.Double,
                defaultValue=0.0,
                minValue=0.0,
            ),
            QgsProcessingParameterNumber(
                self.WORKERS,
                self.tr("Worker processes (0 = automatic, 1 = none)"),
                QgsProcessingParameterNumber.Integer,
                defaultValue=0,
                minValue=0,
                maxValue=MAX_WORKERS,
            ),
        ]
        for parameter in advanced:
            parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(parameter)
        self.addParameter(
            QgsProcessingParameterEnum(
                self.INVALID_POLYGONS,
                self.tr("Invalid polygons"),
                [
                    self.tr("Repair (make valid), then triangulate"),
                    self.tr("Fail the feature"),
                    self.tr("Triangulate the rings as given"),
                ],
                defaultValue=0,
            )
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.OUTPUT_MESH,
                self.tr("Mesh"),
                self.tr("2DM mesh (*.2dm);;PLY mesh (*.ply)"),
                optional=True,
                createByDefault=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSink(
                self.OUTPUT_TRIANGLES,
                self.tr("Triangles"),
                QgsProcessing.TypeVectorPolygon,
                optional=True,
                createByDefault=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSink(
                self.OUTPUT_TREE,
                self.tr("BSP tree"),
                QgsProcessing.TypeVectorLine,
                optional=True,
                createByDefault=False,
            )
        )
        for name, label in (
            (self.FEATURE_COUNT, self.tr("Features read")),
            (self.TRIANGLE_COUNT, self.tr("Triangles")),
            (self.FAILED_COUNT, self.tr("Failed features")),
            (self.EMPTY_COUNT, self.tr("Empty features")),
        ):
            self.addOutput(QgsProcessingOutputNumber(name, label))

    def checkParameterValues(  # noqa: N802 - QGIS API name
        self, parameters: dict[str, Any], context: QgsProcessingContext
    ) -> tuple[bool, str]:
        ok, message = super().checkParameterValues(parameters, context)
        if not ok:
            return ok, message
        source = self.parameterAsEnum(parameters, self.ELEVATION_SOURCE, context)
        if source == elevation.ELEVATION_EXPRESSION:
            text = self.parameterAsExpression(parameters, self.Z_EXPRESSION, context)
            if not text.strip():
                return False, self.tr("The elevation source is an expression: set Z expression.")
            expression = QgsExpression(text)
            if expression.hasParserError():
                return False, self.tr("Z expression: {}").format(expression.parserErrorString())
        if source == elevation.ELEVATION_DEM:
            layer = self.parameterAsRasterLayer(parameters, self.DEM, context)
            if layer is None:
                return False, self.tr("The elevation source is a DEM: choose a DEM raster.")
            band = self._dem_band(parameters, context)
            if not 1 <= band <= layer.bandCount():
                return False, self.tr("DEM band {} does not exist: the DEM has {} band(s).").format(
                    band, layer.bandCount()
                )
        path = self.parameterAsFileOutput(parameters, self.OUTPUT_MESH, context)
        if path and Path(path).suffix.lower().lstrip(".") not in MESH_EXTENSIONS:
            return False, self.tr("The mesh file must end with .2dm or .ply: {}").format(path)
        if not path and not self._wants_triangles(parameters):
            return False, self.tr("Nothing to write: choose a mesh file or the triangles output.")
        return True, ""

    def _wants_triangles(self, parameters: dict[str, Any]) -> bool:
        """Whether the per-triangle output was asked for (skipped when unset or empty)."""
        value = parameters.get(self.OUTPUT_TRIANGLES)
        if isinstance(value, QgsProcessingOutputLayerDefinition):
            value = value.sink.staticValue()
        return value is not None and str(value) != ""

    def _dem_band(self, parameters: dict[str, Any], context: QgsProcessingContext) -> int:
        if parameters.get(self.DEM_BAND) is None:
            return 1
        return self.parameterAsInt(parameters, self.DEM_BAND, context)

    def _worker_count(
        self, parameters: dict[str, Any], context: QgsProcessingContext, features: bool
    ) -> int:
        """Worker processes of the run: as asked, or by default one per core QGIS may use
        (its "max cores" setting) in a run that writes no ``features`` (triangles or tree),
        none in one that does (QGIS writing the features takes nine tenths of such a run:
        workers would spare little time for their memory)."""
        count = self.parameterAsInt(parameters, self.WORKERS, context)
        if count <= 0:
            if features:
                return 1
            allowed = QgsApplication.maxThreads()
            count = allowed if allowed > 0 else os.cpu_count() or 1
        return min(count, MAX_WORKERS)

    def prepareAlgorithm(  # noqa: N802 - QGIS API name
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        feedback: QgsProcessingFeedback,
    ) -> bool:
        # The raster provider is cloned here, on the thread that owns the layer.
        self._dem_provider = None
        self._dem_crs = None
        if self.parameterAsEnum(parameters, self.ELEVATION_SOURCE, context) == (
            elevation.ELEVATION_DEM
        ):
            layer: QgsRasterLayer | None = self.parameterAsRasterLayer(
                parameters, self.DEM, context
            )
            if layer is None or not layer.isValid():
                raise QgsProcessingException(self.invalidRasterError(parameters, self.DEM))
            band = self._dem_band(parameters, context)
            if not 1 <= band <= layer.bandCount():
                raise QgsProcessingException(
                    self.tr("DEM band {} does not exist: the DEM has {} band(s).").format(
                        band, layer.bandCount()
                    )
                )
            self._dem_provider = layer.dataProvider().clone()
            self._dem_crs = layer.crs()
        return True

    def _elevation_source(
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        source: QgsProcessingFeatureSource,
    ) -> elevation.ElevationSource:
        kind = self.parameterAsEnum(parameters, self.ELEVATION_SOURCE, context)
        if kind == elevation.ELEVATION_GEOMETRY:
            return elevation.GeometryElevation()
        if kind == elevation.ELEVATION_EXPRESSION:
            text = self.parameterAsExpression(parameters, self.Z_EXPRESSION, context)
            expression = QgsExpression(text)
            if not text.strip() or expression.hasParserError():
                raise QgsProcessingException(
                    self.tr("Z expression: {}").format(
                        expression.parserErrorString() or self.tr("empty")
                    )
                )
            expression_context = self.createExpressionContext(parameters, context, source)
            return elevation.ExpressionElevation(expression, expression_context)
        if kind == elevation.ELEVATION_DEM:
            if self._dem_provider is None:
                raise QgsProcessingException(self.invalidRasterError(parameters, self.DEM))
            transform = None
            crs = source.sourceCrs()
            if crs.isValid() and self._dem_crs.isValid() and crs != self._dem_crs:
                transform = QgsCoordinateTransform(crs, self._dem_crs, context.transformContext())
            method = elevation.INTERPOLATION_METHODS[
                self.parameterAsEnum(parameters, self.DEM_INTERPOLATION, context)
            ]
            try:
                sampler = elevation.DemSampler(
                    self._dem_provider, self._dem_band(parameters, context), method, transform
                )
            except ValueError as error:
                raise QgsProcessingException(self.tr("DEM: {}").format(error)) from error
            nodata = self.parameterAsEnum(parameters, self.DEM_NODATA, context)
            return elevation.DemElevation(sampler, nodata)
        return elevation.FlatElevation()

    def processAlgorithm(  # noqa: N802 - QGIS API name
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        feedback: QgsProcessingFeedback,
    ) -> dict[str, Any]:
        """Triangulate the layer; a cancelled or failed run raises and leaves no outputs."""
        source = self.parameterAsSource(parameters, self.INPUT, context)
        if source is None:
            raise QgsProcessingException(self.invalidSourceError(parameters, self.INPUT))
        crs = source.sourceCrs()
        fields = triangle_fields(source.fields())
        cleanup = SinkCleanup(context)
        for name in (self.OUTPUT_TRIANGLES, self.OUTPUT_TREE):
            cleanup.note(self.parameterAsOutputLayer(parameters, name, context))
        sink, triangles_id = self.parameterAsSink(
            parameters, self.OUTPUT_TRIANGLES, context, fields, QgsWkbTypes.PolygonZ, crs
        )
        if sink is None and self._wants_triangles(parameters):
            raise QgsProcessingException(self.invalidSinkError(parameters, self.OUTPUT_TRIANGLES))
        if sink is not None:
            cleanup.track(triangles_id)
        tree_sink, tree_id = self.parameterAsSink(
            parameters, self.OUTPUT_TREE, context, tree_fields(), QgsWkbTypes.LineStringZ, crs
        )
        has_tree = tree_sink is not None
        if has_tree:
            cleanup.track(tree_id)
        # the only long-lived references to the sinks: cleared, they close (and can be removed)
        sinks = [sink, tree_sink]
        del sink, tree_sink
        try:
            results = self._process(parameters, context, feedback, source, sinks, fields)
        except BaseException as error:
            sinks.clear()
            # frames of the traceback may still hold a sink, which would keep its file open
            traceback.clear_frames(error.__traceback__)
            cleanup.remove()
            raise
        if triangles_id:
            results[self.OUTPUT_TRIANGLES] = triangles_id
        if has_tree:
            results[self.OUTPUT_TREE] = tree_id
        if triangles_id and context.willLoadLayerOnCompletion(triangles_id):
            context.layerToLoadOnCompletionDetails(triangles_id).setPostProcessor(
                TriangleStylePostProcessor.create()
            )
        return results

    def _cancelled(self) -> QgsProcessingException:
        return QgsProcessingException(self.tr("Cancelled: no output was written."))

    def _process(
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        feedback: QgsProcessingFeedback,
        source: QgsProcessingFeatureSource,
        sinks: list,
        fields: QgsFields,
    ) -> dict[str, Any]:
        """Triangulate into ``sinks`` (triangles, tree or None) and the mesh file; closes the
        sinks by clearing the list. Raises when cancelled."""
        crs = source.sourceCrs()
        lines = tree_fields()
        mesh_path = self.parameterAsFileOutput(parameters, self.OUTPUT_MESH, context)
        source_of_z = self._elevation_source(parameters, context, source)
        rule = APEX_RULES[self.parameterAsEnum(parameters, self.APEX_RULE, context)]
        tolerance = self.parameterAsDouble(parameters, self.PLANAR_TOLERANCE, context)
        max_length = self.parameterAsDouble(parameters, self.MAX_SEGMENT_LENGTH, context)
        z_scale = self.parameterAsDouble(parameters, self.Z_SCALE, context)
        z_offset = self.parameterAsDouble(parameters, self.Z_OFFSET, context)
        invalid_policy = self.parameterAsEnum(parameters, self.INVALID_POLYGONS, context)
        # rings kept as given: the engine triangulates them even where no correct triangle exists
        options = EngineOptions(
            rule, tolerance, "as_given" if invalid_policy == INVALID_AS_GIVEN else "fail"
        )
        workers = self._worker_count(parameters, context, any(s is not None for s in sinks))
        runner = EngineRunner(
            options, workers, feedback, self.tr, self.CHUNK_FEATURES, self.CHUNK_VERTICES
        )

        total = source.featureCount()
        step = 100.0 / total if total > 0 else 0.0
        request = QgsFeatureRequest()
        # attributes are read only for the triangles' rows and a Z expression
        if sinks[0] is None and not isinstance(source_of_z, elevation.ExpressionElevation):
            request.setSubsetOfAttributes([])
        features = source.getFeatures(
            request, QgsProcessingFeatureSource.FlagSkipGeometryValidityChecks
        )
        mesh = MeshAccumulator() if mesh_path else None
        tally = _Tally()
        reported_warnings: set[str] = set()
        writer = SinkWriter()

        def write(job: BatchJob) -> bool:
            """The job's results to the outputs; False when the run was cancelled."""
            start, size = tally.read, len(job.batch)

            def report(fraction: float) -> None:
                feedback.setProgress(min((start + fraction * size) * step, 99.0))

            chunks = runner.finish(job, report)
            if chunks is None:
                return False
            batch = job.batch
            tally.read += size
            tally.repaired.extend(item.fid for item in batch if item.repaired)
            for item in batch:
                if item.error is not None:
                    tally.failed += 1
                    feedback.reportError(
                        self.tr("Feature {}: {}").format(item.fid, item.error), False
                    )
            batch_mesh = BatchMesh.build(chunks)
            with_triangles = batch_mesh.feature_count()
            tally.triangulated += with_triangles
            tally.empty += sum(1 for item in batch if item.error is None) - with_triangles
            tally.triangles += len(batch_mesh)
            writer.write(sinks[0], triangle_feature_chunks(batch_mesh, fields))
            writer.write(sinks[1], tree_feature_chunks(batch_mesh, lines))
            if mesh is not None:
                mesh.add(batch_mesh)
            report(1.0)
            return True

        # with workers, a batch is written once the next one is read and submitted
        pending: list[BatchJob] = []
        try:
            for batch in feature_batches(
                features, invalid_policy, self.BATCH_FEATURES, self.BATCH_VERTICES, feedback
            ):
                if feedback.isCanceled():
                    break
                if max_length > 0:
                    _densify(batch, max_length)
                source_of_z.apply(batch)
                for warning in set(source_of_z.warnings) - reported_warnings:
                    feedback.pushInfo(self.tr("Elevation: {}").format(warning))
                    reported_warnings.add(warning)
                elevation.scale_z(batch, z_scale, z_offset)
                pending.append(runner.submit(batch))
                while len(pending) > runner.parallel and write(pending.pop(0)):
                    pass
                if feedback.isCanceled():
                    break
            while pending and not feedback.isCanceled() and write(pending.pop(0)):
                pass
            writer.close(sinks)  # a GeoPackage builds its spatial index here
            if feedback.isCanceled():
                raise self._cancelled()
            # the workers, if any, write a large 2DM mesh's lines before they stop
            staged = mesh.stage(mesh_path, crs, runner.pool) if mesh is not None else None
            runner.close()
            if runner.calls_in_workers:
                feedback.pushInfo(
                    self.tr("{} of {} engine calls ran in {} worker processes.").format(
                        runner.calls_in_workers, runner.calls, runner.workers_started
                    )
                )
            if staged is not None and feedback.isCanceled():
                staged.discard()
                raise self._cancelled()
            written = staged.commit() if staged is not None else None
        finally:
            runner.close(cancel=True)
            writer.finish()

        read, triangulated, triangles = tally.read, tally.triangulated, tally.triangles
        failed, empty, repaired = tally.failed, tally.empty, tally.repaired
        if repaired:
            self._report_repaired(repaired, feedback)
        results: dict[str, Any] = {
            self.FEATURE_COUNT: read,
            self.TRIANGLE_COUNT: triangles,
            self.FAILED_COUNT: failed,
            self.EMPTY_COUNT: empty,
        }
        if written is not None:
            vertex_count, face_count, dataset_files = written
            feedback.pushInfo(
                self.tr("Mesh {}: {} vertices, {} faces").format(
                    mesh_path, vertex_count, face_count
                )
            )
            results[self.OUTPUT_MESH] = mesh_path
            # without a project (qgis_process) nothing would take the layer: do not open it
            if face_count and context.project() is not None:
                loaded = load_mesh_on_completion(
                    mesh_path, crs, context, self.OUTPUT_MESH, dataset_files
                )
                if not loaded:
                    feedback.pushWarning(
                        self.tr("The mesh file could not be opened as a mesh layer.")
                    )
        feedback.pushInfo(
            self.tr("{} feature(s): {} triangulated, {} failed, {} empty; {} triangles").format(
                read, triangulated, failed, empty, triangles
            )
        )
        feedback.setProgress(100)
        return results

    def _report_repaired(self, repaired: list[int], feedback: QgsProcessingFeedback) -> None:
        listed = ", ".join(str(fid) for fid in repaired[:MAX_LISTED_IDS])
        more = len(repaired) - MAX_LISTED_IDS
        if more > 0:
            listed += self.tr(" and {} more").format(more)
        feedback.pushWarning(
            self.tr("Repaired invalid geometries of {} feature(s): {}").format(
                len(repaired), listed
            )
        )


@dataclass
class _Tally:
    """Counts of a run so far."""

    read: int = 0
    triangulated: int = 0
    triangles: int = 0
    failed: int = 0
    empty: int = 0
    repaired: list[int] = field(default_factory=list)


def _densify(batch: list[FeatureRings], max_length: float) -> None:
    """Split boundary edges longer than ``max_length`` (XY), in place on the batch."""
    for item in batch:
        if item.ok:
            item.parts = [[densify_ring(ring, max_length) for ring in part] for part in item.parts]
