"""Processing algorithm ``bsptriangulate:buildings``: footprints to closed 3D building solids
(roof = the BSP triangulation, floor, walls), written as a 3D model, triangles and CityJSON."""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from qgis.core import (
    NULL,
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsExpression,
    QgsExpressionContext,
    QgsFeature,
    QgsFeatureRequest,
    QgsField,
    QgsFields,
    QgsGeometry,
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeatureSource,
    QgsProcessingFeedback,
    QgsProcessingOutputLayerDefinition,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterExpression,
    QgsProcessingParameterNumber,
    QgsRasterLayer,
)
from qgis.PyQt.QtCore import QCoreApplication
from qgis.PyQt.QtGui import QIcon

from ..bsp_triangulate.formats.cityjson import CityBuilding, write_cityjson
from ..bsp_triangulate.formats.mesh import write_ply
from ..bsp_triangulate.formats.models import write_model
from ..bsp_triangulate.formats.wkb import triangles_to_multipolygon_wkb
from ..bsp_triangulate.packed import PackedPolygons
from ..bsp_triangulate.solids import SURFACE_NAMES, build_solids
from ..bsp_triangulate.terrain.raster_sampling import fill_along_ring
from . import elevation
from .geometry_io import INVALID_AS_GIVEN, FeatureRings, feature_batches
from .outputs import SinkCleanup, add_features
from .parameters import (
    advanced,
    apex_rule,
    count_outputs,
    dem_and_band,
    file_destination,
    invalid_polygons,
    non_negative_double,
    polygon_sink,
    polygon_source,
)
from .qgis_compat import (
    FIELD_TYPES,
    ProcessingFeatureSourceFlag,
    ProcessingNumberParameterType,
    WkbType,
)

ICON = Path(__file__).resolve().parent.parent / "icons" / "buildings.svg"
APEX_RULES = ("first", "elevation", "delaunay")
MESH_FORMATS = ("glb", "gltf", "obj", "ply")
HEIGHT_EXPRESSION = 0
HEIGHT_ROOF_Z = 1
GROUND_DEM_LOWEST = 0
GROUND_DEM_VERTEX = 1
GROUND_CONSTANT = 2
GROUND_EXPRESSION = 3
MAX_LISTED = 200
# Byte order, type and part count of a WKB MultiPolygon.
_MULTI_HEADER = 9


def _new_field(name: str, kind: Any) -> QgsField:
    return QgsField(name, kind)


def building_fields(source_fields: QgsFields) -> QgsFields:
    """building_id, the source's attributes (clashing names and fid prefixed), part, surface."""
    taken = {"building_id", "fid", "part", "surface"}
    fields = QgsFields()
    fields.append(_new_field("building_id", FIELD_TYPES["LongLong"]))
    for source_field in source_fields:
        copy = QgsField(source_field)
        name = copy.name()
        while name.lower() in taken:
            name = "src_" + name
        copy.setName(name)
        taken.add(name.lower())
        fields.append(copy)
    fields.append(_new_field("part", FIELD_TYPES["Int"]))
    fields.append(_new_field("surface", FIELD_TYPES["String"]))
    return fields


def utm_crs(longitude: float, latitude: float) -> QgsCoordinateReferenceSystem:
    """The WGS 84 / UTM zone of a point."""
    zone = min(max(math.floor((longitude + 180.0) / 6.0) + 1, 1), 60)
    return QgsCoordinateReferenceSystem(f"EPSG:{(32700 if latitude < 0 else 32600) + zone}")


@dataclass
class _Model:
    """The solids of the run so far, as numpy blocks (joined at the end)."""

    vertices: list[np.ndarray] = field(default_factory=list)
    triangles: list[np.ndarray] = field(default_factory=list)
    building: list[np.ndarray] = field(default_factory=list)
    part: list[np.ndarray] = field(default_factory=list)
    surface: list[np.ndarray] = field(default_factory=list)
    depth: list[np.ndarray] = field(default_factory=list)
    # per building: fid, attributes, triangle count of each part
    buildings: list[tuple[int, dict, list[int]]] = field(default_factory=list)
    vertex_count: int = 0
    triangle_count: int = 0


@dataclass
class _Tally:
    read: int = 0
    built: int = 0
    failed: int = 0
    empty: int = 0
    triangles: int = 0
    repaired: list[int] = field(default_factory=list)


