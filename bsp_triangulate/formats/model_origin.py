"""What the 3D model writers (:mod:`.gltf`, :mod:`.obj`) share: their checked input, the local
origin the vertices are written relative to, and the record that places a model on the map."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .mesh import _check_face_values, _check_mesh


def default_origin(vertices: np.ndarray) -> np.ndarray:
    """The centre of the bounding box, rounded to whole units (0 for an empty mesh)."""
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if not len(vertices):
        return np.zeros(3)
    return np.round((vertices.min(axis=0) + vertices.max(axis=0)) / 2.0)


def checked_model(
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None,
    origin: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The vertices, faces, per-face values and local origin (``default_origin`` when None)
    as the writers use them; ValueError for any that does not fit."""
    vertices, faces = _check_mesh(vertices, faces)
    properties = {
        key: _check_face_values(key, values, len(faces))
        for key, values in (face_properties or {}).items()
    }
    origin = default_origin(vertices) if origin is None else np.asarray(origin, np.float64)
    if origin.shape != (3,) or not np.isfinite(origin).all():
        raise ValueError("origin must be three finite numbers")
    return vertices, faces, properties, origin


def origin_record(origin: np.ndarray, crs_wkt: str | None, axes: str) -> dict:
    """The local origin in the map frame, the CRS ('' without one) and the axis convention,
    as JSON values (glTF's ``asset.extras``, an OBJ's ``.origin.json``)."""
    return {"origin_xyz": [float(v) for v in origin], "crs_wkt": crs_wkt or "", "axes": axes}
