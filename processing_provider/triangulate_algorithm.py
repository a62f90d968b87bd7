"""Processing algorithm ``bsptriangulate:triangulate``: polygons to a 3D triangle mesh."""

from __future__ import annotations

import os
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from qgis.core import (
    QgsApplication,
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsEllipsoidUtils,
    QgsExpression,
    QgsFeatureRequest,
    QgsFields,
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeatureSource,
    QgsProcessingFeedback,
    QgsProcessingOutputLayerDefinition,
    QgsProcessingOutputNumber,
    QgsProcessingParameterBand,
    QgsProcessingParameterDistance,
    QgsProcessingParameterEnum,
    QgsProcessingParameterExpression,
    QgsProcessingParameterFeatureSink,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterField,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
    QgsRasterLayer,
    QgsRectangle,
    QgsWkbTypes,
)
from qgis.PyQt.QtCore import QCoreApplication
from qgis.PyQt.QtGui import QIcon

from ..bsp_triangulate.metrics import WGS84
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
    is_model,
    load_mesh_on_completion,
    tree_feature_chunks,
    tree_fields,
    triangle_feature_chunks,
    triangle_fields,
)
from .qgis_compat import (
    DistanceUnit,
    GeometryType,
    ProcessingFeatureSourceFlag,
    ProcessingFieldParameterDataType,
    ProcessingNumberParameterType,
    ProcessingParameterFlag,
    ProcessingSourceType,
    WkbType,
)
from .run_report import REFINE_STAGES, FailureLog, Progress
from .terrain_points import CancelledError, InteriorPoints, SurveyPoints, scale_points
from .warped_dem import WarpedDemSampler

ICON = Path(__file__).resolve().parent.parent / "icons" / "triangulate.svg"
APEX_RULES = ("first", "elevation", "delaunay")
MAX_LISTED_IDS = 200
MAX_WORKERS = 64
HELP_URL = "https://github.com/bsptriangulate/bsptriangulate#readme"


