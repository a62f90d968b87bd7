"""Writing a triangle mesh as glTF 2.0: binary ``.glb`` or JSON ``.gltf`` (sidecar ``.bin`` or
an embedded data URI), pure numpy and the standard library.

Same input as the writers of :mod:`.mesh`: ``vertices`` (N, 3) float64 in the map's CRS,
``faces`` (M, 3) vertex indices, counter-clockwise seen from above (or from outside a solid),
and optional per-face values (``face_properties``: name -> (M,) array, e.g. ``feature_id`` and
``depth``).

Conventions of the written file
-------------------------------
- **Local origin.** float32 positions lose centimetres a few thousand kilometres from their
  origin, so positions are written relative to a local origin (by default the centre of the
  mesh's bounding box, rounded to whole units). The origin is the translation of the scene's
  only node, as float64 JSON numbers (full precision): a viewer places the mesh where it
  belongs by the node transform. ``asset.extras`` repeats it in the map frame
  (``origin_xyz``) with the CRS (``crs_wkt``) and the axis convention.
- **Y up.** glTF is Y-up and right-handed, the map frame Z-up: a map point (x, y, z) is written
  as glTF (x, z, -y), a rotation of -90 degrees about X (east stays +X, up becomes +Y, north
  becomes -Z), as the glTF specification requires. It is a proper rotation, so winding and
  outward normals are kept. A map point is ``(X, -Z, Y)`` of a glTF point (after the node's
  translation).
- **Flat faces.** Every triangle has its own three vertices (no vertex is shared between
  triangles) and each vertex the ``NORMAL`` of its triangle (unit length, float32; (0, 1, 0)
  for a triangle without area). So per-face values are constant over their triangle and the
  mesh is shaded flat, as a triangulated polygon should be. The primitive has no index
  accessor: vertices 3i, 3i + 1, 3i + 2 make triangle i.
- **Per-face values** are vertex attributes, the same on a triangle's three vertices. Integer
  values in [0, 2**24) (ids, depths, surface codes) are feature IDs of the ``EXT_mesh_features``
  extension: attribute ``_FEATURE_ID_k`` (float32, exact for such integers) and an entry in
  the primitive's ``EXT_mesh_features.featureIds`` with the property's name as ``label`` and
  its ``featureCount``. Other values (floats, negative or larger integers) are written as the
  float32 attribute ``_<NAME>`` (upper case), listed in the primitive's ``extras``. The
  extension is in ``extensionsUsed`` only, not required: a viewer without it shows the mesh.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .model_origin import checked_model, origin_record

GLTF_EXTENSIONS = ("glb", "gltf")
FEATURE_EXTENSION = "EXT_mesh_features"
# float32 holds every integer below this exactly
_EXACT_INTEGERS = 2**24
_ARRAY_BUFFER = 34962
_FLOAT = 5126
_GLB_MAGIC = 0x46546C67
_JSON_CHUNK = 0x4E4F534A
_BIN_CHUNK = 0x004E4942
GENERATOR = "BSP Triangulate"
AXES = "glTF (X, Y, Z) = map (x, z, -y): Y up, -Z north; node translation = the local origin"


def to_y_up(points: np.ndarray) -> np.ndarray:
    """Map frame (x east, y north, z up) to glTF's (x, z, -y)."""
    points = np.asarray(points, dtype=np.float64)
    return np.stack([points[..., 0], points[..., 2], -points[..., 1]], axis=-1)


def from_y_up(points: np.ndarray) -> np.ndarray:
    """glTF (X, Y, Z) back to the map frame: (X, -Z, Y)."""
    points = np.asarray(points, dtype=np.float64)
    return np.stack([points[..., 0], -points[..., 2], points[..., 1]], axis=-1)


def flat_normals(corners: np.ndarray) -> np.ndarray:
    """(M, 3) unit normals of (M, 3, 3) triangles (right-hand rule); (0, 0, 1) for none."""
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normal, axis=1)
    good = length > 0
    out = np.zeros_like(normal)
    out[:, 2] = 1.0
    out[good] = normal[good] / length[good, None]
    return out


class GltfBuffer:
    """The binary buffer, laid out as 4-byte aligned views (one per attribute) of float32
    arrays, which are written as they are (no copy into one ``bytes``)."""

    def __init__(self) -> None:
        self.blocks: list[np.ndarray] = []
        self.length = 0
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def attribute(self, array: np.ndarray, kind: str, bounds: bool = False) -> int:
        """An accessor of float32 ``array`` ((n,) SCALAR or (n, 3) VEC3); its index."""
        data = np.ascontiguousarray(array, dtype="<f4")
        view = {"buffer": 0, "byteOffset": self.length, "byteLength": data.nbytes}
        view["target"] = _ARRAY_BUFFER
        self.views.append(view)
        self.blocks.append(data)
        self.length += data.nbytes  # a multiple of 4: float32 only
        accessor = {
            "bufferView": len(self.views) - 1,
            "componentType": _FLOAT,
            "count": len(data),
            "type": kind,
        }
        if bounds and len(data):
            # min and max of the float32 values themselves (the validator compares them)
            accessor["min"] = [float(v) for v in np.atleast_1d(data.min(axis=0))]
            accessor["max"] = [float(v) for v in np.atleast_1d(data.max(axis=0))]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def write(self, handle) -> None:
        for block in self.blocks:
            handle.write(memoryview(block).cast("B"))

    def data(self) -> bytes:
        return b"".join(block.tobytes() for block in self.blocks)


