"""Outputs of the triangulation: triangle features, tree lines, the mesh file and its loading."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from qgis.core import (
    Qgis,
    QgsCoordinateReferenceSystem,
    QgsFeature,
    QgsFeatureSink,
    QgsField,
    QgsFields,
    QgsGeometry,
    QgsGraduatedSymbolRenderer,
    QgsMapLayer,
    QgsMeshLayer,
    QgsProcessingContext,
    QgsProcessingFeedback,
    QgsProcessingLayerPostProcessorInterface,
    QgsProcessingUtils,
    QgsVectorLayer,
)
from qgis.PyQt.QtCore import QMetaType, QVariant

from ..bsp_triangulate import metrics
from ..bsp_triangulate.mesh import merge_meshes, write_2dm, write_ply
from ..bsp_triangulate.triangulation import Triangulation
from ..bsp_triangulate.wkb import triangles_to_wkb
from .geometry_io import FeatureRings

STYLE_PATH = Path(__file__).resolve().parent / "styles" / "triangles.qml"
MESH_EXTENSIONS = ("2dm", "ply")
SOURCE_PREFIX = "src_"

TRIANGLE_FIELDS = (
    ("part", "Int"),
    ("order", "Int"),
    ("parent", "Int"),
    ("depth", "Int"),
    ("side", "Int"),
    ("area_2d", "Double"),
    ("area_3d", "Double"),
    ("min_angle", "Double"),
    ("slope", "Double"),
    ("aspect", "Double"),
)
TREE_FIELDS = (
    ("feature_id", "LongLong"),
    ("part", "Int"),
    ("parent", "Int"),
    ("child", "Int"),
    ("side", "Int"),
)

# One little-endian ISO LineStringZ (type 1002) with two points: 57 bytes, no padding.
_LINE_DTYPE = np.dtype(
    [("order", "u1"), ("type", "<u4"), ("count", "<u4"), ("points", "<f8", (2, 3))]
)


@dataclass
class BatchMesh:
    """The triangles of a batch of features, concatenated, with their tree attributes."""

    vertices: np.ndarray  # (V, 3)
    triangles: np.ndarray  # (M, 3) into vertices
    item: np.ndarray  # (M,) index into ``items``
    part: np.ndarray
    order: np.ndarray  # index in the part's BSP pre-order
    parent: np.ndarray  # parent's order, -1 for the root
    depth: np.ndarray
    side: np.ndarray
    items: list[FeatureRings]

    @property
    def fid(self) -> np.ndarray:
        fids = np.array([item.fid for item in self.items], dtype=np.int64)
        return fids[self.item] if len(fids) else np.zeros(0, np.int64)

    @classmethod
    def build(cls, results: list[tuple[FeatureRings, list[Triangulation]]]) -> BatchMesh:
        """Concatenate the triangulations of the parts of each feature."""
        vertices, triangles, item, part, order, parent, depth, side = ([] for _ in range(8))
        offset = 0
        for row, (_feature, parts) in enumerate(results):
            for index, tri in enumerate(parts):
                count = len(tri.triangles)
                if not count:
                    continue
                vertices.append(np.asarray(tri.vertices, dtype=np.float64))
                triangles.append(np.asarray(tri.triangles, dtype=np.int64) + offset)
                offset += len(tri.vertices)
                item.append(np.full(count, row, np.int64))
                part.append(np.full(count, index, np.int64))
                order.append(np.arange(count, dtype=np.int64))
                parent.append(np.asarray(tri.parent, dtype=np.int64))
                depth.append(np.asarray(tri.depth, dtype=np.int64))
                side.append(np.asarray(tri.side, dtype=np.int64))

        def joined(arrays: list[np.ndarray], shape: tuple[int, ...], dtype) -> np.ndarray:
            return np.concatenate(arrays) if arrays else np.zeros(shape, dtype)

        return cls(
            vertices=joined(vertices, (0, 3), np.float64),
            triangles=joined(triangles, (0, 3), np.int64),
            item=joined(item, (0,), np.int64),
            part=joined(part, (0,), np.int64),
            order=joined(order, (0,), np.int64),
            parent=joined(parent, (0,), np.int64),
            depth=joined(depth, (0,), np.int64),
            side=joined(side, (0,), np.int64),
            items=[feature for feature, _parts in results],
        )

    def __len__(self) -> int:
        return len(self.triangles)

    def parent_index(self) -> np.ndarray:
        """Row of each triangle's parent in this batch, -1 for roots."""
        rows = np.arange(len(self), dtype=np.int64)
        return np.where(self.parent >= 0, rows - self.order + self.parent, -1)


