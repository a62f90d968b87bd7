"""3D model files by extension: ``.glb``, ``.gltf`` (:mod:`.gltf`) and ``.obj`` (:mod:`.obj`)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .gltf import write_glb, write_gltf
from .obj import write_obj

MODEL_EXTENSIONS = ("glb", "gltf", "obj")


def model_format(path: str | os.PathLike) -> str | None:
    """'glb', 'gltf' or 'obj' from the file name; None for any other extension."""
    suffix = Path(path).suffix.lower().lstrip(".")
    return suffix if suffix in MODEL_EXTENSIONS else None


def write_model(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None = None,
    crs_wkt: str | None = None,
    **options,
) -> list[Path]:
    """Write the mesh in the format of ``path``'s extension; the written paths (the model
    first, then its sidecars). ``options`` go to the writer (``origin`` for all; ``embed``
    for .gltf; ``group_by`` and ``labels`` for .obj)."""
    kind = model_format(path)
    if kind is None:
        raise ValueError(f"{path}: not a .glb, .gltf or .obj file name")
    writer = {"glb": write_glb, "gltf": write_gltf, "obj": write_obj}[kind]
    return writer(path, vertices, faces, face_properties, crs_wkt, **options)