class BuildingsAlgorithm(QgsProcessingAlgorithm):
    """Extrudes footprints into closed, outward-oriented building solids (paper §5)."""

    INPUT = "INPUT"
    HEIGHT_SOURCE = "HEIGHT_SOURCE"
    HEIGHT = "HEIGHT"
    GROUND = "GROUND"
    GROUND_VALUE = "GROUND_VALUE"
    GROUND_EXPRESSION = "GROUND_EXPRESSION"
    DEM = "DEM"
    DEM_BAND = "DEM_BAND"
    ROOF_PLANAR_TOLERANCE = "ROOF_PLANAR_TOLERANCE"
    APEX_RULE = "APEX_RULE"
    INVALID_POLYGONS = "INVALID_POLYGONS"
    TARGET_CRS = "TARGET_CRS"
    OUTPUT_MESH = "OUTPUT_MESH"
    OUTPUT_TRIANGLES = "OUTPUT_TRIANGLES"
    OUTPUT_CITYJSON = "OUTPUT_CITYJSON"
    FEATURE_COUNT = "FEATURE_COUNT"
    BUILT_COUNT = "BUILT_COUNT"
    FAILED_COUNT = "FAILED_COUNT"
    EMPTY_COUNT = "EMPTY_COUNT"
    TRIANGLE_COUNT = "TRIANGLE_COUNT"

    BATCH_FEATURES = 20_000
    BATCH_VERTICES = 400_000

    def tr(self, text: str) -> str:
        return QCoreApplication.translate("BuildingsAlgorithm", text)

    def createInstance(self) -> BuildingsAlgorithm:  # noqa: N802 - QGIS API name
        return BuildingsAlgorithm()

    def name(self) -> str:
        return "buildings"

    def displayName(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr("Buildings to 3D solids")

    def group(self) -> str:
        return self.tr("Triangulation")

    def groupId(self) -> str:  # noqa: N802 - QGIS API name
        return "triangulation"

    def icon(self) -> QIcon:
        return QIcon(str(ICON))

    def tags(self) -> list[str]:
        return self.tr("buildings,3d,solid,extrude,lod1,gltf,glb,obj,cityjson,bsp").split(",")

    def shortDescription(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr("Turns building footprints into closed 3D solids (roof, walls, floor).")

    def shortHelpString(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr(
            "<p>Builds one closed, outward-oriented, watertight solid per building footprint "
            "(the paper's §5 building models): the roof is the footprint's BSP triangulation "
            "at roof height, the floor the same triangles at ground height, facing down, and "
            "the walls two triangles under every edge of every ring, courtyards (holes) "
            "included. Multi-part footprints give one solid per part.</p>"
            "<h3>Parameters</h3>"
            "<p><b>Footprints</b>: polygons or multipolygons. A layer in a geographic CRS "
            "(degrees) is reprojected to <b>Target CRS</b> if set, else to the DEM's CRS when "
            "that is projected, else to the UTM zone of the layer's centre; the log says "
            "which. All outputs are in that CRS.</p>"
            "<p><b>Height from</b>: <i>Height expression</i> (default): the roof is flat, "
            "<b>Height</b> metres (an expression or field; default 10) above the footprint's "
            "lowest ground. <i>Roof Z of the geometry</i>: the roof is at the footprint's own "
            "Z values (a sloped or digitised roof).</p>"
            "<p><b>Ground</b>: <i>DEM: lowest value under the footprint</i> (the lowest DEM "
            "value sampled, bilinear, at its vertices: a flat floor); <i>DEM: per vertex</i> "
            "(the floor follows the terrain, and so do the walls' feet; vertices off the DEM "
            "are filled from their neighbours along the ring); <i>Constant</i> (default, "
            "<b>Ground value</b>, default 0); <i>Expression</i> (<b>Ground expression</b>, per "
            "feature).</p>"
            "<p><b>DEM</b>, <b>DEM band</b> (default 1): the elevation raster (reprojected "
            "when its CRS differs).</p>"
            "<p><b>Roof planar tolerance</b> (default 0 = off): near-planar digitised roofs "
            "are snapped onto one plane when no vertex moves by more than this (paper §4.2).</p>"
            "<p><b>Apex rule</b>: <i>first</i> correct apex (default) or closest "
            "<i>elevation</i> (paper §4.1).</p>"
            "<p><b>Invalid polygons</b>: repair (default), fail the feature, or triangulate "
            "the rings as given (a solid whose triangles overlap then fails).</p>"
            "<h3>Outputs</h3>"
            "<p><b>3D model</b>: .glb (default), .gltf (with a .bin beside it), .obj (with "
            ".origin.json and .prj) or .ply. glTF is Y-up: a map point (x, y, z) is written as "
            "(x, z, -y), relative to a local origin kept at full precision as the node's "
            "translation; each face carries building_id and surface (0 roof, 1 wall, 2 floor) "
            "as EXT_mesh_features feature IDs. OBJ groups the faces by building and surface.</p>"
            "<p><b>Triangles</b> (optional): one PolygonZ per triangle with building_id, the "
            "footprint's attributes (clashing names prefixed with src_), part and surface "
            "(roof, wall or floor).</p>"
            "<p><b>CityJSON</b> (optional, .city.json): CityJSON 2.0, one Building per "
            "footprint with an LoD1 Solid (BuildingPart children for multi-part footprints), "
            "semantics RoofSurface / WallSurface / GroundSurface, the CRS as referenceSystem, "
            "vertices quantised to millimetres.</p>"
            "<p>A footprint that cannot be built (it cannot be triangulated, the roof is not "
            "above the ground, no height or ground value) is reported with its id and reason "
            "and counted in FAILED_COUNT; null and empty geometries in EMPTY_COUNT. "
            "FEATURE_COUNT = BUILT_COUNT + FAILED_COUNT + EMPTY_COUNT. A cancelled run writes "
            "no model or CityJSON file and deletes the triangles it created.</p>"
        )

    def initAlgorithm(self, config: dict[str, Any] | None = None) -> None:  # noqa: N802
        declared = [
            polygon_source(self.INPUT, self.tr("Footprints")),
            QgsProcessingParameterEnum(
                self.HEIGHT_SOURCE,
                self.tr("Height from"),
                [
                    self.tr("Height expression (above the ground)"),
                    self.tr("Roof Z of the geometry"),
                ],
                defaultValue=HEIGHT_EXPRESSION,
            ),
            QgsProcessingParameterExpression(
                self.HEIGHT,
                self.tr("Height (metres above ground)"),
                defaultValue="10",
                parentLayerParameterName=self.INPUT,
                optional=True,
            ),
            QgsProcessingParameterEnum(
                self.GROUND,
                self.tr("Ground"),
                [
                    self.tr("DEM: lowest value under the footprint"),
                    self.tr("DEM: per vertex (walls follow the terrain)"),
                    self.tr("Constant"),
                    self.tr("Expression"),
                ],
                defaultValue=GROUND_CONSTANT,
            ),
            QgsProcessingParameterNumber(
                self.GROUND_VALUE,
                self.tr("Ground value"),
                ProcessingNumberParameterType.Double,
                defaultValue=0.0,
            ),
            QgsProcessingParameterExpression(
                self.GROUND_EXPRESSION,
                self.tr("Ground expression"),
                parentLayerParameterName=self.INPUT,
                optional=True,
            ),
            *dem_and_band(self.DEM, self.DEM_BAND, self.tr),
            *advanced(
                [
                    non_negative_double(
                        self.ROOF_PLANAR_TOLERANCE, self.tr("Roof planar tolerance (0 = off)")
                    ),
                    apex_rule(self.APEX_RULE, self.tr),
                    invalid_polygons(
                        self.INVALID_POLYGONS, self.tr("Repair (make valid), then build"), self.tr
                    ),
                    QgsProcessingParameterCrs(
                        self.TARGET_CRS, self.tr("Target CRS for a geographic layer"), optional=True
                    ),
                ]
            ),
            file_destination(
                self.OUTPUT_MESH,
                self.tr("3D model"),
                self.tr(
                    "Binary glTF (*.glb);;glTF (*.gltf);;Wavefront OBJ (*.obj);;PLY mesh (*.ply)"
                ),
                create_by_default=True,
            ),
            polygon_sink(self.OUTPUT_TRIANGLES, self.tr("Triangles"), create_by_default=False),
            file_destination(
                self.OUTPUT_CITYJSON,
                self.tr("CityJSON"),
                self.tr("CityJSON (*.city.json *.json)"),
                create_by_default=False,
            ),
        ]
        for parameter in declared:
            self.addParameter(parameter)
        for output in count_outputs(
            [
                (self.FEATURE_COUNT, self.tr("Features read")),
                (self.BUILT_COUNT, self.tr("Buildings built")),
                (self.FAILED_COUNT, self.tr("Failed features")),
                (self.EMPTY_COUNT, self.tr("Empty features")),
                (self.TRIANGLE_COUNT, self.tr("Triangles")),
            ]
        ):
            self.addOutput(output)

    # -- checks -------------------------------------------------------------------------

    def _wants(self, parameters: dict[str, Any], name: str) -> bool:
        value = parameters.get(name)
        if isinstance(value, QgsProcessingOutputLayerDefinition):
            value = value.sink.staticValue()
        return value is not None and str(value) != ""

    def checkParameterValues(  # noqa: N802 - QGIS API name
        self, parameters: dict[str, Any], context: QgsProcessingContext
    ) -> tuple[bool, str]:
        ok, message = super().checkParameterValues(parameters, context)
        if not ok:
            return ok, message
        if self.parameterAsEnum(parameters, self.HEIGHT_SOURCE, context) == HEIGHT_EXPRESSION:
            problem = self._expression_problem(parameters, self.HEIGHT, context, "Height")
            if problem:
                return False, problem
        ground = self.parameterAsEnum(parameters, self.GROUND, context)
        if ground == GROUND_EXPRESSION:
            problem = self._expression_problem(
                parameters, self.GROUND_EXPRESSION, context, "Ground expression"
            )
            if problem:
                return False, problem
        if ground in (GROUND_DEM_LOWEST, GROUND_DEM_VERTEX):
            layer = self.parameterAsRasterLayer(parameters, self.DEM, context)
            if layer is None:
                return False, self.tr("The ground is taken from a DEM: choose a DEM raster.")
            band = self._dem_band(parameters, context)
            if not 1 <= band <= layer.bandCount():
                return False, self.tr("DEM band {} does not exist: the DEM has {} band(s).").format(
                    band, layer.bandCount()
                )
        path = self.parameterAsFileOutput(parameters, self.OUTPUT_MESH, context)
        if path and Path(path).suffix.lower().lstrip(".") not in MESH_FORMATS:
            return False, self.tr(
                "The 3D model must end with .glb, .gltf, .obj or .ply: {}"
            ).format(path)
        if (
            not path
            and not self._wants(parameters, self.OUTPUT_TRIANGLES)
            and not (self.parameterAsFileOutput(parameters, self.OUTPUT_CITYJSON, context))
        ):
            return False, self.tr("Nothing to write: choose a 3D model, triangles or CityJSON.")
        return True, ""

    def _expression_problem(
        self, parameters: dict[str, Any], name: str, context: QgsProcessingContext, label: str
    ) -> str:
        text = self.parameterAsExpression(parameters, name, context)
        if not text.strip():
            return self.tr("{}: set an expression or a field.").format(label)
        expression = QgsExpression(text)
        if expression.hasParserError():
            return self.tr("{}: {}").format(label, expression.parserErrorString())
        return ""

    def _dem_band(self, parameters: dict[str, Any], context: QgsProcessingContext) -> int:
        if parameters.get(self.DEM_BAND) is None:
            return 1
        return self.parameterAsInt(parameters, self.DEM_BAND, context)

    def prepareAlgorithm(  # noqa: N802 - QGIS API name
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        feedback: QgsProcessingFeedback,
    ) -> bool:
        # the raster provider is cloned here, on the thread that owns the layer
        self._dem_provider = None
        self._dem_crs = QgsCoordinateReferenceSystem()
        layer: QgsRasterLayer | None = self.parameterAsRasterLayer(parameters, self.DEM, context)
        ground = self.parameterAsEnum(parameters, self.GROUND, context)
        if ground in (GROUND_DEM_LOWEST, GROUND_DEM_VERTEX):
            if layer is None or not layer.isValid():
                raise QgsProcessingException(self.invalidRasterError(parameters, self.DEM))
            self._dem_provider = layer.dataProvider().clone()
        if layer is not None and layer.isValid():
            self._dem_crs = layer.crs()
        return True

    # -- run --------------------------------------------------------------------------

    def _target_crs(
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        source: QgsProcessingFeatureSource,
        feedback: QgsProcessingFeedback,
    ) -> QgsCoordinateReferenceSystem:
        """The CRS of the outputs: the layer's, or a projected one for a geographic layer."""
        crs = source.sourceCrs()
        if not crs.isValid() or not crs.isGeographic():
            return crs
        target = self.parameterAsCrs(parameters, self.TARGET_CRS, context)
        reason = self.tr("the target CRS")
        if not target.isValid() or target.isGeographic():
            if self._dem_crs.isValid() and not self._dem_crs.isGeographic():
                target, reason = self._dem_crs, self.tr("the DEM's CRS")
            else:
                extent = source.sourceExtent()
                centre = extent.center()
                target = utm_crs(centre.x(), centre.y())
                reason = self.tr("the UTM zone of the layer's centre")
        feedback.pushInfo(
            self.tr("The footprints are in a geographic CRS ({}): reprojected to {} ({}).").format(
                crs.authid() or crs.description(), target.authid(), reason
            )
        )
        return target

    def processAlgorithm(  # noqa: N802 - QGIS API name
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        feedback: QgsProcessingFeedback,
    ) -> dict[str, Any]:
        source = self.parameterAsSource(parameters, self.INPUT, context)
        if source is None:
            raise QgsProcessingException(self.invalidSourceError(parameters, self.INPUT))
        crs = self._target_crs(parameters, context, source, feedback)
        fields = building_fields(source.fields())
        cleanup = SinkCleanup(context)
        cleanup.note(self.parameterAsOutputLayer(parameters, self.OUTPUT_TRIANGLES, context))
        sink, triangles_id = self.parameterAsSink(
            parameters, self.OUTPUT_TRIANGLES, context, fields, WkbType.PolygonZ, crs
        )
        if sink is None and self._wants(parameters, self.OUTPUT_TRIANGLES):
            raise QgsProcessingException(self.invalidSinkError(parameters, self.OUTPUT_TRIANGLES))
        if sink is not None:
            cleanup.track(triangles_id)
        sinks = [sink]
        del sink
        try:
            results = self._process(parameters, context, feedback, source, crs, sinks, fields)
        except BaseException as error:
            sinks.clear()
            traceback.clear_frames(error.__traceback__)
            cleanup.remove()
            raise
        if triangles_id:
            results[self.OUTPUT_TRIANGLES] = triangles_id
        return results

    def _cancelled(self) -> QgsProcessingException:
        return QgsProcessingException(self.tr("Cancelled: no output was written."))

    def _process(
        self,
        parameters: dict[str, Any],
        context: QgsProcessingContext,
        feedback: QgsProcessingFeedback,
        source: QgsProcessingFeatureSource,
        crs: QgsCoordinateReferenceSystem,
        sinks: list,
        fields: QgsFields,
    ) -> dict[str, Any]:
        mesh_path = self.parameterAsFileOutput(parameters, self.OUTPUT_MESH, context)
        city_path = self.parameterAsFileOutput(parameters, self.OUTPUT_CITYJSON, context)
        rule = APEX_RULES[self.parameterAsEnum(parameters, self.APEX_RULE, context)]
        tolerance = self.parameterAsDouble(parameters, self.ROOF_PLANAR_TOLERANCE, context)
        invalid_policy = self.parameterAsEnum(parameters, self.INVALID_POLYGONS, context)
        invalid = "as_given" if invalid_policy == INVALID_AS_GIVEN else "fail"
        height_source = self.parameterAsEnum(parameters, self.HEIGHT_SOURCE, context)
        ground_kind = self.parameterAsEnum(parameters, self.GROUND, context)
        expression_context = self.createExpressionContext(parameters, context, source)
        height = None
        if height_source == HEIGHT_EXPRESSION:
            height = self._expression(parameters, self.HEIGHT, context, expression_context)
        ground_expression = None
        if ground_kind == GROUND_EXPRESSION:
            ground_expression = self._expression(
                parameters, self.GROUND_EXPRESSION, context, expression_context
            )
        ground_value = self.parameterAsDouble(parameters, self.GROUND_VALUE, context)
        sampler = None
        if ground_kind in (GROUND_DEM_LOWEST, GROUND_DEM_VERTEX):
            transform = None
            if crs.isValid() and self._dem_crs.isValid() and crs != self._dem_crs:
                transform = QgsCoordinateTransform(crs, self._dem_crs, context.transformContext())
            try:
                sampler = elevation.DemSampler(
                    self._dem_provider, self._dem_band(parameters, context), "bilinear", transform
                )
            except ValueError as error:
                raise QgsProcessingException(self.tr("DEM: {}").format(error)) from error

        request = QgsFeatureRequest()
        if crs != source.sourceCrs():
            request.setDestinationCrs(crs, context.transformContext())
        features = source.getFeatures(
            request, ProcessingFeatureSourceFlag.SkipGeometryValidityChecks
        )
        total = source.featureCount()
        step = 100.0 / total if total > 0 else 0.0
        model = _Model()
        tally = _Tally()
        keep_attributes = bool(city_path)
        for batch in feature_batches(
            features, invalid_policy, self.BATCH_FEATURES, self.BATCH_VERTICES, feedback
        ):
            if feedback.isCanceled():
                break
            tally.read += len(batch)
            tally.repaired.extend(item.fid for item in batch if item.repaired)
            ground = self._ground(
                batch, ground_kind, ground_value, ground_expression, sampler, expression_context
            )
            self._roofs(batch, height, ground, expression_context)
            built = self._build(batch, ground, rule, tolerance, invalid)
            made = self._collect(built, model, keep_attributes)
            tally.triangles = model.triangle_count
            for item in batch:
                if item.error is not None:
                    tally.failed += 1
                    feedback.reportError(
                        self.tr("Feature {}: {}").format(item.fid, item.error), False
                    )
                elif id(item) in made:
                    tally.built += 1
                else:  # null or empty geometry, or a footprint without area
                    tally.empty += 1
            if sinks[0] is not None:
                self._write_triangles(sinks[0], built, fields)
            feedback.setProgress(min(tally.read * step, 99.0))
        if feedback.isCanceled():
            raise self._cancelled()
        sinks.clear()  # closes the triangles' sink (a GeoPackage builds its index here)
        if feedback.isCanceled():
            raise self._cancelled()
        results: dict[str, Any] = {}
        staged: list[tuple[Path, Path]] = []
        try:
            if mesh_path or city_path:
                vertices, triangles, columns = self._joined(model)
                if mesh_path:
                    staged += self._stage_mesh(mesh_path, vertices, triangles, columns, crs)
                    results[self.OUTPUT_MESH] = mesh_path
                if feedback.isCanceled():
                    raise self._cancelled()
                if city_path:
                    staged += self._stage_cityjson(
                        city_path, vertices, triangles, columns, model, crs, feedback
                    )
                    results[self.OUTPUT_CITYJSON] = city_path
            if feedback.isCanceled():
                raise self._cancelled()
            for temporary, target in staged:
                os.replace(temporary, target)
        finally:
            # the hidden staging folders, with whatever a failed or cancelled run left there
            for folder in {temporary.parent for temporary, _target in staged}:
                for leftover in folder.iterdir():
                    leftover.unlink(missing_ok=True)
                with contextlib.suppress(OSError):
                    folder.rmdir()
        if tally.repaired:
            listed = ", ".join(str(fid) for fid in tally.repaired[:MAX_LISTED])
            feedback.pushWarning(
                self.tr("Repaired invalid geometries of {} feature(s): {}").format(
                    len(tally.repaired), listed
                )
            )
        feedback.pushInfo(
            self.tr("{} feature(s): {} built, {} failed, {} empty; {} triangles").format(
                tally.read, tally.built, tally.failed, tally.empty, tally.triangles
            )
        )
        feedback.setProgress(100)
        results.update(
            {
                self.FEATURE_COUNT: tally.read,
                self.BUILT_COUNT: tally.built,
                self.FAILED_COUNT: tally.failed,
                self.EMPTY_COUNT: tally.empty,
                self.TRIANGLE_COUNT: tally.triangles,
            }
        )
        return results

    # -- heights ------------------------------------------------------------------------

    def _expression(
        self,
        parameters: dict[str, Any],
        name: str,
        context: QgsProcessingContext,
        expression_context: QgsExpressionContext,
    ) -> QgsExpression:
        text = self.parameterAsExpression(parameters, name, context)
        expression = QgsExpression(text)
        if not text.strip() or expression.hasParserError():
            raise QgsProcessingException(
                self.tr("{}: {}").format(name, expression.parserErrorString() or self.tr("empty"))
            )
        expression.prepare(expression_context)
        return expression

    def _value(
        self,
        expression: QgsExpression,
        context: QgsExpressionContext,
        item: FeatureRings,
        label: str,
    ) -> float | str:
        """The expression's number for a feature, or the reason there is none."""
        context.setFeature(item.feature)
        value = expression.evaluate(context)
        if expression.hasEvalError():
            return self.tr("{} expression error: {}").format(label, expression.evalErrorString())
        if value is None or value == NULL:
            return self.tr("{} is NULL").format(label)
        try:
            number = float(value)
        except (TypeError, ValueError):
            return self.tr("{} is {!r}, not a number").format(label, value)
        if not math.isfinite(number):
            return self.tr("{} is {}").format(label, number)
        return number

    def _ground(
        self,
        batch: list[FeatureRings],
        kind: int,
        constant: float,
        expression: QgsExpression | None,
        sampler: elevation.DemSampler | None,
        context: QgsExpressionContext,
    ) -> dict[int, float | list[list[np.ndarray]]]:
        """Per usable item (by position in the batch): its ground z, or (per-vertex DEM) one
        array of ground z per ring of each part. Items without one get an error."""
        out: dict[int, float | list[list[np.ndarray]]] = {}
        usable = [(index, item) for index, item in enumerate(batch) if item.ok]
        if kind == GROUND_CONSTANT:
            return {index: constant for index, _item in usable}
        if kind == GROUND_EXPRESSION:
            for index, item in usable:
                value = self._value(expression, context, item, self.tr("Ground"))
                if isinstance(value, str):
                    item.error = value
                else:
                    out[index] = value
            return out
        rings = [ring for _index, item in usable for part in item.parts for ring in part]
        if not rings:
            return out
        xy = np.concatenate([ring[:, :2] for ring in rings])
        values = sampler.sample(xy)
        position = 0
        for index, item in usable:
            per_part = []
            for part in item.parts:
                per_ring = []
                for ring in part:
                    per_ring.append(values[position : position + len(ring)])
                    position += len(ring)
                per_part.append(per_ring)
            flat = np.concatenate([z for part in per_part for z in part])
            if np.isnan(flat).all():
                item.error = self.tr("no vertex of the footprint lies on a valid DEM cell")
                continue
            if kind == GROUND_DEM_LOWEST:
                out[index] = float(np.nanmin(flat))
                continue
            filled = []
            for part, z_part in zip(item.parts, per_part):
                rings_z = []
                for ring, z in zip(part, z_part):
                    if np.isnan(z).all():
                        rings_z = None
                        break
                    rings_z.append(fill_along_ring(z, ring[:, :2]) if np.isnan(z).any() else z)
                if rings_z is None:
                    item.error = self.tr("no vertex of a ring lies on a valid DEM cell")
                    break
                filled.append(rings_z)
            if item.error is None:
                out[index] = filled
        return out

    def _roofs(
        self,
        batch: list[FeatureRings],
        height: QgsExpression | None,
        ground: dict,
        context: QgsExpressionContext,
    ) -> None:
        """Set every usable ring's z to its roof z (in place)."""
        for index, item in enumerate(batch):
            if not item.ok or index not in ground:
                continue
            if height is None:  # the roof's own Z
                if not item.has_z:
                    item.error = self.tr("the footprint has no Z values for the roof")
                    continue
                if any(not np.isfinite(ring[:, 2]).all() for part in item.parts for ring in part):
                    item.error = self.tr("a roof vertex has no Z value")
                continue
            value = self._value(height, context, item, self.tr("Height"))
            if isinstance(value, str):
                item.error = value
                continue
            base = ground[index]
            if not isinstance(base, float):  # per vertex: a flat roof above the lowest
                base = float(min(z.min() for part in base for z in part))
            for part in item.parts:
                for ring in part:
                    ring[:, 2] = base + value

    def _build(
        self, batch: list[FeatureRings], ground: dict, rule: str, tolerance: float, invalid: str
    ) -> _Built:
        """Solids of the batch's usable items (failures set on their items)."""
        chosen = [(i, item) for i, item in enumerate(batch) if item.ok and i in ground]
        built = _Built(batch, [item for _i, item in chosen])
        if not chosen:
            return built
        parts = [part for _i, item in chosen for part in item.parts]
        part_count = np.array([len(item.parts) for _i, item in chosen], dtype=np.int64)
        rings = [ring for part in parts for ring in part]
        polygons = PackedPolygons(
            np.concatenate(rings),
            np.fromiter((len(r) for r in rings), np.int64, len(rings)),
            np.fromiter((len(p) for p in parts), np.int64, len(parts)),
        )
        ground_of = [ground[i] for i, _item in chosen]
        if all(isinstance(g, float) for g in ground_of):
            solids = build_solids(
                polygons,
                np.repeat(np.array(ground_of, dtype=np.float64), part_count),
                rule=rule,
                planar_tolerance=tolerance,
                invalid=invalid,
            )
        else:
            points = np.concatenate([z for g in ground_of for part in g for z in part])
            solids = build_solids(
                polygons, ground_points=points, rule=rule, planar_tolerance=tolerance,
                invalid=invalid,
            )  # fmt: skip
        owner = np.repeat(np.arange(len(chosen)), part_count)
        for part_index, reason in solids.errors.items():
            item = built.items[int(owner[part_index])]
            if item.error is None:
                item.error = reason
        built.solids = solids
        built.owner = owner
        built.part = np.concatenate(
            [np.arange(count, dtype=np.int64) for count in part_count.tolist()]
        )
        return built

    # -- outputs -------------------------------------------------------------------------

    def _collect(self, built: _Built, model: _Model, attributes: bool) -> set[int]:
        """Solids of the items that did not fail to the model; the ids (``id()``) of the items
        with a solid."""
        solids = built.solids
        if solids is None:
            return set()
        failed = np.array([item.error is not None for item in built.items], dtype=bool)
        per_item = np.bincount(
            built.owner, weights=solids.triangle_count, minlength=len(built.items)
        )
        has = (per_item > 0) & ~failed
        face_owner = built.owner[solids.solid]
        keep = has[face_owner]
        built.keep = keep
        if not keep.any():
            return set()
        triangles = solids.triangles[keep]
        used = np.unique(triangles)
        rank = np.full(len(solids.vertices), -1, dtype=np.int64)
        rank[used] = np.arange(len(used))
        vertices = solids.vertices[used]
        fids = np.array([item.fid for item in built.items], dtype=np.int64)
        model.vertices.append(vertices)
        model.triangles.append(rank[triangles] + model.vertex_count)
        model.building.append(fids[face_owner[keep]])
        model.part.append(built.part[solids.solid[keep]])
        model.surface.append(solids.surface[keep])
        model.depth.append(solids.depth[keep])
        model.vertex_count += len(vertices)
        model.triangle_count += int(keep.sum())
        counts = solids.triangle_count
        for index in np.flatnonzero(has).tolist():
            item = built.items[index]
            part_counts = counts[built.owner == index].tolist()
            values = _attribute_values(item) if attributes else {}
            model.buildings.append((item.fid, values, part_counts))
        return {id(built.items[index]) for index in np.flatnonzero(has).tolist()}

    def _write_triangles(self, sink, built: _Built, fields: QgsFields) -> None:
        solids = built.solids
        if solids is None or built.keep is None or not built.keep.any():
            return
        keep = built.keep
        triangles = solids.triangles[keep]
        owner = built.owner[solids.solid[keep]]
        part = built.part[solids.solid[keep]].tolist()
        surface = [SURFACE_NAMES[s] for s in solids.surface[keep].tolist()]
        heads = [[item.fid, *item.feature.attributes()] for item in built.items]
        chunk = 20_000
        for start in range(0, len(triangles), chunk):
            rows = slice(start, start + chunk)
            buffer = triangles_to_multipolygon_wkb(solids.vertices, triangles[rows])
            size = (len(buffer) - _MULTI_HEADER) // len(triangles[rows])
            wkbs = [
                buffer[offset : offset + size] for offset in range(_MULTI_HEADER, len(buffer), size)
            ]
            tails = list(zip(part[rows], surface[rows]))
            add_features(
                sink,
                _triangle_features(fields, wkbs, [heads[o] for o in owner[rows].tolist()], tails),
            )

    def _joined(self, model: _Model) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        def join(blocks, shape, dtype):
            """The blocks one after another; the list is emptied (parts and whole are not
            held at once longer than the copy)."""
            joined = np.concatenate(blocks) if blocks else np.zeros(shape, dtype)
            blocks.clear()
            return joined

        vertices = join(model.vertices, (0, 3), np.float64)
        index_type = np.int32 if model.vertex_count < 2**31 else np.int64
        triangles = join(model.triangles, (0, 3), np.int64).astype(index_type)
        columns = {
            "building_id": join(model.building, (0,), np.int64),
            "part": join(model.part, (0,), np.int64).astype(np.int32),
            "surface": join(model.surface, (0,), np.int8),
            "depth": join(model.depth, (0,), np.int64).astype(np.int32),
        }
        return vertices, triangles, columns

    def _stage_mesh(
        self,
        path: str,
        vertices: np.ndarray,
        triangles: np.ndarray,
        columns: dict[str, np.ndarray],
        crs: QgsCoordinateReferenceSystem,
    ) -> list[tuple[Path, Path]]:
        """The model written into a hidden folder beside ``path``: (written, target) pairs."""
        target = Path(path).absolute()
        folder = Path(
            tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
        )
        wkt = crs.toWkt() if crs.isValid() else None
        values = {"building_id": columns["building_id"], "surface": columns["surface"]}
        try:
            if target.suffix.lower() == ".ply":
                values["part"] = columns["part"]
                written = [write_ply(folder / target.name, vertices, triangles, values, True, wkt)]
            elif target.suffix.lower() == ".obj":
                written = write_model(
                    folder / target.name, vertices, triangles, values, wkt,
                    group_by=["building_id", "surface"], labels={"surface": SURFACE_NAMES},
                )  # fmt: skip
            else:
                written = write_model(folder / target.name, vertices, triangles, values, wkt)
        except BaseException:
            for file in folder.iterdir():
                file.unlink()
            folder.rmdir()
            raise
        # sidecars first, the model last: a model file in place always has its sidecars
        return [(file, target.with_name(file.name)) for file in [*written[1:], written[0]]]

    def _stage_cityjson(
        self,
        path: str,
        vertices: np.ndarray,
        triangles: np.ndarray,
        columns: dict[str, np.ndarray],
        model: _Model,
        crs: QgsCoordinateReferenceSystem,
        feedback: QgsProcessingFeedback,
    ) -> list[tuple[Path, Path]]:
        target = Path(path).absolute()
        folder = Path(
            tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
        )
        epsg = None
        authid = crs.authid() if crs.isValid() else ""
        if authid.upper().startswith("EPSG:"):
            epsg = int(authid.split(":")[1])
        else:
            feedback.pushWarning(
                self.tr("CityJSON: the CRS has no EPSG code; no referenceSystem is written.")
            )
        buildings = []
        start = 0
        for fid, attributes, part_counts in model.buildings:
            parts = []
            for count in part_counts:
                parts.append(np.arange(start, start + count, dtype=np.int64))
                start += count
            buildings.append(CityBuilding(str(fid), parts, attributes))
        try:
            written = write_cityjson(
                folder / target.name, vertices, triangles, columns["surface"], buildings, epsg
            )
        except BaseException:
            for file in folder.iterdir():
                file.unlink()
            folder.rmdir()
            raise
        return [(written, target)]


@dataclass(eq=False)
class _Built:
    """The solids of one batch: ``items`` (usable ones, in order), their parts' solids
    (``owner``: the item of each part, ``part``: its index in the item), and the triangles
    kept (``keep``: of items that did not fail)."""

    batch: list[FeatureRings]
    items: list[FeatureRings]
    solids: Any = None
    owner: np.ndarray | None = None
    part: np.ndarray | None = None
    keep: np.ndarray | None = None


def _triangle_features(
    fields: QgsFields, wkbs: list[bytes], heads: list[list], tails: list[tuple]
) -> list[QgsFeature]:
    """Features of WKB geometries with the attributes ``head + tail``."""
    features = []
    for wkb, head, tail in zip(wkbs, heads, tails):
        feature = QgsFeature(fields)
        geometry = QgsGeometry()
        geometry.fromWkb(wkb)
        feature.setGeometry(geometry)
        feature.setAttributes(head + list(tail))
        features.append(feature)
    return features


def _attribute_values(item: FeatureRings) -> dict:
    feature = item.feature
    names = feature.fields().names()
    values = {}
    for name, value in zip(names, feature.attributes()):
        if value is None or value == NULL:
            values[name] = None
        elif isinstance(value, (bool, int, float, str)):
            values[name] = value
        else:
            values[name] = str(value)
    return values