def _is_feature_id(values: np.ndarray) -> bool:
    if values.dtype == np.bool_:
        return True
    if values.dtype.kind not in "iuf" or not len(values):
        return values.dtype.kind in "iu"
    if values.dtype.kind == "f" and not (
        np.isfinite(values).all() and (values == np.round(values)).all()
    ):
        return False
    return bool(values.min() >= 0 and values.max() < _EXACT_INTEGERS)


def _attribute_name(name: str) -> str:
    token = "".join(c if c.isalnum() else "_" for c in name.upper())
    return "_" + (token or "VALUE")


def gltf_document(
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None = None,
    crs_wkt: str | None = None,
    origin: np.ndarray | None = None,
    name: str = "mesh",
) -> tuple[dict, GltfBuffer]:
    """The glTF JSON (without ``buffers[0].uri``) and its binary buffer."""
    vertices, faces, properties, origin = checked_model(vertices, faces, face_properties, origin)
    # float32 positions of the vertices, then of the faces' corners (the same values as
    # rounding each corner, at a third of the memory)
    local = vertices - origin
    positions = to_y_up(local).astype("<f4")[faces.reshape(-1)]
    normals = np.repeat(to_y_up(_face_normals(local, faces)).astype("<f4"), 3, axis=0)
    del local
    buffer = GltfBuffer()
    attributes = {
        "POSITION": buffer.attribute(positions, "VEC3", bounds=True),
        "NORMAL": buffer.attribute(normals, "VEC3"),
    }
    feature_ids: list[dict] = []
    others: dict[str, str] = {}
    for key, values in properties.items():
        per_vertex = np.repeat(values.astype("<f4"), 3)
        if _is_feature_id(values):
            attribute = f"_FEATURE_ID_{len(feature_ids)}"
            attributes[attribute] = buffer.attribute(per_vertex, "SCALAR")
            count = len(np.unique(values)) if len(values) else 0
            feature_ids.append(
                {"featureCount": max(count, 1), "attribute": len(feature_ids), "label": key}
            )
        else:
            attribute = _attribute_name(key)
            while attribute in attributes:
                attribute += "_"
            attributes[attribute] = buffer.attribute(per_vertex, "SCALAR")
            others[attribute] = key
    primitive: dict = {"attributes": attributes, "mode": 4}
    document: dict = {
        "asset": {
            "version": "2.0",
            "generator": GENERATOR,
            "extras": origin_record(origin, crs_wkt, AXES),
        },
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": name, "mesh": 0, "translation": [float(v) for v in to_y_up(origin)]}],
        "meshes": [{"name": name, "primitives": [primitive]}],
    }
    if feature_ids:
        primitive["extensions"] = {FEATURE_EXTENSION: {"featureIds": feature_ids}}
        document["extensionsUsed"] = [FEATURE_EXTENSION]
    if others:
        primitive["extras"] = {"face_values": others}
    if len(faces):
        document["accessors"] = buffer.accessors
        document["bufferViews"] = buffer.views
        document["buffers"] = [{"byteLength": buffer.length}]
    else:
        # a mesh needs a primitive with a POSITION accessor: an empty mesh has no mesh at all
        del document["meshes"]
        del document["nodes"][0]["mesh"]
    return document, buffer


def _face_normals(local: np.ndarray, faces: np.ndarray, block: int = 1 << 20) -> np.ndarray:
    """:func:`flat_normals` of the faces, a block of faces at a time (bounded float64
    temporaries)."""
    out = np.empty((len(faces), 3), dtype=np.float64)
    for start in range(0, len(faces), block):
        rows = faces[start : start + block]
        out[start : start + block] = flat_normals(local[rows])
    return out


def _json_bytes(document: dict) -> bytes:
    return json.dumps(document, separators=(",", ":"), allow_nan=False).encode("utf-8")


def write_glb(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None = None,
    crs_wkt: str | None = None,
    origin: np.ndarray | None = None,
) -> list[Path]:
    """Write a binary glTF (``.glb``): one file, JSON chunk then BIN chunk. Returns [path]."""
    path = Path(path)
    document, buffer = gltf_document(vertices, faces, face_properties, crs_wkt, origin, path.stem)
    text = _json_bytes(document)
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + (8 + buffer.length if buffer.length else 0)
    with open(path, "wb") as handle:
        handle.write(struct.pack("<III", _GLB_MAGIC, 2, total))
        handle.write(struct.pack("<II", len(text), _JSON_CHUNK) + text)
        if buffer.length:
            handle.write(struct.pack("<II", buffer.length, _BIN_CHUNK))
            buffer.write(handle)
    return [path]


def write_gltf(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None = None,
    crs_wkt: str | None = None,
    origin: np.ndarray | None = None,
    embed: bool = False,
) -> list[Path]:
    """Write a JSON glTF (``.gltf``) with its buffer in ``<stem>.bin`` beside it (default) or,
    with ``embed=True``, inside the JSON as a base64 data URI (a third larger). Returns the
    written paths, the ``.gltf`` first."""
    path = Path(path)
    document, buffer = gltf_document(vertices, faces, face_properties, crs_wkt, origin, path.stem)
    written = [path]
    if buffer.length:
        if embed:
            data = base64.b64encode(buffer.data()).decode()
            uri = "data:application/octet-stream;base64," + data
        else:
            sidecar = path.with_suffix(".bin")
            with open(sidecar, "wb") as handle:
                buffer.write(handle)
            written.append(sidecar)
            uri = sidecar.name
        document["buffers"][0]["uri"] = uri
    path.write_bytes(_json_bytes(document))
    return written
