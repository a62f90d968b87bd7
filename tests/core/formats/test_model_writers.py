"""The glTF (.glb, .gltf) and OBJ writers: the Khronos glTF Validator finds no error, trimesh
reads every file back with the written counts and bounds, the origin and CRS are kept at full
precision, per-face values are feature IDs (glTF) and groups (OBJ)."""

from __future__ import annotations

import base64
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from bsp_triangulate import triangulate
from bsp_triangulate.formats.gltf import (
    FEATURE_EXTENSION,
    from_y_up,
    gltf_document,
    to_y_up,
    write_glb,
    write_gltf,
)
from bsp_triangulate.formats.models import model_format, write_model
from bsp_triangulate.formats.obj import write_obj
from tests import model_checks
from tests.model_checks import assert_valid_gltf, trimesh_read

gltf_validator = model_checks.gltf_validator  # the session fixture, used by name

# far from the CRS origin (UTM 33S northings), where float32 would lose centimetres
X0, Y0 = 351_182.162, 6_210_733.389
WKT = 'PROJCS["WGS 84 / UTM zone 33S",AUTHORITY["EPSG","32733"]]'


def two_features() -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """A concave polygon with two islands (feature 7) and a sloped square (feature 12)."""
    first = triangulate(
        [
            [(0, 0, 100), (20, 0, 100), (20, 20, 101), (10, 8, 102), (0, 20, 103)],
            [(2, 2, 100), (6, 2, 100), (6, 5, 100), (2, 5, 100)],
            [(14, 3, 100), (17, 2.5, 100), (15, 6, 100)],
        ]
    )
    second = triangulate([[(30, 0, 90), (40, 0, 95), (40, 10, 99.25), (30, 10, 94.5)]])
    vertices = np.concatenate([first.vertices, second.vertices]) + np.array([X0, Y0, 0.0])
    faces = np.concatenate([first.triangles, second.triangles + len(first.vertices)])
    properties = {
        "feature_id": np.repeat([7, 12], [len(first), len(second)]),
        "depth": np.concatenate([first.depth, second.depth]).astype(np.int32),
    }
    return vertices, faces, properties


def read_glb(path: Path) -> tuple[dict, bytes]:
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<III", data)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    json_length, kind = struct.unpack_from("<II", data, 12)
    assert kind == 0x4E4F534A and json_length % 4 == 0
    document = json.loads(data[20 : 20 + json_length])
    bin_length, kind = struct.unpack_from("<II", data, 20 + json_length)
    assert kind == 0x004E4942
    return document, data[28 + json_length : 28 + json_length + bin_length]


def accessor(document: dict, binary: bytes, index: int) -> np.ndarray:
    acc = document["accessors"][index]
    view = document["bufferViews"][acc["bufferView"]]
    width = {"SCALAR": 1, "VEC3": 3}[acc["type"]]
    values = np.frombuffer(binary, "<f4", acc["count"] * width, view["byteOffset"])
    return values.reshape(-1, width) if width > 1 else values


@pytest.fixture()
def mesh():
    return two_features()


def test_y_up_is_a_rotation_and_reversible() -> None:
    points = np.array([[1.0, 2.0, 3.0], [-4.0, 5.5, 0.0]])
    assert to_y_up(points).tolist() == [[1.0, 3.0, -2.0], [-4.0, 0.0, -5.5]]
    np.testing.assert_array_equal(from_y_up(to_y_up(points)), points)
    rotation = to_y_up(np.eye(3))
    assert np.linalg.det(rotation) == pytest.approx(1.0)  # winding kept


def test_glb_and_gltf_pass_the_khronos_validator(tmp_path: Path, mesh, gltf_validator) -> None:
    vertices, faces, properties = mesh
    written = [
        *write_glb(tmp_path / "a.glb", vertices, faces, properties, WKT),
        *write_gltf(tmp_path / "b.gltf", vertices, faces, properties, WKT),
        *write_gltf(tmp_path / "c.gltf", vertices, faces, properties, WKT, embed=True),
        *write_glb(tmp_path / "plain.glb", vertices, faces),
        *write_glb(tmp_path / "empty.glb", np.zeros((0, 3)), np.zeros((0, 3), int)),
    ]
    models = [path for path in written if path.suffix in (".glb", ".gltf")]
    assert [path.name for path in written] == [
        "a.glb", "b.gltf", "b.bin", "c.gltf", "plain.glb", "empty.glb"
    ]  # fmt: skip
    assert_valid_gltf(gltf_validator, *models)


