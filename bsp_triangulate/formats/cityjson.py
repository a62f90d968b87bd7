"""Writing building solids as CityJSON 2.0 (``.city.json``), pure numpy and the standard library.

One ``Building`` city object per building, with one LoD1 ``Solid``; a building of several
parts (a multi-part footprint) has no geometry of its own but one ``BuildingPart`` child per
part (ids ``<id>-1``, ``<id>-2``, ...), each with its ``Solid`` (CityJSON allows no
``MultiSolid`` on a ``Building``). Every
triangle of a solid is one surface (a triangle ring) of its shell, with its semantic surface:
``RoofSurface``, ``WallSurface`` or ``GroundSurface``. The shells are outward oriented, as
CityJSON wants (counter-clockwise seen from outside).

Vertices are quantised: integers with the root ``transform`` (``scale``, by default 1 mm, and
``translate``, the lowest corner of the vertices), listed once each (identical quantised
vertices are one). A triangle that quantisation collapses (two corners within half a scale
step) is dropped; its neighbours then close the shell. The CRS goes to
``metadata.referenceSystem`` as an OGC CRS URL
(``https://www.opengis.net/def/crs/EPSG/0/<code>``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

SEMANTIC_TYPES = ("RoofSurface", "WallSurface", "GroundSurface")
VERSION = "2.0"


@dataclass
class CityBuilding:
    """A building: its city object id, the rows of its solids' triangles (one array per
    part), and its attributes (JSON values)."""

    id: str
    parts: Sequence[np.ndarray]
    attributes: Mapping[str, object] = field(default_factory=dict)


def reference_system(epsg: int) -> str:
    return f"https://www.opengis.net/def/crs/EPSG/0/{int(epsg)}"


def _json_value(value: object) -> object:
    """An attribute as a JSON value (numpy scalars to Python, others as text)."""
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, np.generic):
        return _json_value(value.item())
    return str(value)


def quantise(vertices: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(integer vertices, each once; translate; index of each input vertex's integer one)."""
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    translate = vertices.min(axis=0) if len(vertices) else np.zeros(3)
    integers = np.round((vertices - translate) / scale).astype(np.int64)
    unique, inverse = np.unique(integers, axis=0, return_inverse=True)
    return unique, translate, inverse.ravel()


def cityjson_document(
    vertices: np.ndarray,
    triangles: np.ndarray,
    surface: np.ndarray,
    buildings: Sequence[CityBuilding],
    epsg: int | None = None,
    scale: float = 0.001,
    title: str | None = None,
) -> dict:
    """The CityJSON document of ``buildings`` (parts: rows of ``triangles``, whose
    ``surface`` is 0 roof, 1 wall, 2 floor)."""
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    surface = np.asarray(surface, dtype=np.int64).ravel()
    rows = [np.asarray(part, dtype=np.int64) for b in buildings for part in b.parts]
    used = np.unique(triangles[np.concatenate(rows)].ravel()) if rows else np.zeros(0, np.int64)
    integers, translate, inverse = quantise(np.asarray(vertices)[used], scale)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = inverse
    quantised = remap[triangles]
    # triangles collapsed by quantisation are dropped
    distinct = (
        (quantised[:, 0] != quantised[:, 1])
        & (quantised[:, 1] != quantised[:, 2])
        & (quantised[:, 0] != quantised[:, 2])
    )
    objects: dict[str, dict] = {}
    for building in buildings:
        solids = []
        for part in building.parts:
            part = np.asarray(part, dtype=np.int64)
            part = part[distinct[part]]
            solids.append(
                {
                    "type": "Solid",
                    "lod": "1",
                    "boundaries": [[[ring] for ring in quantised[part].tolist()]],
                    "semantics": {"surfaces": _surfaces(), "values": [surface[part].tolist()]},
                }
            )
        name = str(building.id)
        city_object: dict = {"type": "Building"}
        attributes = {str(k): _json_value(v) for k, v in building.attributes.items()}
        if attributes:
            city_object["attributes"] = attributes
        objects[name] = city_object
        if len(solids) == 1:
            city_object["geometry"] = solids
            continue
        # a Building takes no MultiSolid: one BuildingPart per part, each with its Solid
        children = [f"{name}-{k + 1}" for k in range(len(solids))]
        city_object["geometry"] = []
        city_object["children"] = children
        for child, solid in zip(children, solids):
            objects[child] = {"type": "BuildingPart", "parents": [name], "geometry": [solid]}
    document: dict = {
        "type": "CityJSON",
        "version": VERSION,
        "transform": {"scale": [scale] * 3, "translate": [float(v) for v in translate]},
        "CityObjects": objects,
        "vertices": integers.tolist(),
    }
    metadata: dict = {}
    if epsg:
        metadata["referenceSystem"] = reference_system(epsg)
    if len(integers):
        low = translate + integers.min(axis=0) * scale
        high = translate + integers.max(axis=0) * scale
        metadata["geographicalExtent"] = [float(v) for v in (*low, *high)]
    if title:
        metadata["title"] = title
    if metadata:
        document["metadata"] = metadata
    return document


def _surfaces() -> list[dict]:
    return [{"type": kind} for kind in SEMANTIC_TYPES]


def write_cityjson(
    path: str | os.PathLike,
    vertices: np.ndarray,
    triangles: np.ndarray,
    surface: np.ndarray,
    buildings: Sequence[CityBuilding],
    epsg: int | None = None,
    scale: float = 0.001,
    title: str | None = None,
) -> Path:
    """Write :func:`cityjson_document` as compact JSON; returns the path."""
    path = Path(path)
    document = cityjson_document(vertices, triangles, surface, buildings, epsg, scale, title)
    with open(path, "w", encoding="utf-8") as handle:
        json.dump(document, handle, separators=(",", ":"), allow_nan=False)
    return path