class TriangulateAlgorithm(QgsProcessingAlgorithm):
    """Triangulates each polygon with Qiang Liu's recursive BSP-tree algorithm."""

    INPUT = "INPUT"
    ELEVATION_SOURCE = "ELEVATION_SOURCE"
    Z_EXPRESSION = "Z_EXPRESSION"
    DEM = "DEM"
    DEM_BAND = "DEM_BAND"
    DEM_INTERPOLATION = "DEM_INTERPOLATION"
    DEM_NODATA = "DEM_NODATA"
    MAX_VERTICAL_ERROR = "MAX_VERTICAL_ERROR"
    MAX_POINTS = "MAX_POINTS"
    INPUT_POINTS = "INPUT_POINTS"
    POINTS_Z_FIELD = "POINTS_Z_FIELD"
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
    OUTPUT_REPORT = "OUTPUT_REPORT"
    FEATURE_COUNT = "FEATURE_COUNT"
    TRIANGLE_COUNT = "TRIANGLE_COUNT"
    FAILED_COUNT = "FAILED_COUNT"
    EMPTY_COUNT = "EMPTY_COUNT"
    POINTS_ADDED = "POINTS_ADDED"

    BATCH_FEATURES = 10_000
    BATCH_VERTICES = 400_000
    # Engine calls within a batch: progress and cancel between them. Each lock-step round has
    # a fixed cost, so the batch path needs thousands of polygons per call to be fast.
    CHUNK_FEATURES = 10_000
    CHUNK_VERTICES = 250_000
    # features given their z at once (progress and cancel between)
    ELEVATION_FEATURES = 1_000

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

    def svgIconPath(self) -> str:  # noqa: N802 - QGIS API name
        return str(ICON)

    def helpUrl(self) -> str:  # noqa: N802 - QGIS API name
        return HELP_URL

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
            "geometries are segmentized. Point and line layers are refused.</p>"
            "<p><b>Elevation source</b>: where vertex z comes from. <i>Automatic</i> "
            "(default): the DEM when one is given, else the Z expression when one is given, "
            "else the geometry's Z. <i>None</i>: z = 0. "
            "<i>Geometry Z</i>: the geometry's own z (0 if the layer has none). "
            "<i>Expression</i>: one value per feature from the Z expression. <i>DEM</i>: "
            "sampled from a raster band at every vertex (reprojected when the DEM's CRS "
            "differs; a DEM that does not overlap the layer is refused). A DEM given with "
            "another source is refused, never ignored.</p>"
            "<p>Polygons draped on terrain (z from a DEM, an expression or none) are always "
            "triangulated in XY, whatever the units. Only the geometry's own Z, in a projected "
            "CRS in metres, can make a near-vertical face (a wall) that is triangulated in its "
            "own plane; on a geographic layer (degrees) every polygon is triangulated in XY, "
            "and the log says so.</p>"
            "<p><b>Z expression</b>: expression (or field name) evaluated on each feature; its "
            "number is the z of all vertices of the feature.</p>"
            "<p><b>DEM</b>, <b>DEM band</b>: the elevation raster and its band (default 1).</p>"
            "<p><b>DEM interpolation</b>: bilinear between cell centres (default) or the "
            "nearest cell.</p>"
            "<p><b>Vertices on DEM nodata</b>: <i>fill</i> interpolates their z from the "
            "nearest valid vertices along the ring (default); <i>fail</i> rejects the feature. "
            "Vertices outside the DEM count as nodata.</p>"
            "<p><b>Maximum vertical error</b> (metres; DEM only; 0 = off, default): DEM cell "
            "centres inside each polygon are added as interior vertices, each round where the "
            "mesh is farthest from the DEM, until the mesh is within this distance of the DEM "
            "at every cell centre strictly inside the polygon (cells on nodata are skipped). "
            "A DEM in another CRS than the layer's is first resampled into the layer's CRS "
            "(GDAL warp in memory, bilinear, or nearest with <i>Nearest cell</i>; cells of about "
            "the DEM's cell area; nodata kept): the vertices' z, the added points and the "
            "error are then all taken on the resampled cells, whose values differ slightly "
            "from the DEM's own (interpolated between its cells); the log gives their size.</p>"
            "<p><b>Maximum added points per feature</b> (default 10,000): a feature that "
            "reaches it is still written; it is reported as a warning with its id and the "
            "error reached (and listed in the failure report). POINTS_ADDED counts the DEM "
            "points added.</p>"
            "<p><b>Input points</b> (optional point layer: spot heights, survey points), "
            "<b>Points Z field</b> (optional; default the points' geometry Z): the points "
            "strictly inside a polygon become interior vertices of its mesh with their z "
            "(reprojected to the layer's CRS; points without z are left out); with a maximum "
            "vertical error they are kept and DEM points are added around them.</p>"
            "<p>Which rule for interior points: <i>delaunay</i> needs the fewest DEM points for "
            "a given vertical error and gives well-shaped triangles: the rule for terrain "
            "surfaces. <i>first</i> and <i>elevation</i> join each point by a bridge from the "
            "boundary, which gives long thin triangles: they need more points for the same "
            "error; use them for a few survey points on flat or planar areas.</p>"
            "<p><b>Z offset</b>, <b>Z scale</b>: final z = z × scale + offset (defaults 0 and "
            "1), interior points included.</p>"
            "<p><b>Maximum segment length</b>: boundary edges longer than this (layer units) "
            "are split before triangulation; the new points become vertices and get their z "
            "from the elevation source. 0 = off (default).</p>"
            "<p><b>Apex rule</b>: <i>first</i> takes the first correct apex in the paper's "
            "order; <i>elevation</i> takes, among all correct apexes, the one whose z is "
            "closest to the mean z of the base edge (paper §4.1; suits roads and streams "
            "over terrain); <i>delaunay</i> takes the correct apex that sees the base under "
            "the largest angle, so the tree is the constrained Delaunay triangulation of the "
            "polygon's vertices (fewest slivers: the surface follows the terrain between "
            "boundary points best, as GEOS's constrained Delaunay does). Time, against "
            "first: delaunay 0.8 to 1.6 times as long, elevation 2 to 7 times on polygons of "
            "hundreds of vertices or more. Default: first.</p>"
            "<p><b>Planar tolerance</b> (z units, e.g. metres): near-planar polygons (roofs) "
            "are snapped onto one plane when no vertex moves by more than this vertically "
            "(paper §4.2). 0 = off (default).</p>"
            "<p><b>Worker processes</b>: large layers are triangulated in this many Python "
            "processes at once; 1 keeps all the work in QGIS's process. By default (0): one "
            "per core (QGIS's <i>max cores</i> setting limits it) for a mesh-only run, none "
            "when the triangles or the tree are written (writing those features takes most "
            "of such a run). With workers, a batch's engine calls are cut so that they spread "
            "over them, and the DEM points of <i>Maximum vertical error</i> are added there "
            "too. A small layer (under 100,000 vertices, interior points included, whose parts' "
            "boxes cover fewer than 100,000 DEM cells) stays in QGIS's process. The workers "
            "also write a large .2dm mesh's lines (on "
            "Linux). Results are the same either way.</p>"
            "<p><b>Invalid polygons</b>: <i>repair</i> them with make valid, then triangulate "
            "(default; repaired feature ids are reported); <i>fail</i> the feature; or "
            "<i>triangulate the rings as given</i>.</p>"
            "<p><b>Failure report</b> (optional): a CSV file with the id and reason of every "
            "feature that failed. The log lists the first ten failures of each kind and "
            "counts the rest.</p>"
            "<h3>Outputs</h3>"
            "<p><b>Mesh</b>: one .ply (default) or .2dm file for the whole layer, vertices "
            "shared where identical, z per vertex, face values feature_id and depth; loaded "
            "as a mesh layer in the input's CRS. PLY carries the input's CRS and the face "
            "values, so QGIS opens it complete later; 2DM has no CRS (MDAL reads none) and its "
            "face values are in &lt;name&gt;_els.dat, to be added by hand. Both get "
            "&lt;name&gt;.qml beside them: their 2D style and 3D renderer. .glb, .gltf and "
            ".obj write a 3D model for other software (Blender, web viewers, Cesium) instead: "
            "vertices relative to a local origin kept at full precision, the CRS in glTF's "
            "asset.extras or beside the OBJ in a .prj, glTF in its Y-up frame (x, z, −y); "
            "feature_id and "
            "depth as glTF EXT_mesh_features feature IDs, as OBJ groups by feature_id. A model "
            "is not loaded into the project.</p>"
            "<p><b>Triangles</b> (skip it for a faster mesh-only run; at least one of the mesh "
            "and the triangles is needed): one PolygonZ feature per triangle with the source "
            "feature id "
            "and attributes (clashing names prefixed with src_), part, order (index in the "
            "BSP tree's pre-order), parent, depth, side (0 root, 1 left, 2 right), area_2d, "
            "area_3d, min_angle, slope and aspect (degrees).</p>"
            "<p><b>BSP tree</b> (optional): a line from each triangle's centroid to each "
            "child's centroid.</p>"
            "<p>Every triangulation is checked: its triangles' areas must add up to the "
            "polygon's area (in the plane it was triangulated in), or the feature fails; no "
            "wrong triangle is written. "
            "A feature that cannot be triangulated is reported with its id and reason and "
            "counted in FAILED_COUNT; null and empty geometries in EMPTY_COUNT. "
            "With a maximum vertical error, every feature's mesh is checked against the DEM at "
            "every cell centre inside it; one that stays farther off is reported. "
            "FEATURE_COUNT = triangulated + FAILED_COUNT + EMPTY_COUNT.</p>"
            "<p>A cancelled run writes no mesh file and deletes the triangle and tree outputs "
            "it created.</p>"
        )

    def initAlgorithm(self, config: dict[str, Any] | None = None) -> None:  # noqa: N802
        self.addParameter(
            QgsProcessingParameterFeatureSource(
                self.INPUT, self.tr("Input polygon layer"), [ProcessingSourceType.VectorPolygon]
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
                    self.tr("Automatic: the DEM if given, else the expression, else geometry Z"),
                ],
                defaultValue=elevation.ELEVATION_AUTOMATIC,
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
        self.addParameter(
            QgsProcessingParameterNumber(
                self.MAX_VERTICAL_ERROR,
                self.tr("Maximum vertical error from the DEM, metres (0 = off)"),
                ProcessingNumberParameterType.Double,
                defaultValue=0.0,
                minValue=0.0,
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSource(
                self.INPUT_POINTS,
                self.tr("Input points (spot heights, survey points)"),
                [ProcessingSourceType.VectorPoint],
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterField(
                self.POINTS_Z_FIELD,
                self.tr("Points Z field (default: the points' geometry Z)"),
                parentLayerParameterName=self.INPUT_POINTS,
                type=ProcessingFieldParameterDataType.Numeric,
                optional=True,
            )
        )
        advanced = [
            QgsProcessingParameterNumber(
                self.MAX_POINTS,
                self.tr("Maximum added points per feature"),
                ProcessingNumberParameterType.Integer,
                defaultValue=10_000,
                minValue=0,
            ),
            QgsProcessingParameterNumber(
                self.Z_OFFSET,
                self.tr("Z offset"),
                ProcessingNumberParameterType.Double,
                defaultValue=0.0,
            ),
            QgsProcessingParameterNumber(
                self.Z_SCALE,
                self.tr("Z scale"),
                ProcessingNumberParameterType.Double,
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
                [
                    self.tr("First correct apex (planar)"),
                    self.tr("Closest elevation"),
                    self.tr("Constrained Delaunay (largest angle)"),
                ],
                defaultValue=0,
            )
        )
        advanced += [
            QgsProcessingParameterNumber(
                self.PLANAR_TOLERANCE,
                self.tr("Planar tolerance (z units; 0 = off)"),
                ProcessingNumberParameterType.Double,
                defaultValue=0.0,
                minValue=0.0,
            ),
            QgsProcessingParameterNumber(
                self.WORKERS,
                self.tr("Worker processes (0 = automatic, 1 = none)"),
                ProcessingNumberParameterType.Integer,
                defaultValue=0,
                minValue=0,
                maxValue=MAX_WORKERS,
            ),
        ]
        for parameter in advanced:
            parameter.setFlags(parameter.flags() | ProcessingParameterFlag.Advanced)
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
                self.tr(
                    "PLY mesh (*.ply);;2DM mesh (*.2dm);;Binary glTF (*.glb);;glTF (*.gltf);;"
                    "Wavefront OBJ (*.obj)"
                ),
                optional=True,
                createByDefault=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSink(
                self.OUTPUT_TRIANGLES,
                self.tr("Triangles"),
                ProcessingSourceType.VectorPolygon,
                optional=True,
                createByDefault=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSink(
                self.OUTPUT_TREE,
                self.tr("BSP tree"),
                ProcessingSourceType.VectorLine,
                optional=True,
                createByDefault=False,
            )
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.OUTPUT_REPORT,
                self.tr("Failure report (fid, reason)"),
                self.tr("CSV file (*.csv)"),
                optional=True,
                createByDefault=False,
            )
        )
        for name, label in (
            (self.FEATURE_COUNT, self.tr("Number of features read")),
            (self.TRIANGLE_COUNT, self.tr("Number of triangles")),
            (self.FAILED_COUNT, self.tr("Number of failed features")),
            (self.EMPTY_COUNT, self.tr("Number of empty features")),
            (self.POINTS_ADDED, self.tr("Number of DEM points added")),
        ):
            self.addOutput(QgsProcessingOutputNumber(name, label))

    def checkParameterValues(  # noqa: N802 - QGIS API name
        self, parameters: dict[str, Any], context: QgsProcessingContext
    ) -> tuple[bool, str]:
        ok, message = super().checkParameterValues(parameters, context)
        if not ok:
            return ok, message
        layer_source = self.parameterAsSource(parameters, self.INPUT, context)
        if layer_source is not None:
            kind = QgsWkbTypes.geometryType(layer_source.wkbType())
            if kind not in (GeometryType.Polygon, GeometryType.Unknown):
                return False, self.tr(
                    "The input layer has {} geometries: choose a polygon layer."
                ).format(QgsWkbTypes.geometryDisplayString(kind).lower())
        chosen = self.parameterAsEnum(parameters, self.ELEVATION_SOURCE, context)
        source = self._elevation_kind(parameters, context)
        if chosen not in (elevation.ELEVATION_DEM, elevation.ELEVATION_AUTOMATIC) and (
            self._dem_given(parameters)
        ):
            return False, self.tr(
                "A DEM is given but the elevation source is not DEM: choose DEM (or "
                "Automatic) as the elevation source, or leave the DEM empty."
            )
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
            if layer_source is not None and not self._dem_overlaps(layer_source, layer, context):
                return False, self.tr(
                    "The DEM ({}) does not overlap the input layer: no vertex would get an "
                    "elevation. Check the DEM and the layers' CRSs."
                ).format(layer.name())
        refused = self._check_points(parameters, context, source)
        if refused:
            return False, refused
        path = self.parameterAsFileOutput(parameters, self.OUTPUT_MESH, context)
        if path and Path(path).suffix.lower().lstrip(".") not in MESH_EXTENSIONS:
            return False, self.tr(
                "The mesh file must end with .ply, .2dm, .glb, .gltf or .obj: {}"
            ).format(path)
        if not path and not self._wants_triangles(parameters):
            return False, self.tr("Nothing to write: choose a mesh file or the triangles output.")
        return True, ""

    def _check_points(
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        kind: int,
    ) -> str:
        """Why the interior point parameters cannot run together ("" when they can)."""
        tolerance = self.parameterAsDouble(parameters, self.MAX_VERTICAL_ERROR, context)
        if tolerance > 0 and kind != elevation.ELEVATION_DEM:
            return self.tr(
                "A maximum vertical error needs the DEM as the elevation source: choose a "
                "DEM, or set the maximum vertical error to 0."
            )
        points = self.parameterAsSource(parameters, self.INPUT_POINTS, context)
        z_field = self._points_z_field(parameters, context)
        if points is None:
            if z_field:
                return self.tr("A points Z field is given without input points.")
            return ""
        if z_field and points.fields().lookupField(z_field) < 0:
            return self.tr("The input points have no field {}.").format(z_field)
        if not z_field and not QgsWkbTypes.hasZ(points.wkbType()):
            return self.tr(
                "The input points have no Z: choose a points Z field with their elevation."
            )
        return ""

    def _points_z_field(self, parameters: dict[str, Any], context: QgsProcessingContext) -> str:
        if parameters.get(self.POINTS_Z_FIELD) in (None, ""):
            return ""
        # parameterAsStrings from QGIS 3.32 on; parameterAsFields is deprecated since 3.40
        read = getattr(self, "parameterAsStrings", None) or self.parameterAsFields
        fields = read(parameters, self.POINTS_Z_FIELD, context)
        return fields[0] if fields else ""

    def _dem_given(self, parameters: dict[str, Any]) -> bool:
        value = parameters.get(self.DEM)
        return value is not None and str(value) != ""

    def _elevation_kind(self, parameters: dict[str, Any], context: QgsProcessingContext) -> int:
        """The elevation source of the run: the chosen one, or the automatic one's pick."""
        kind = self.parameterAsEnum(parameters, self.ELEVATION_SOURCE, context)
        if kind != elevation.ELEVATION_AUTOMATIC:
            return kind
        if self._dem_given(parameters):
            return elevation.ELEVATION_DEM
        if self.parameterAsExpression(parameters, self.Z_EXPRESSION, context).strip():
            return elevation.ELEVATION_EXPRESSION
        return elevation.ELEVATION_GEOMETRY

    @staticmethod
    def _dem_overlaps(
        source: QgsProcessingFeatureSource, dem: QgsRasterLayer, context: QgsProcessingContext
    ) -> bool:
        """The DEM's extent meets the layer's (compared in the DEM's CRS); True when the
        extents cannot be compared."""
        extent = source.sourceExtent()
        if extent.isNull():
            return True
        crs, dem_crs = source.sourceCrs(), dem.crs()
        try:
            if crs.isValid() and dem_crs.isValid() and crs != dem_crs:
                transform = QgsCoordinateTransform(crs, dem_crs, context.transformContext())
                extent = transform.transformBoundingBox(extent)
        except Exception:  # a transform that fails cannot tell
            return True
        grown = QgsRectangle(extent)
        grown.grow(max(dem.rasterUnitsPerPixelX(), dem.rasterUnitsPerPixelY()))
        return grown.intersects(dem.extent())

    def _plane(
        self, source: QgsProcessingFeatureSource, kind: int, feedback: QgsProcessingFeedback
    ) -> str:
        """The engine's working plane: XY for draped elevations (DEM, expression, none) and
        for a layer whose x and y are not metres; steep faces only for the geometry's own Z
        in a projected CRS in metres."""
        if kind != elevation.ELEVATION_GEOMETRY:
            return "xy"
        crs = source.sourceCrs()
        if crs.isValid() and not crs.isGeographic() and (crs.mapUnits() == DistanceUnit.Meters):
            return "auto"
        if QgsWkbTypes.hasZ(source.wkbType()):
            feedback.pushInfo(
                self.tr(
                    "The layer's x and y are not in metres ({}), its Z presumably is: every "
                    "polygon is triangulated in XY, and no face is taken for a wall."
                ).format(crs.authid() or self.tr("no CRS"))
            )
        return "xy"

    def _wants_triangles(self, parameters: dict[str, Any]) -> bool:
        """Whether the per-triangle output was asked for (skipped when unset or empty)."""
        return self._destination(parameters, self.OUTPUT_TRIANGLES) != ""

    @staticmethod
    def _destination(parameters: dict[str, Any], name: str) -> str:
        """A sink's destination as given ("" when unset or skipped)."""
        value = parameters.get(name)
        if isinstance(value, QgsProcessingOutputLayerDefinition):
            value = value.sink.staticValue()
        return "" if value is None else str(value)

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
        if self._elevation_kind(parameters, context) == elevation.ELEVATION_DEM:
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
        feedback: QgsProcessingFeedback,
    ) -> elevation.ElevationSource:
        kind = self._elevation_kind(parameters, context)
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
            refining = self.parameterAsDouble(parameters, self.MAX_VERTICAL_ERROR, context) > 0
            try:
                sampler = elevation.DemSampler(
                    self._dem_provider,
                    self._dem_band(parameters, context),
                    method,
                    None if refining else transform,
                )
                if refining and transform is not None:
                    # the refinement needs the DEM's cells in the layer's CRS: the DEM is
                    # resampled there, and the rings are sampled on the same cells
                    sampler = WarpedDemSampler(
                        sampler,
                        crs,
                        self._dem_crs,
                        context.transformContext(),
                        source.sourceExtent().center(),
                    )
                    feedback.pushInfo(
                        self.tr(
                            "The DEM ({}) is resampled into the layer's CRS ({}) for the "
                            "maximum vertical error: {} cells of {:.6g} × {:.6g} layer units; "
                            "vertex z and the error are taken on these cells."
                        ).format(
                            self._dem_crs.authid() or self.tr("its CRS"),
                            crs.authid() or self.tr("its CRS"),
                            self.tr("bilinear") if method == "bilinear" else self.tr("nearest"),
                            sampler.dx,
                            sampler.dy,
                        )
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
        mesh_path = self.parameterAsFileOutput(parameters, self.OUTPUT_MESH, context)
        if mesh_path:
            try:
                Path(mesh_path).parent.mkdir(parents=True, exist_ok=True)
            except OSError as error:
                raise QgsProcessingException(
                    self.tr("Cannot create the mesh file's folder {}: {}").format(
                        Path(mesh_path).parent, error.strerror or error
                    )
                ) from error
        fields = triangle_fields(source.fields())
        cleanup = SinkCleanup(context)
        for name in (self.OUTPUT_TRIANGLES, self.OUTPUT_TREE):
            # the destination as given: parameterAsOutputLayer would register a second layer
            # to load on completion (a "memory:Triangles" that is never made)
            cleanup.note(self._destination(parameters, name))
        sink, triangles_id = self.parameterAsSink(
            parameters, self.OUTPUT_TRIANGLES, context, fields, WkbType.PolygonZ, crs
        )
        if sink is None and self._wants_triangles(parameters):
            raise QgsProcessingException(self.invalidSinkError(parameters, self.OUTPUT_TRIANGLES))
        if sink is not None:
            cleanup.track(triangles_id)
        tree_sink, tree_id = self.parameterAsSink(
            parameters, self.OUTPUT_TREE, context, tree_fields(), WkbType.LineStringZ, crs
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
        source_of_z = self._elevation_source(parameters, context, source, feedback)
        rule = APEX_RULES[self.parameterAsEnum(parameters, self.APEX_RULE, context)]
        tolerance = self.parameterAsDouble(parameters, self.PLANAR_TOLERANCE, context)
        max_length = self.parameterAsDouble(parameters, self.MAX_SEGMENT_LENGTH, context)
        z_scale = self.parameterAsDouble(parameters, self.Z_SCALE, context)
        z_offset = self.parameterAsDouble(parameters, self.Z_OFFSET, context)
        invalid_policy = self.parameterAsEnum(parameters, self.INVALID_POLYGONS, context)
        plane = self._plane(source, self._elevation_kind(parameters, context), feedback)
        # rings kept as given: the engine triangulates them even where no correct triangle exists
        options = EngineOptions(
            rule, tolerance, "as_given" if invalid_policy == INVALID_AS_GIVEN else "fail", plane
        )
        workers = self._worker_count(parameters, context, any(s is not None for s in sinks))
        runner = EngineRunner(
            options, workers, feedback, self.tr, self.CHUNK_FEATURES, self.CHUNK_VERTICES
        )

        interior = self._interior_points(
            parameters, context, source, source_of_z, options, feedback, runner
        )
        refining = interior is not None and interior.sampler is not None
        ellipsoid = _ellipsoid(crs)
        total = source.featureCount()
        progress = Progress(feedback, total, REFINE_STAGES if refining else None)
        report_path = self.parameterAsFileOutput(parameters, self.OUTPUT_REPORT, context)
        failures = FailureLog(feedback, self.tr, report_path or None)
        request = QgsFeatureRequest()
        # attributes are read only for the triangles' rows and a Z expression
        if sinks[0] is None and not isinstance(source_of_z, elevation.ExpressionElevation):
            request.setSubsetOfAttributes([])
        features = source.getFeatures(
            request, ProcessingFeatureSourceFlag.SkipGeometryValidityChecks
        )
        mesh = MeshAccumulator() if mesh_path else None
        tally = _Tally()
        reported_warnings: set[str] = set()
        writer = SinkWriter()

        def write(job: BatchJob) -> bool:
            """The job's results to the outputs; False when the run was cancelled."""
            size = len(job.batch)
            reported = [0.0]

            def report(fraction: float) -> None:
                progress.advance("engine", fraction * size - reported[0])
                reported[0] = fraction * size

            chunks = runner.finish(job, report)
            if chunks is None:
                return False
            report(1.0)
            batch = job.batch
            tally.read += size
            tally.repaired.extend(item.fid for item in batch if item.repaired)
            for item in batch:
                if item.error is not None:
                    tally.failed += 1
                    failures.add(item.fid, item.error)
            batch_mesh = BatchMesh.build(chunks)
            with_triangles = batch_mesh.feature_count()
            tally.triangulated += with_triangles
            tally.empty += sum(1 for item in batch if item.error is None) - with_triangles
            tally.triangles += len(batch_mesh)
            # the batch's features pass "write" in proportion to the triangles written
            per_triangle = size / max(len(batch_mesh), 1)
            sinks_used = [s for s in sinks if s is not None] or [None]
            share = per_triangle / len(sinks_used)
            for sink, chunks_of in (
                (sinks[0], triangle_feature_chunks(batch_mesh, fields, ellipsoid=ellipsoid)),
                (sinks[1], tree_feature_chunks(batch_mesh, lines)),
            ):
                if sink is not None:
                    counted = progress.counted("write", chunks_of, lambda c: len(c) * share)
                    writer.write(sink, counted)
            if feedback.isCanceled():
                return False
            if mesh is not None:
                mesh.add(batch_mesh)
            progress.done["write"] = tally.read
            progress.advance("write", 0)
            return True

        # with workers, a batch is written once the next one is read and submitted
        pending: list[BatchJob] = []
        try:
            for batch in feature_batches(
                progress.counted("read", features, lambda _feature: 1),
                invalid_policy,
                self.BATCH_FEATURES,
                self.BATCH_VERTICES,
                feedback,
                walls=plane == "auto",
            ):
                if feedback.isCanceled():
                    break
                if max_length > 0:
                    _densify(batch, max_length)
                for first in range(0, len(batch), self.ELEVATION_FEATURES):
                    part = batch[first : first + self.ELEVATION_FEATURES]
                    source_of_z.apply(part)
                    progress.advance("elevation", len(part))
                    if feedback.isCanceled():
                        break
                for warning in set(source_of_z.warnings) - reported_warnings:
                    feedback.pushInfo(self.tr("Elevation: {}").format(warning))
                    reported_warnings.add(warning)
                points = None
                if interior is not None:
                    try:
                        points = interior.for_batch(
                            batch,
                            failures.warn,
                            _stage_share(progress, "refine", len(batch)) if refining else _ignore,
                        )
                    except CancelledError:
                        break
                    scale_points(points, z_scale, z_offset)
                elevation.scale_z(batch, z_scale, z_offset)
                pending.append(runner.submit(batch, points))
                while len(pending) > runner.parallel and write(pending.pop(0)):
                    pass
                if feedback.isCanceled():
                    break
            while pending and not feedback.isCanceled() and write(pending.pop(0)):
                pass
            if feedback.isCanceled():
                raise self._cancelled()
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
            failures.close()

        read, triangulated, triangles = tally.read, tally.triangulated, tally.triangles
        failed, empty, repaired = tally.failed, tally.empty, tally.repaired
        if repaired:
            self._report_repaired(repaired, feedback)
        filled = getattr(source_of_z, "filled", 0)
        if filled:
            feedback.pushWarning(
                self.tr(
                    "{} feature(s) have vertices outside the DEM or on its nodata cells: their "
                    "z was filled from the nearest valid vertices along the ring (set "
                    "'Vertices on DEM nodata' to fail them instead)."
                ).format(filled)
            )
        results: dict[str, Any] = {
            self.FEATURE_COUNT: read,
            self.TRIANGLE_COUNT: triangles,
            self.FAILED_COUNT: failed,
            self.EMPTY_COUNT: empty,
            self.POINTS_ADDED: interior.added if interior is not None else 0,
        }
        if written is not None:
            vertex_count, face_count, dataset_files = written
            feedback.pushInfo(
                self.tr("Mesh {}: {} vertices, {} faces").format(
                    mesh_path, vertex_count, face_count
                )
            )
            results[self.OUTPUT_MESH] = mesh_path
            # without a project (qgis_process) nothing would take the layer: do not open it;
            # glTF and OBJ are models for other software, which QGIS does not open as meshes
            if face_count and context.project() is not None and not is_model(mesh_path):
                loaded = load_mesh_on_completion(
                    mesh_path, crs, context, self.OUTPUT_MESH, dataset_files
                )
                if not loaded:
                    feedback.pushWarning(
                        self.tr("The mesh file could not be opened as a mesh layer.")
                    )
        if report_path:
            results[self.OUTPUT_REPORT] = report_path
        feedback.pushInfo(
            self.tr("{} feature(s): {} triangulated, {} failed, {} empty; {} triangles").format(
                read, triangulated, failed, empty, triangles
            )
        )
        feedback.setProgress(100)
        return results

    def _interior_points(
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        source: QgsProcessingFeatureSource,
        source_of_z: elevation.ElevationSource,
        options: EngineOptions,
        feedback: QgsProcessingFeedback,
        runner: EngineRunner | None = None,
    ) -> InteriorPoints | None:
        """The run's interior points (survey points, DEM points), or None without them; the
        DEM points are added in the ``runner``'s workers when it uses them."""
        tolerance = self.parameterAsDouble(parameters, self.MAX_VERTICAL_ERROR, context)
        points_source = self.parameterAsSource(parameters, self.INPUT_POINTS, context)
        if tolerance <= 0 and points_source is None:
            return None
        survey = None
        if points_source is not None:
            transform = None
            crs, points_crs = source.sourceCrs(), points_source.sourceCrs()
            if crs.isValid() and points_crs.isValid() and crs != points_crs:
                transform = QgsCoordinateTransform(points_crs, crs, context.transformContext())
            try:
                survey, skipped = SurveyPoints.read(
                    points_source, self._points_z_field(parameters, context), transform, feedback
                )
            except CancelledError:
                raise self._cancelled() from None
            feedback.pushInfo(
                self.tr("Input points: {} read, {} without a z or a position left out.").format(
                    len(survey), skipped
                )
            )
        sampler = getattr(source_of_z, "sampler", None)
        if tolerance > 0 and (sampler is None or sampler.transform is not None):
            raise QgsProcessingException(
                self.tr("A maximum vertical error needs the DEM as the elevation source.")
            )
        max_points = self.parameterAsInt(parameters, self.MAX_POINTS, context)
        return InteriorPoints(survey, sampler, tolerance, max_points, options, feedback, runner)

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


def _ellipsoid(crs: QgsCoordinateReferenceSystem) -> tuple[float, float] | None:
    """(semi-major axis, flattening) of a geographic CRS's ellipsoid (WGS 84 when unknown);
    None for a projected CRS."""
    if not crs.isValid() or not crs.isGeographic():
        return None
    parameters = QgsEllipsoidUtils.ellipsoidParameters(crs.ellipsoidAcronym())
    if not parameters.valid or parameters.semiMajor <= 0:
        return WGS84
    return parameters.semiMajor, 1.0 - parameters.semiMinor / parameters.semiMajor


def _densify(batch: list[FeatureRings], max_length: float) -> None:
    """Split boundary edges longer than ``max_length`` (XY), in place on the batch."""
    for item in batch:
        if item.ok:
            item.parts = [[densify_ring(ring, max_length) for ring in part] for part in item.parts]


def _stage_share(progress: Progress, stage: str, size: int) -> Callable[[float], None]:
    """A callback that takes the share of ``size`` features done in ``stage``."""
    reported = [0.0]

    def report(share: float) -> None:
        progress.advance(stage, share * size - reported[0])
        reported[0] = share * size

    return report


def _ignore(_share: float) -> None:
    """A progress callback for work that has no stage of its own."""