def test_float_and_large_face_values_are_plain_attributes_and_still_valid(
    tmp_path: Path, mesh, gltf_validator
) -> None:
    vertices, faces, _ = mesh
    values = {
        "slope": np.linspace(0.0, 45.5, len(faces)),
        "feature_id": np.arange(len(faces)) + 2**30,
    }
    path = write_glb(tmp_path / "values.glb", vertices, faces, values)[0]
    document, _ = read_glb(path)
    primitive = document["meshes"][0]["primitives"][0]
    assert primitive["extras"]["face_values"] == {"_SLOPE": "slope", "_FEATURE_ID": "feature_id"}
    assert "extensions" not in primitive
    assert_valid_gltf(gltf_validator, path)


def test_glb_keeps_the_origin_at_full_precision_and_the_crs(tmp_path: Path, mesh) -> None:
    vertices, faces, properties = mesh
    path = write_glb(tmp_path / "m.glb", vertices, faces, properties, WKT)[0]
    document, binary = read_glb(path)
    extras = document["asset"]["extras"]
    assert extras["crs_wkt"] == WKT
    origin = np.array(extras["origin_xyz"])
    np.testing.assert_array_equal(origin, np.round((vertices.min(0) + vertices.max(0)) / 2))
    translation = np.array(document["nodes"][0]["translation"])
    np.testing.assert_array_equal(from_y_up(translation), origin)
    primitive = document["meshes"][0]["primitives"][0]
    positions = accessor(document, binary, primitive["attributes"]["POSITION"])
    # every corner of every face, in the map frame: within float32 rounding of the
    # local coordinates (a few micrometres here), not of the 6,000 km coordinates
    corners = from_y_up(positions.astype(np.float64)) + origin
    np.testing.assert_allclose(corners, vertices[faces.ravel()], rtol=0, atol=1e-5)
    acc = document["accessors"][primitive["attributes"]["POSITION"]]
    assert acc["min"] == positions.min(0).tolist() and acc["max"] == positions.max(0).tolist()


def test_glb_face_values_are_ext_mesh_features_ids_per_triangle(tmp_path: Path, mesh) -> None:
    vertices, faces, properties = mesh
    path = write_glb(tmp_path / "m.glb", vertices, faces, properties)[0]
    document, binary = read_glb(path)
    assert document["extensionsUsed"] == [FEATURE_EXTENSION]
    assert "extensionsRequired" not in document
    primitive = document["meshes"][0]["primitives"][0]
    assert "indices" not in primitive
    feature_ids = primitive["extensions"][FEATURE_EXTENSION]["featureIds"]
    assert feature_ids == [
        {"featureCount": 2, "attribute": 0, "label": "feature_id"},
        {"featureCount": len(np.unique(properties["depth"])), "attribute": 1, "label": "depth"},
    ]
    for k, name in enumerate(("feature_id", "depth")):
        values = accessor(document, binary, primitive["attributes"][f"_FEATURE_ID_{k}"])
        np.testing.assert_array_equal(values, np.repeat(properties[name], 3))


def test_glb_normals_are_flat_unit_and_up_for_a_counter_clockwise_surface(
    tmp_path: Path, mesh
) -> None:
    vertices, faces, properties = mesh
    document, buffer = gltf_document(vertices, faces, properties)
    binary = buffer.data()
    primitive = document["meshes"][0]["primitives"][0]
    normals = accessor(document, binary, primitive["attributes"]["NORMAL"]).astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    assert (normals[:, 1] > 0).all()  # Y up: every face of the surface faces up
    np.testing.assert_array_equal(normals[0::3], normals[1::3])


def test_gltf_sidecar_and_data_uri_hold_the_same_buffer(tmp_path: Path, mesh) -> None:
    vertices, faces, properties = mesh
    write_gltf(tmp_path / "s.gltf", vertices, faces, properties)
    write_gltf(tmp_path / "e.gltf", vertices, faces, properties, embed=True)
    sidecar = json.loads((tmp_path / "s.gltf").read_text())
    embedded = json.loads((tmp_path / "e.gltf").read_text())
    assert sidecar["buffers"][0]["uri"] == "s.bin"
    prefix = "data:application/octet-stream;base64,"
    assert embedded["buffers"][0]["uri"].startswith(prefix)
    data = base64.b64decode(embedded["buffers"][0]["uri"][len(prefix) :])
    assert data == (tmp_path / "s.bin").read_bytes()
    assert len(data) == sidecar["buffers"][0]["byteLength"]


@pytest.mark.parametrize("name", ["m.glb", "m.gltf"])
def test_trimesh_reads_gltf_back_with_counts_and_bounds(tmp_path: Path, mesh, name) -> None:
    vertices, faces, properties = mesh
    write_model(tmp_path / name, vertices, faces, properties, WKT)
    read = trimesh_read(tmp_path / name)
    assert len(read.faces) == len(faces)
    assert len(read.vertices) == 3 * len(faces)  # each face its own three vertices
    corners = vertices[faces.ravel()]
    # trimesh applies the node translation: bounds in the glTF frame, full coordinates
    bounds = from_y_up(np.asarray(read.bounds))
    np.testing.assert_allclose(np.sort(bounds, axis=0), [corners.min(0), corners.max(0)], atol=1e-3)