def _field(name: str, kind: str) -> QgsField:
    """A field of type ``kind`` (Int, LongLong, Double): QMetaType from QGIS 3.38, else QVariant."""
    if Qgis.QGIS_VERSION_INT >= 33800:
        return QgsField(name, getattr(QMetaType, kind))
    return QgsField(name, getattr(QVariant, kind))


def triangle_fields(source_fields: QgsFields) -> QgsFields:
    """feature_id, the source's attributes (clashing names and fid prefixed), tree, metrics."""
    # "fid" is the primary key of GeoPackage outputs: copied per triangle it would repeat.
    taken = {"feature_id", "fid"} | {name for name, _kind in TRIANGLE_FIELDS}
    fields = QgsFields()
    fields.append(_field("feature_id", "LongLong"))
    for source_field in source_fields:
        field = QgsField(source_field)
        name = field.name()
        while name.lower() in taken:
            name = SOURCE_PREFIX + name
        field.setName(name)
        taken.add(name.lower())
        fields.append(field)
    for name, kind in TRIANGLE_FIELDS:
        fields.append(_field(name, kind))
    return fields


def tree_fields() -> QgsFields:
    fields = QgsFields()
    for name, kind in TREE_FIELDS:
        fields.append(_field(name, kind))
    return fields


def _column(values: np.ndarray) -> list:
    """Python values for attributes; NaN becomes NULL."""
    values = np.asarray(values)
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        return [None if not np.isfinite(v) else float(v) for v in values.tolist()]
    return values.tolist()


def triangle_features(mesh: BatchMesh, fields: QgsFields) -> list[QgsFeature]:
    """One PolygonZ feature per triangle, geometry from numpy-built WKB."""
    if not len(mesh):
        return []
    values = metrics.triangle_metrics(mesh.vertices, mesh.triangles)
    attributes = [item.feature.attributes() for item in mesh.items]
    columns = zip(
        mesh.fid.tolist(),
        mesh.item.tolist(),
        mesh.part.tolist(),
        mesh.order.tolist(),
        mesh.parent.tolist(),
        mesh.depth.tolist(),
        mesh.side.tolist(),
        *(_column(values[name]) for name in ("area_2d", "area_3d", "min_angle", "slope", "aspect")),
    )
    features = []
    for wkb, (fid, row, *rest) in zip(triangles_to_wkb(mesh.vertices, mesh.triangles), columns):
        feature = QgsFeature(fields)
        geometry = QgsGeometry()
        geometry.fromWkb(wkb)
        feature.setGeometry(geometry)
        feature.setAttributes([fid, *attributes[row], *rest])
        features.append(feature)
    return features


def tree_features(mesh: BatchMesh, fields: QgsFields) -> list[QgsFeature]:
    """One LineStringZ per tree edge, from the parent's centroid to the child's centroid."""
    children = np.flatnonzero(mesh.parent >= 0)
    if not len(children):
        return []
    centroids = metrics.centroid(mesh.vertices, mesh.triangles)
    records = np.zeros(len(children), dtype=_LINE_DTYPE)
    records["order"] = 1
    records["type"] = 1002
    records["count"] = 2
    records["points"][:, 0] = centroids[mesh.parent_index()[children]]
    records["points"][:, 1] = centroids[children]
    buffer = records.tobytes()
    size = _LINE_DTYPE.itemsize
    columns = zip(
        mesh.fid[children].tolist(),
        mesh.part[children].tolist(),
        mesh.parent[children].tolist(),
        mesh.order[children].tolist(),
        mesh.side[children].tolist(),
    )
    features = []
    for start, attributes in zip(range(0, len(buffer), size), columns):
        feature = QgsFeature(fields)
        geometry = QgsGeometry()
        geometry.fromWkb(buffer[start : start + size])
        feature.setGeometry(geometry)
        feature.setAttributes(list(attributes))
        features.append(feature)
    return features


