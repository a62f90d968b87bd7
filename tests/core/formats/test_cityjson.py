"""The CityJSON 2.0 writer: the document validates against the official schemas, every Solid
and every shell of a MultiSolid is closed and outward, vertices are quantised once each."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bsp_triangulate.formats.cityjson import (
    CityBuilding,
    cityjson_document,
    reference_system,
    write_cityjson,
)
from bsp_triangulate.packed import PackedPolygons
from bsp_triangulate.solids import build_solids
from tests.model_checks import cityjson_solids, cityjson_validator, ring_edges_closed


def solids_of(polygons, height=6.0, ground=100.0):
    packed = PackedPolygons.of(
        [[np.column_stack([ring, np.full(len(ring), ground + height)]) for ring in rings]
         for rings in polygons]
    )  # fmt: skip
    return build_solids(packed, ground)


OFFSET = np.array([351_182.162, 6e6])
SQUARE = np.array([(0, 0), (10, 0), (10, 10), (0, 10)], dtype=float) + OFFSET
COURT = np.array([(3, 3), (3, 7), (7, 7), (7, 3)], dtype=float) + OFFSET
ELL = np.array([(20, 0), (30, 0), (30, 4), (24, 4), (24, 10), (20, 10)], dtype=float) + OFFSET


@pytest.fixture()
def document() -> dict:
    # building "a": one footprint with a courtyard; building "b": two parts (BuildingParts)
    solids = solids_of([[SQUARE, COURT], [ELL], [SQUARE + np.array([0.0, 20.0])]])
    buildings = [
        CityBuilding("a", [np.flatnonzero(solids.solid == 0)], {"name": "Hall", "h": 6.0}),
        CityBuilding("b", [np.flatnonzero(solids.solid == k) for k in (1, 2)], {"n": np.int64(2)}),
    ]
    return cityjson_document(
        solids.vertices, solids.triangles, solids.surface, buildings, epsg=32733
    )


def test_document_validates_against_the_cityjson_2_schemas(document) -> None:
    errors = sorted(cityjson_validator().iter_errors(document), key=str)
    assert errors == []


def test_every_solid_shell_is_closed_and_outward(document) -> None:
    shells = cityjson_solids(document)
    assert [name for name, _rings in shells] == ["a", "b-1", "b-2"]
    vertices = np.array(document["vertices"]) * document["transform"]["scale"] + np.array(
        document["transform"]["translate"]
    )
    for name, rings in shells:
        assert ring_edges_closed(rings), name
        corners = vertices[np.array(rings)] - vertices.mean(axis=0)
        volume = np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2]))
        assert volume.sum() / 6 > 0


def test_semantics_reference_system_and_transform(document) -> None:
    assert document["version"] == "2.0"
    assert document["metadata"]["referenceSystem"] == reference_system(32733)
    a = document["CityObjects"]["a"]
    assert a["attributes"] == {"name": "Hall", "h": 6.0}
    geometry = a["geometry"][0]
    assert (geometry["type"], geometry["lod"]) == ("Solid", "1")
    kinds = [s["type"] for s in geometry["semantics"]["surfaces"]]
    assert kinds == ["RoofSurface", "WallSurface", "GroundSurface"]
    values = geometry["semantics"]["values"][0]
    assert len(values) == len(geometry["boundaries"][0])
    assert values.count(1) == 2 * 8  # walls: 4 outer edges + 4 courtyard edges
    b = document["CityObjects"]["b"]
    assert (b["geometry"], b["children"]) == ([], ["b-1", "b-2"])
    for child in b["children"]:
        part = document["CityObjects"][child]
        assert (part["type"], part["parents"]) == ("BuildingPart", ["b"])
        assert part["geometry"][0]["type"] == "Solid"
    # quantised to millimetres, each vertex once
    vertices = [tuple(v) for v in document["vertices"]]
    assert len(set(vertices)) == len(vertices)
    assert all(isinstance(c, int) for v in document["vertices"] for c in v)
    assert document["transform"]["scale"] == [0.001] * 3


def test_volume_from_the_quantised_vertices_is_area_times_height(document) -> None:
    scale = np.array(document["transform"]["scale"])
    vertices = np.array(document["vertices"]) * scale + document["transform"]["translate"]
    rings = dict(cityjson_solids(document)[:1])["a"]
    corners = vertices[np.array(rings)] - vertices.mean(axis=0)
    volume = np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum()
    assert volume / 6 == pytest.approx((100 - 16) * 6.0, rel=1e-9)


def test_write_cityjson_writes_the_document(tmp_path) -> None:
    solids = solids_of([[SQUARE]])
    path = write_cityjson(
        tmp_path / "b.city.json",
        solids.vertices,
        solids.triangles,
        solids.surface,
        [CityBuilding("1", [np.arange(len(solids.triangles))])],
        epsg=32733,
    )
    document = json.loads(path.read_text())
    assert list(cityjson_validator().iter_errors(document)) == []
    assert len(document["vertices"]) == 8