def test_trimesh_reads_obj_back_with_counts_and_bounds(tmp_path: Path, mesh) -> None:
    vertices, faces, properties = mesh
    written = write_obj(tmp_path / "m.obj", vertices, faces, properties, WKT)
    assert [path.name for path in written] == ["m.obj", "m.origin.json", "m.prj"]
    origin = np.array(json.loads(written[1].read_text())["origin_xyz"])
    read = trimesh_read(written[0])
    assert (len(read.vertices), len(read.faces)) == (len(vertices), len(faces))
    np.testing.assert_allclose(
        read.bounds + origin, [vertices.min(0), vertices.max(0)], rtol=0, atol=1e-9
    )
    assert written[2].read_text() == WKT


def test_obj_vertices_read_back_exactly_relative_to_the_header_origin(tmp_path: Path, mesh) -> None:
    vertices, faces, properties = mesh
    path = write_obj(tmp_path / "m.obj", vertices, faces, properties)[0]
    text = path.read_text()
    origin = np.array([float(v) for v in re.search(r"^# origin (.+)$", text, re.M)[1].split()])
    rows = [line.split()[1:] for line in text.splitlines() if line.startswith("v ")]
    local = np.array(rows, dtype=np.float64)
    np.testing.assert_array_equal(local, vertices - origin)
    face_rows = [line.split()[1:] for line in text.splitlines() if line.startswith("f ")]
    np.testing.assert_array_equal(np.array(face_rows, dtype=np.int64) - 1, faces)


def test_obj_groups_follow_the_feature_ids(tmp_path: Path, mesh) -> None:
    vertices, faces, properties = mesh
    # the features interleaved: a group starts again where its faces start again
    order = np.argsort(np.arange(len(faces)) % 3, kind="stable")
    values = {name: column[order] for name, column in properties.items()}
    path = write_obj(tmp_path / "m.obj", vertices, faces[order], values)[0]
    current, seen = None, []
    for line in path.read_text().splitlines():
        if line.startswith("g "):
            current = line[2:]
        elif line.startswith("f "):
            seen.append(current)
    assert seen == [f"feature_id_{v}" for v in values["feature_id"]]


def test_obj_groups_by_several_values_with_labels(tmp_path: Path) -> None:
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 1, 3]])
    values = {"building": np.array([5, 5, 5]), "surface": np.array([0, 0, 1])}
    path = write_obj(
        tmp_path / "m.obj",
        vertices,
        faces,
        values,
        group_by=["building", "surface"],
        labels={"surface": ("roof", "wall", "floor")},
        origin=np.zeros(3),
    )[0]
    lines = [line for line in path.read_text().splitlines() if line[:2] in ("g ", "f ")]
    assert lines == [
        "g building_5 surface_roof", "f 1 2 3", "f 1 3 4", "g building_5 surface_wall", "f 1 2 4"
    ]  # fmt: skip


def test_obj_groups_across_write_blocks(tmp_path: Path, monkeypatch) -> None:
    from bsp_triangulate.formats import obj

    monkeypatch.setattr(obj, "_CHUNK", 4)
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]], dtype=float)
    faces = np.tile(np.arange(3), (11, 1))
    ids = np.array([1, 1, 1, 1, 1, 2, 2, 3, 3, 3, 3])
    path = write_obj(tmp_path / "m.obj", vertices, faces, {"id": ids})[0]
    lines = [line for line in path.read_text().splitlines() if line[:2] in ("g ", "f ")]
    assert [line for line in lines if line.startswith("g ")] == ["g id_1", "g id_2", "g id_3"]
    assert len(lines) == 14


def test_write_model_dispatches_by_extension(tmp_path: Path, mesh) -> None:
    vertices, faces, _ = mesh
    assert [model_format(name) for name in ("a.GLB", "b.gltf", "c.obj", "d.ply")] == [
        "glb", "gltf", "obj", None
    ]  # fmt: skip
    with pytest.raises(ValueError, match=r"not a \.glb"):
        write_model(tmp_path / "m.ply", vertices, faces)


def test_writers_reject_bad_input(tmp_path: Path, mesh) -> None:
    vertices, faces, _ = mesh
    with pytest.raises(ValueError, match="outside"):
        write_glb(tmp_path / "m.glb", vertices, faces + len(vertices))
    with pytest.raises(ValueError, match="values for"):
        write_obj(tmp_path / "m.obj", vertices, faces, {"id": np.zeros(2)})
    with pytest.raises(ValueError, match="origin"):
        write_gltf(tmp_path / "m.gltf", vertices, faces, origin=np.array([np.nan, 0, 0]))
