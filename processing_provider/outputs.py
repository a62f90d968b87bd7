"""Outputs of the triangulation: triangle features, tree lines, the mesh file and its loading."""

from __future__ import annotations

import functools
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from qgis.core import (
    QgsApplication,
    QgsClassificationCustom,
    QgsColorRampShader,
    QgsCoordinateReferenceSystem,
    QgsDataSourceUri,
    QgsFeature,
    QgsFeatureRequest,
    QgsFeatureSink,
    QgsField,
    QgsFields,
    QgsGeometry,
    QgsGradientColorRamp,
    QgsGraduatedSymbolRenderer,
    QgsMapLayer,
    QgsMeshDatasetIndex,
    QgsMeshLayer,
    QgsMeshRendererMeshSettings,
    QgsMeshRendererScalarSettings,
    QgsMeshRendererSettings,
    QgsProcessingContext,
    QgsProcessingFeedback,
    QgsProcessingLayerPostProcessorInterface,
    QgsProcessingUtils,
    QgsProviderRegistry,
    QgsReadWriteContext,
    QgsRendererRange,
    QgsUnitTypes,
    QgsVectorFileWriter,
    QgsVectorLayer,
    QgsVectorLayerSimpleLabeling,
)
from qgis.PyQt.QtCore import QCoreApplication, QThread
from qgis.PyQt.QtXml import QDomDocument

from ..bsp_triangulate import metrics
from ..bsp_triangulate.formats.mesh import merge_meshes, write_2dm, write_ply
from ..bsp_triangulate.formats.models import MODEL_EXTENSIONS, model_format, write_model
from ..bsp_triangulate.formats.wkb import triangles_to_multipolygon_wkb
from ..bsp_triangulate.geometry.rings_batch import ragged_index
from ..bsp_triangulate.packed import PackedTriangulations
from ..bsp_triangulate.workers import WorkerPool
from .geometry_io import FeatureRings
from .qgis_compat import FIELD_TYPES, CrsWktVariant, FeatureRequestFlag

STYLE_DIR = Path(__file__).resolve().parent / "styles"
STYLE_PATH = STYLE_DIR / "triangles.qml"
# The mesh layer's 3D renderer (a surface coloured as the 2D map, true vertical scale).
MESH_3D_STYLE_PATH = STYLE_DIR / "mesh_3d.qml"
# meshes QGIS opens as mesh layers, and 3D models for other software (not loaded in QGIS)
MESH_EXTENSIONS = ("ply", "2dm", *MODEL_EXTENSIONS)
SOURCE_PREFIX = "src_"
# Features built and written at a time: bounded memory, few sink calls.
FEATURE_CHUNK = 20_000

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

# Byte order, type and part count of a WKB MultiPolygon.
_MULTI_HEADER = 9
# One little-endian ISO LineStringZ (type 1002) with two points: 57 bytes, no padding.
_LINE_DTYPE = np.dtype(
    [("order", "u1"), ("type", "<u4"), ("count", "<u4"), ("points", "<f8", (2, 3))]
)


@dataclass
class EngineChunk:
    """One engine call's results: ``packed`` holds the parts of ``items`` (in order,
    ``part_count`` each); ``item_kept`` marks the items none of whose parts failed."""

    items: list[FeatureRings]
    part_count: np.ndarray
    packed: PackedTriangulations
    item_kept: np.ndarray

    @property
    def kept(self) -> np.ndarray:
        """Per part: its item is kept."""
        return np.repeat(self.item_kept, self.part_count)