def add_features(sink: QgsFeatureSink | None, features: list[QgsFeature]) -> None:
    """Write in one call; a refused write is an error the algorithm cannot go on from."""
    if sink is None or not features:
        return
    if not sink.addFeatures(features, QgsFeatureSink.FastInsert):
        message = sink.lastError() if hasattr(sink, "lastError") else ""
        raise OSError(f"cannot write features: {message}")


class MeshAccumulator:
    """Collects the triangles of all batches for one mesh file (identical vertices merged)."""

    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.faces: list[np.ndarray] = []
        self.fids: list[np.ndarray] = []
        self.depths: list[np.ndarray] = []

    def add(self, mesh: BatchMesh) -> None:
        if len(mesh):
            self.vertices.append(mesh.vertices)
            self.faces.append(mesh.triangles)
            self.fids.append(mesh.fid)
            self.depths.append(mesh.depth)

    def write(self, path: str, crs: QgsCoordinateReferenceSystem) -> tuple[int, int, list[str]]:
        """Write .2dm or .ply (by extension) with face values feature_id and depth.

        Returns (vertex count, face count, extra dataset files to add to the mesh layer).
        """
        vertices, faces, _part = merge_meshes(zip(self.vertices, self.faces))
        datasets = {
            "feature_id": _joined(self.fids),
            "depth": _joined(self.depths),
        }
        if mesh_format(path) == "ply":
            write_ply(path, vertices, faces, datasets, crs_wkt=crs.toWkt() or None)
            extra: list[str] = []
        else:
            written = write_2dm(path, vertices, faces, datasets if len(faces) else None)
            extra = [str(file) for file in written[1:]]
        return len(vertices), len(faces), extra


def _joined(arrays: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(arrays) if arrays else np.zeros(0, np.int64)


def mesh_format(path: str) -> str:
    """'ply' or '2dm' from the file name (2DM for anything else)."""
    return "ply" if Path(path).suffix.lower() == ".ply" else "2dm"


def load_mesh_on_completion(
    path: str,
    crs: QgsCoordinateReferenceSystem,
    context: QgsProcessingContext,
    output_name: str,
    dataset_files: Sequence[str] = (),
) -> str | None:
    """Open the written mesh as an MDAL layer with ``crs`` and ask Processing to load it."""
    name = Path(path).stem
    layer = QgsMeshLayer(path, name, "mdal")
    if not layer.isValid():
        return None
    layer.setCrs(crs)
    for dataset_file in dataset_files:
        layer.addDatasets(dataset_file)
    context.temporaryLayerStore().addMapLayer(layer)
    details = QgsProcessingContext.LayerDetails(
        name, context.project(), output_name, QgsProcessingUtils.LayerHint.Mesh
    )
    context.addLayerToLoadOnCompletion(layer.id(), details)
    return layer.id()


_POST_PROCESSORS: list[QgsProcessingLayerPostProcessorInterface] = []


class TriangleStylePostProcessor(QgsProcessingLayerPostProcessorInterface):
    """Applies styles/triangles.qml and re-classes the depth ramp on the loaded layer."""

    CLASSES = 6

    @classmethod
    def create(cls) -> TriangleStylePostProcessor:
        # Processing holds only a C++ pointer: without a Python reference it is collected.
        instance = cls()
        _POST_PROCESSORS.append(instance)
        return instance

    def postProcessLayer(  # noqa: N802 - QGIS API name
        self, layer: QgsMapLayer, context: QgsProcessingContext, feedback: QgsProcessingFeedback
    ) -> None:
        if not isinstance(layer, QgsVectorLayer):
            return
        _message, ok = layer.loadNamedStyle(str(STYLE_PATH))
        if not ok:
            feedback.pushInfo(f"Default style not applied: {_message}")
            return
        renderer = layer.renderer()
        if isinstance(renderer, QgsGraduatedSymbolRenderer) and layer.featureCount() > 0:
            renderer.updateClasses(layer, self.CLASSES)
        layer.triggerRepaint()