class BatchMesh:
    """The triangles of a batch of features, concatenated, with their tree attributes.

    - ``vertices`` (V, 3), ``triangles`` (M, 3) into ``vertices``, ``item`` (M,) index into
      ``items``;
    - ``part``, ``order`` (index in the part's BSP pre-order), ``parent`` (the parent's
      order, -1 for the root), ``depth``, ``side``: (M,) columns.
    """

    def __init__(
        self,
        items: list[FeatureRings],
        vertices: np.ndarray,
        triangles: np.ndarray,
        item: np.ndarray,
        part: np.ndarray,
        counts: np.ndarray,
        tree: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> None:
        self.items = items
        self.vertices = vertices
        self.triangles = triangles
        self.item = item
        self.part = part
        self._counts = counts
        self.parent, self.depth, self.side = tree

    @property
    def fid(self) -> np.ndarray:
        if not len(self.item):
            return np.zeros(0, np.int64)
        fids = np.array([item.fid for item in self.items], dtype=np.int64)
        return fids[self.item]

    @classmethod
    def build(cls, chunks: list[EngineChunk]) -> BatchMesh:
        """The triangles of the kept parts of every chunk, items one after another."""
        items: list[FeatureRings] = []
        blocks: list[tuple[np.ndarray, ...]] = []
        vertex_offset = 0
        for chunk in chunks:
            packed = chunk.packed
            owner = np.repeat(np.arange(len(chunk.part_count)), chunk.part_count)
            # each part's index within its feature
            part = ragged_index(np.zeros(len(chunk.part_count), np.int64), chunk.part_count)
            # the kept items' rows in this mesh
            row = np.cumsum(chunk.item_kept) - 1 + len(items)
            items += [item for item, keep in zip(chunk.items, chunk.item_kept.tolist()) if keep]
            keep = chunk.kept & (packed.triangle_count > 0)
            counts = packed.triangle_count[keep]
            vertices, triangles, tree = packed.vertices, packed.triangles, packed.tree()
            if not keep.all():
                rows = ragged_index(packed.triangle_start[keep], counts)
                triangles = triangles[rows]
                tree = tuple(column[rows] for column in tree)
                vertex_rows = ragged_index(packed.vertex_start[keep], packed.vertex_count[keep])
                vertices = vertices[vertex_rows]
                vertex_count = packed.vertex_count[keep]
            else:
                vertex_count = packed.vertex_count
            # local indices to indices into this mesh's vertices
            shift = np.cumsum(vertex_count) - vertex_count + vertex_offset
            triangles = triangles + np.repeat(shift, counts)[:, None]
            vertex_offset += len(vertices)
            blocks.append(
                (vertices, triangles, np.repeat(row[owner[keep]], counts),
                 np.repeat(part[keep], counts), counts, *tree)
            )  # fmt: skip
        if not blocks:
            none = np.zeros(0, np.int64)
            return cls(items, np.zeros((0, 3)), np.zeros((0, 3), np.int64), none, none, none,
                       (none, none, np.zeros(0, np.int8)))  # fmt: skip
        columns = [np.concatenate(column) for column in zip(*blocks)]
        vertices, triangles, item, part, counts, parent, depth, side = columns
        return cls(items, vertices, triangles, item, part, counts, (parent, depth, side))

    @functools.cached_property
    def order(self) -> np.ndarray:
        first = np.cumsum(self._counts) - self._counts
        return np.arange(len(self), dtype=np.int64) - np.repeat(first, self._counts)

    def __len__(self) -> int:
        return len(self.triangles)

    def feature_count(self) -> int:
        """How many features have triangles here (``item`` is non-decreasing)."""
        if not len(self.item):
            return 0
        return int(np.count_nonzero(self.item[1:] != self.item[:-1])) + 1

    def parent_index(self) -> np.ndarray:
        """Row of each triangle's parent in this batch, -1 for roots."""
        rows = np.arange(len(self), dtype=np.int64)
        return np.where(self.parent >= 0, rows - self.order + self.parent, -1)


def _field(name: str, kind: str) -> QgsField:
    """A field of type ``kind`` (Int, LongLong, Double, String)."""
    return QgsField(name, FIELD_TYPES[kind])


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


def triangle_feature_chunks(
    mesh: BatchMesh,
    fields: QgsFields,
    size: int = FEATURE_CHUNK,
    ellipsoid: tuple[float, float] | None = None,
) -> Iterator[list[QgsFeature]]:
    """One PolygonZ feature per triangle (geometry from numpy-built WKB), ``size`` at a time.

    Attributes and WKB are computed for the whole batch in numpy; the QgsFeature objects exist
    only for one chunk, so memory stays bounded however large the batch is. ``ellipsoid``:
    the layer is geographic, its metrics are taken in metres (``metrics.triangle_metrics``).
    """
    if not len(mesh):
        return
    # the ellipsoid only when given: the committed metrics module may not take it yet
    extra = {} if ellipsoid is None else {"ellipsoid": ellipsoid}
    values = metrics.triangle_metrics(mesh.vertices, mesh.triangles, **extra)
    # feature_id and the source attributes: one list per source feature, shared by its triangles
    heads = [[item.fid, *item.feature.attributes()] for item in mesh.items]
    tails = list(
        zip(
            mesh.part.tolist(),
            mesh.order.tolist(),
            mesh.parent.tolist(),
            mesh.depth.tolist(),
            mesh.side.tolist(),
            *(
                _column(values[name])
                for name in ("area_2d", "area_3d", "min_angle", "slope", "aspect")
            ),
        )
    )
    rows = mesh.item.tolist()
    # one MultiPolygonZ WKB: after its header, each triangle's PolygonZ WKB follows the last
    buffer = triangles_to_multipolygon_wkb(mesh.vertices, mesh.triangles)
    polygon_size = (len(buffer) - _MULTI_HEADER) // len(mesh)
    for start in range(0, len(mesh), size):
        stop = min(start + size, len(mesh))
        wkbs = [
            buffer[offset : offset + polygon_size]
            for offset in range(
                _MULTI_HEADER + start * polygon_size,
                _MULTI_HEADER + stop * polygon_size,
                polygon_size,
            )
        ]
        yield _features(fields, wkbs, [heads[row] for row in rows[start:stop]], tails[start:stop])


def _features(
    fields: QgsFields, wkbs: list[bytes], heads: list[list], tails: list[tuple]
) -> list[QgsFeature]:
    """Features of WKB geometries with the attributes ``head + tail`` (lists of equal length)."""
    new_feature, new_geometry = QgsFeature, QgsGeometry
    features = []
    append = features.append
    for wkb, head, tail in zip(wkbs, heads, tails):
        feature = new_feature(fields)
        geometry = new_geometry()
        geometry.fromWkb(wkb)
        feature.setGeometry(geometry)
        feature.setAttributes(head + list(tail))
        append(feature)
    return features


def tree_feature_chunks(
    mesh: BatchMesh, fields: QgsFields, size: int = FEATURE_CHUNK
) -> Iterator[list[QgsFeature]]:
    """One LineStringZ per tree edge, from the parent's centroid to the child's, in chunks."""
    children = np.flatnonzero(mesh.parent >= 0)
    if not len(children):
        return
    centroids = metrics.centroid(mesh.vertices, mesh.triangles)
    records = np.zeros(len(children), dtype=_LINE_DTYPE)
    records["order"] = 1
    records["type"] = 1002
    records["count"] = 2
    records["points"][:, 0] = centroids[mesh.parent_index()[children]]
    records["points"][:, 1] = centroids[children]
    buffer = records.tobytes()
    line_size = _LINE_DTYPE.itemsize
    wkbs = [buffer[start : start + line_size] for start in range(0, len(buffer), line_size)]
    tails = list(
        zip(
            mesh.fid[children].tolist(),
            mesh.part[children].tolist(),
            mesh.parent[children].tolist(),
            mesh.order[children].tolist(),
            mesh.side[children].tolist(),
        )
    )
    for start in range(0, len(children), size):
        stop = min(start + size, len(children))
        yield _features(fields, wkbs[start:stop], [[]] * (stop - start), tails[start:stop])


class SinkWriter:
    """Adds feature chunks to sinks in order, then releases the sinks.

    Everything happens on the algorithm's own thread: QGIS sinks (memory layers, GeoPackage
    writers) are not meant to be shared with another thread, and a crash inside QGIS desktop
    costs a user far more than the seconds an overlapped write would save.
    """

    def write(self, sink: QgsFeatureSink | None, chunks: Iterable[list[QgsFeature]]) -> None:
        """Write every chunk to ``sink``; nothing is built when there is no sink."""
        if sink is None:
            return
        for features in chunks:
            add_features(sink, features)

    def close(self, sinks: list) -> None:
        """Drop the last references to the sinks, which closes them (a GeoPackage builds its
        spatial index then)."""
        sinks.clear()

    def finish(self) -> None:
        """Nothing is pending: writes are synchronous."""


def add_features(sink: QgsFeatureSink | None, features: list[QgsFeature]) -> None:
    """Write in one call; a refused write is an error the algorithm cannot go on from."""
    if sink is None or not features:
        return
    if not sink.addFeatures(features, QgsFeatureSink.Flag.FastInsert):
        message = sink.lastError() if hasattr(sink, "lastError") else ""
        raise OSError(f"cannot write features: {message}")


class MeshAccumulator:
    """Collects the triangles of all batches for one mesh file (identical vertices merged).

    Keeps only numpy arrays: float64 vertices, int32 faces (int64 past 2**31 vertices) and the
    face values.
    """

    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.faces: list[np.ndarray] = []
        self.fids: list[np.ndarray] = []
        self.depths: list[np.ndarray] = []
        self.vertex_count = 0

    def add(self, mesh: BatchMesh) -> None:
        if not len(mesh):
            return
        offset = self.vertex_count
        self.vertex_count += len(mesh.vertices)
        # converted first, then shifted in place: every index fits the new type
        faces = mesh.triangles.astype(_index_type(self.vertex_count))
        faces += offset
        self.vertices.append(mesh.vertices)
        self.faces.append(faces)
        self.fids.append(mesh.fid)
        self.depths.append(mesh.depth.astype(np.int32))

    def stage(
        self, path: str, crs: QgsCoordinateReferenceSystem, pool: WorkerPool | None = None
    ) -> StagedMesh:
        """Write .2dm or .ply (by extension) with face values feature_id and depth into a
        hidden folder next to ``path``; nothing is at ``path`` until the result is committed.
        A large 2DM's lines are written by the ``pool``'s workers, if given."""
        dtype = _index_type(self.vertex_count)
        vertices = _joined(self.vertices, (0, 3), np.float64)
        faces = _joined(self.faces, (0, 3), dtype)
        vertices, faces = merge_identical_vertices(vertices, faces)
        datasets = {
            "feature_id": _joined(self.fids, (0,), np.int64),
            "depth": _joined(self.depths, (0,), np.int32),
        }
        target = Path(path).absolute()
        folder = Path(
            tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
        )
        staged = StagedMesh(target, folder, len(vertices), len(faces))
        try:
            if model_format(path) is not None:
                # glTF or OBJ: a model for 3D software, with its origin and CRS sidecars
                model = folder / target.name
                written = write_model(model, vertices, faces, datasets, crs_text(crs))
                staged.sidecars = [file.name for file in written[1:]]
                return staged
            if mesh_format(path) == "ply":
                write_ply(folder / target.name, vertices, faces, datasets, crs_wkt=crs_text(crs))
            else:
                written = write_2dm(
                    folder / target.name, vertices, faces, datasets if len(faces) else None, pool
                )
                staged.companions = [file.name for file in written[1:]]
            if len(faces):
                # the default style QGIS loads with a mesh opened by its path (PyQGIS,
                # Processing); QGIS desktop's Add Mesh Layer opens it as PLY:"<path>", for
                # which QgsMapLayer::baseURI finds no style file (it decodes only ogr, gdal,
                # delimitedtext and spatialite sources): there it is Load Style by hand
                style = folder / mesh_style_name(target)
                z = vertices[:, 2]
                document = mesh_style_document(float(z.min()), float(z.max()))
                style.write_text(document.toString(2), encoding="utf-8")
                staged.sidecars = [style.name]
        except BaseException:
            staged.discard()
            raise
        return staged


@dataclass
class StagedMesh:
    """A mesh file (and its 2DM companion) written to a hidden folder beside its destination.

    ``commit`` moves it into place, replacing an earlier file of the same name only then, so a
    cancelled or failed run leaves the destination as it was; ``discard`` removes it.
    """

    target: Path
    folder: Path
    vertex_count: int
    face_count: int
    # face value files (2DM's <name>_els.dat), added to the layer as extra datasets
    companions: list[str] = field(default_factory=list)
    # other files beside the mesh (its default style <name>.qml)
    sidecars: list[str] = field(default_factory=list)

    def commit(self) -> tuple[int, int, list[str]]:
        """Rename into place, companions first; returns (vertices, faces, dataset files)."""
        try:
            for name in self.companions + self.sidecars:
                os.replace(self.folder / name, self.target.with_name(name))
            dat = self.target.stem + "_els.dat"
            if mesh_format(str(self.target)) == "2dm" and dat not in self.companions:
                # a face value file left by an earlier run would not match the new mesh
                self.target.with_name(dat).unlink(missing_ok=True)
            os.replace(self.folder / self.target.name, self.target)
        finally:
            self.discard()
        extra = [str(self.target.with_name(name)) for name in self.companions]
        return self.vertex_count, self.face_count, extra

    def discard(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


class SinkCleanup:
    """Removes what a cancelled or failed run wrote to its feature sinks.

    File outputs the run created are deleted; a layer the run added to a GeoPackage that
    existed before is dropped from it. Memory layers are taken out of the context's layers to
    load. A database table (``postgis:``, ``spatialite:`` and other provider destinations) is
    dropped through the provider's connection: the run created it, replacing any earlier one.
    """

    def __init__(self, context: QgsProcessingContext) -> None:
        self.context = context
        self.existed: dict[str, bool] = {}
        self.destinations: list[str] = []

    def note(self, destination: str) -> None:
        """Before any sink is created: whether the destination's file exists already."""
        path = _destination_file(destination)
        if path:
            self.existed.setdefault(os.path.abspath(path), os.path.exists(path))

    def track(self, destination_id: str | None) -> None:
        """A sink was created with this destination (layer id or file URI)."""
        if destination_id:
            self.destinations.append(destination_id)

    def remove(self) -> None:
        """Call once the sinks are released (no reference to them is left)."""
        to_load = self.context.layersToLoadOnCompletion()
        for destination in self.destinations:
            to_load.pop(destination, None)
            store = self.context.temporaryLayerStore()
            if store.mapLayer(destination) is not None:
                store.removeMapLayer(destination)
                continue
            if _drop_database_table(destination):
                continue
            parts = QgsProviderRegistry.instance().decodeUri("ogr", destination)
            path, layer = parts.get("path") or "", parts.get("layerName")
            if not path or not os.path.isfile(path):
                continue
            if layer and self.existed.get(os.path.abspath(path), True):
                _drop_layer(path, layer)
            else:
                _delete_vector_file(path)
        self.context.setLayersToLoadOnCompletion(to_load)


def _destination_file(destination: str) -> str:
    """The file of a sink destination string as the user gave it ('' when not a file)."""
    if destination.startswith("ogr:"):
        return QgsDataSourceUri(destination[len("ogr:") :]).database()
    if ":" in destination.split("/")[0] and not os.path.isabs(destination):
        return ""  # memory:, postgres: and other providers
    return destination.split("|")[0]


def _database_table(destination: str) -> tuple[str, QgsDataSourceUri] | None:
    """(provider key, URI) of a ``provider:uri`` destination naming a database table."""
    match = re.match(r"^([A-Za-z_]{3,}?):(.*)$", destination.split("|")[0], re.DOTALL)
    if match is None:
        return None
    key = "postgres" if match[1] == "postgis" else match[1]
    if key in ("memory", "ogr") or key not in QgsProviderRegistry.instance().providerList():
        return None
    uri = QgsDataSourceUri(match[2])
    return (key, uri) if uri.table() else None


def _drop_database_table(destination: str) -> bool:
    """Drop the table of a database destination; False when it is not one (or cannot be)."""
    found = _database_table(destination)
    if found is None:
        return False
    key, uri = found
    metadata = QgsProviderRegistry.instance().providerMetadata(key)
    try:
        connection = metadata.createConnection(uri.uri(False), {})
        connection.dropVectorTable(uri.schema(), uri.table())
    except Exception:  # QgsProviderConnectionException, or a provider without connections
        return False
    return True


def _drop_layer(path: str, layer: str) -> None:
    from osgeo import ogr

    dataset = ogr.Open(path, 1)
    if dataset is None:
        return
    for index in range(dataset.GetLayerCount()):
        if dataset.GetLayerByIndex(index).GetName() == layer:
            dataset.DeleteLayer(index)
            break
    dataset = None


def _delete_vector_file(path: str) -> None:
    if Path(path).suffix.lower() == ".shp":
        QgsVectorFileWriter.deleteShapeFile(path)
        return
    for name in (path, path + "-wal", path + "-shm", path + "-journal"):
        Path(name).unlink(missing_ok=True)


# Odd 64-bit constants that spread the coordinate bits over the hash.
_HASH_MULTIPLIERS = (
    np.uint64(0x9E3779B97F4A7C15),
    np.uint64(0xC2B2AE3D27D4EB4F),
    np.uint64(0x165667B19E3779F9),
)


def _index_type(vertex_count: int) -> type:
    return np.int32 if vertex_count <= np.iinfo(np.int32).max else np.int64


def _joined(arrays: list[np.ndarray], shape: tuple[int, ...], dtype: type) -> np.ndarray:
    """The arrays one after another; the list is emptied as they are copied, so the parts
    and the whole are not all held at once."""
    if not arrays:
        return np.zeros(shape, dtype)
    out = np.empty((sum(len(a) for a in arrays), *shape[1:]), dtype)
    position = 0
    arrays.reverse()
    while arrays:
        part = arrays.pop()
        out[position : position + len(part)] = part
        position += len(part)
    return out


def merge_identical_vertices(
    vertices: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices with identical x, y and z as one, in order of first appearance.

    The same result as ``bsp_triangulate.formats.mesh.merge_meshes`` (0.0 and -0.0 are equal, other
    values compare by their bits), found by sorting one 64-bit hash per vertex instead of
    24-byte rows; every merge is checked on the full coordinates, and a hash collision between
    different vertices falls back to the exact row sort. ``vertices`` (the caller's own
    array) has its -0.0 turned into 0.0 in place, to save a copy of the whole mesh.
    """
    count = len(vertices)
    if count == 0:
        return vertices, faces
    vertices = np.ascontiguousarray(vertices)
    vertices += 0.0  # -0.0 -> 0.0 in place (the caller's own array): no copy of the mesh
    bits = vertices.view(np.uint64)
    key = bits[:, 0] * _HASH_MULTIPLIERS[0]
    key ^= key >> np.uint64(29)
    key += bits[:, 1] * _HASH_MULTIPLIERS[1]
    key ^= key >> np.uint64(32)
    key += bits[:, 2] * _HASH_MULTIPLIERS[2]
    key ^= key >> np.uint64(29)
    # identical vertices have identical keys: without a repeated key (a plain sort, much
    # faster than an argsort, tells) nothing merges
    sorted_key = np.sort(key)
    repeated = bool((sorted_key[1:] == sorted_key[:-1]).any())
    del sorted_key
    if not repeated:
        return vertices, faces
    order = np.argsort(key)  # not stable (3x faster): first appearances are minima below
    sorted_key = key[order]
    del key
    starts = np.empty(count, dtype=bool)
    starts[0] = True
    np.not_equal(sorted_key[1:], sorted_key[:-1], out=starts[1:])
    del sorted_key
    # each group's first appearance: the smallest index among its members
    first = np.minimum.reduceat(order, np.flatnonzero(starts))
    representative = np.empty(count, dtype=np.int64)
    representative[order] = first[np.cumsum(starts) - 1]
    del order, starts
    if len(first) == count:
        return vertices, faces
    if not _same_rows(bits, representative):
        merged, merged_faces, _part = merge_meshes([(vertices, faces)])
        return merged, merged_faces
    kept = np.sort(first)
    rank = np.empty(count, dtype=faces.dtype)
    rank[kept] = np.arange(len(kept), dtype=faces.dtype)
    return vertices[kept], rank[representative][faces]


def _same_rows(bits: np.ndarray, representative: np.ndarray, block: int = 1 << 20) -> bool:
    """Every row equals its representative's row (compared block by block)."""
    for start in range(0, len(bits), block):
        rows = slice(start, start + block)
        if not (bits[rows] == bits[representative[rows]]).all():
            return False
    return True


def mesh_format(path: str) -> str:
    """'ply', '2dm', or a 3D model's 'glb', 'gltf' or 'obj' from the file name (2DM for
    anything else)."""
    suffix = Path(path).suffix.lower().lstrip(".")
    return suffix if suffix in ("ply", *MODEL_EXTENSIONS) else "2dm"


def is_model(path: str) -> bool:
    """The file is a glTF or OBJ 3D model (not a mesh QGIS opens)."""
    return model_format(path) is not None


def crs_text(crs: QgsCoordinateReferenceSystem) -> str | None:
    """The CRS as WKT (WKT2 where PROJ has it) for the mesh file; None when it is not valid."""
    if not crs.isValid():
        return None
    preferred = CrsWktVariant.Preferred
    return crs.toWkt(preferred) or crs.toWkt() or None


def mesh_style_name(path: str | os.PathLike) -> str:
    """The default style file QGIS looks for beside a layer's file: the name up to its last
    dot, then .qml (``QgsMapLayer::styleURI``)."""
    return Path(path).stem + ".qml"


# A terrain ramp for the mesh's elevation: low green, then ochre and brown, high near white.
_ELEVATION_RAMP = {
    "color1": "38,115,77,255",
    "color2": "250,250,250,255",
    "stops": "0.25;132,168,86,255:0.5;222,196,120,255:0.75;164,113,75,255",
}
# The first dataset group MDAL gives a 2DM or PLY mesh: z of its vertices.
BED_ELEVATION_GROUP = 0
BED_ELEVATION_NAME = "Bed Elevation"


def ensure_3d_renderers() -> bool:
    """Whether QGIS can read a mesh 3D renderer here: QGIS desktop registers the 3D renderer
    types at start; a script (or qgis_process) has them registered here, on the main thread,
    when it has not."""
    registry = QgsApplication.renderer3DRegistry()
    if "mesh" in registry.renderersList():
        return True
    app = QCoreApplication.instance()
    if app is None or QThread.currentThread() is not app.thread():
        return False
    try:
        from qgis._3d import Qgs3D  # "qgis.3d" cannot be imported by name
    except ImportError:
        return False
    Qgs3D.initialize()
    return "mesh" in registry.renderersList()


def mesh_style_document(z_min: float, z_max: float) -> QDomDocument:
    """The mesh layer's style as a QML document: the 2D map colours the surface by its
    elevation (z_min to z_max, terrain ramp, interpolated); the 3D renderer draws it in 3D
    views with the same ramp on z (styles/mesh_3d.qml, its ramp replaced)."""
    if not z_max > z_min:
        z_max = z_min + 1.0
    document = QDomDocument()
    document.setContent(MESH_3D_STYLE_PATH.read_text(encoding="utf-8"))
    root = document.documentElement()
    root.setAttribute("styleCategories", "Symbology|Symbology3D")
    shader = QgsColorRampShader(z_min, z_max, QgsGradientColorRamp.create(_ELEVATION_RAMP))
    shader.classifyColorRamp(5)
    scalar = QgsMeshRendererScalarSettings()
    scalar.setClassificationMinimumMaximum(z_min, z_max)
    scalar.setColorRampShader(shader)
    settings = QgsMeshRendererSettings()
    settings.setScalarSettings(BED_ELEVATION_GROUP, scalar)
    settings.setActiveScalarDatasetGroup(BED_ELEVATION_GROUP)
    frame = QgsMeshRendererMeshSettings()
    frame.setEnabled(False)  # the triangles output draws the edges
    settings.setNativeMeshSettings(frame)
    root.appendChild(settings.writeXml(document, QgsReadWriteContext()))
    # the 3D surface in the same colours, by z
    advanced = root.firstChildElement("renderer-3d").firstChildElement("symbol")
    advanced = advanced.firstChildElement("advanced-settings")
    advanced.setAttribute("min-color-ramp-shader", repr(z_min))
    advanced.setAttribute("max-color-ramp-shader", repr(z_max))
    advanced.replaceChild(
        shader.writeXml(document, QgsReadWriteContext()),
        advanced.firstChildElement("colorrampshader"),
    )
    # QGIS 3.28+ applies a style's group settings by group name (3.22 ignores the element)
    name = document.createElement("name-to-global-index")
    name.setAttribute("name", BED_ELEVATION_NAME)
    name.setAttribute("global-index", BED_ELEVATION_GROUP)
    root.appendChild(name)
    return document


def apply_mesh_style(layer: QgsMeshLayer) -> bool:
    """Give a loaded mesh layer the plugin's 2D style and, where QGIS can read it, its 3D
    renderer; True when the 3D renderer is set."""
    meta = layer.datasetGroupMetadata(QgsMeshDatasetIndex(BED_ELEVATION_GROUP))
    document = mesh_style_document(meta.minimum(), meta.maximum())
    categories = QgsMapLayer.StyleCategories(QgsMapLayer.StyleCategory.Symbology)
    with_3d = ensure_3d_renderers()
    if with_3d:
        categories |= QgsMapLayer.StyleCategory.Symbology3D
    layer.importNamedStyle(document, categories)
    return with_3d and layer.renderer3D() is not None


def load_mesh_on_completion(
    path: str,
    crs: QgsCoordinateReferenceSystem,
    context: QgsProcessingContext,
    output_name: str,
    dataset_files: Sequence[str] = (),
) -> str | None:
    """Open the written mesh as an MDAL layer with ``crs`` and its style (2D and 3D) and ask
    Processing to load it."""
    name = Path(path).stem
    layer = QgsMeshLayer(path, name, "mdal")
    if not layer.isValid():
        return None
    layer.setCrs(crs)
    for dataset_file in dataset_files:
        layer.addDatasets(dataset_file)
    apply_mesh_style(layer)
    context.temporaryLayerStore().addMapLayer(layer)
    details = QgsProcessingContext.LayerDetails(
        name, context.project(), output_name, QgsProcessingUtils.LayerHint.Mesh
    )
    context.addLayerToLoadOnCompletion(layer.id(), details)
    return layer.id()


_POST_PROCESSORS: list[QgsProcessingLayerPostProcessorInterface] = []


class TriangleStylePostProcessor(QgsProcessingLayerPostProcessorInterface):
    """Applies styles/triangles.qml, then the depth classes and the label scale of the layer's
    own data (see :func:`style_triangles`)."""

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
        style_triangles(layer)
        layer.triggerRepaint()


def depth_classes(deepest: int) -> list[tuple[int, int]]:
    """Depth classes that double: 0, 1, 2-3, 4-7, 8-15, ... up to ``deepest``.

    A BSP tree has up to 2**d triangles at depth d, and most of a layer's triangles sit at
    small depths with a long tail of deep ones (equal intervals put about 97 % of the
    Swellendam farms' triangles in the first class): doubling classes spread them over the
    legend and stay readable whatever the deepest level.
    """
    classes = [(0, 0)]
    low = 1
    while low <= max(deepest, 0):
        classes.append((low, min(2 * low - 1, deepest)))
        low *= 2
    return classes


def _class_label(low: int, high: int) -> str:
    return str(low) if low == high else f"{low} - {high}"


# Labels are drawn where a typical triangle is at least this wide on the screen.
LABEL_MIN_SIZE_M = 0.012
LABEL_SAMPLE = 20_000
DEFAULT_LABEL_SCALE = 5_000.0


def label_scale(typical_size_m: float | None) -> float:
    """The most zoomed-out scale (denominator) at which a triangle of ``typical_size_m``
    (metres on the ground) is ``LABEL_MIN_SIZE_M`` wide on the map, rounded down to 1, 2 or 5
    times a power of ten."""
    if not typical_size_m or not np.isfinite(typical_size_m) or typical_size_m <= 0:
        return DEFAULT_LABEL_SCALE
    scale = typical_size_m / LABEL_MIN_SIZE_M
    power = 10.0 ** np.floor(np.log10(scale))
    step = max(s for s in (1.0, 2.0, 5.0) if s * power <= scale)
    return max(float(step * power), 1.0)


def _typical_triangle_size(layer: QgsVectorLayer) -> float | None:
    """About a triangle's edge length in metres: from the median area_2d of (up to
    ``LABEL_SAMPLE``) triangles."""
    index = layer.fields().indexOf("area_2d")
    if index < 0:
        return None
    request = QgsFeatureRequest().setFlags(FeatureRequestFlag.NoGeometry)
    request.setSubsetOfAttributes([index]).setLimit(LABEL_SAMPLE)
    areas = [f.attribute(index) for f in layer.getFeatures(request)]
    areas = np.array([a for a in areas if isinstance(a, (int, float))], dtype=np.float64)
    if not len(areas):
        return None
    metres, _ok = QgsUnitTypes.decodeDistanceUnit("meters")  # no enum name: QGIS 3.22 to 4
    to_metres = QgsUnitTypes.fromUnitToUnitFactor(layer.crs().mapUnits(), metres)
    return float(np.sqrt(2.0 * np.median(areas))) * to_metres


def style_triangles(layer: QgsVectorLayer) -> None:
    """The triangle layer's classes and labels from its own data.

    - depth: :func:`depth_classes` up to the deepest triangle, coloured along the style's
      ramp, set as a new renderer so the legend (Layers panel) and the map are the same;
    - labels (triangle order): only from the scale where a typical triangle is about 12 mm
      wide, only inside their triangle, never overlapping.
    """
    renderer = layer.renderer()
    depth = layer.fields().indexOf("depth")
    if isinstance(renderer, QgsGraduatedSymbolRenderer) and depth >= 0:
        deepest = layer.maximumValue(depth)
        deepest = int(deepest) if isinstance(deepest, (int, float)) else 0
        classes = depth_classes(deepest)
        ramp = renderer.sourceColorRamp()
        ranges = []
        for index, (low, high) in enumerate(classes):
            symbol = renderer.sourceSymbol().clone()
            if ramp is not None:
                symbol.setColor(ramp.color(index / max(len(classes) - 1, 1)))
            ranges.append(QgsRendererRange(low, high, symbol, _class_label(low, high)))
        classified = QgsGraduatedSymbolRenderer("depth", ranges)
        classified.setSourceSymbol(renderer.sourceSymbol().clone())
        if ramp is not None:
            classified.setSourceColorRamp(ramp.clone())
        classified.setClassificationMethod(QgsClassificationCustom())
        layer.setRenderer(classified)
    labeling = layer.labeling()
    if labeling is not None and hasattr(labeling, "settings"):
        settings = labeling.settings()
        settings.scaleVisibility = True
        settings.minimumScale = label_scale(_typical_triangle_size(layer))
        settings.maximumScale = 0.0
        settings.fitInPolygonOnly = True
        settings.displayAll = False
        layer.setLabeling(QgsVectorLayerSimpleLabeling(settings))
        layer.setLabelsEnabled(True)
