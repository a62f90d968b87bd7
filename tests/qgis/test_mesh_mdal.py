"""Written 2DM and PLY meshes load through QGIS's mdal provider with their face datasets."""

from __future__ import annotations

import numpy as np
import pytest
from qgis.core import QgsMesh, QgsMeshDatasetGroupMetadata, QgsMeshDatasetIndex, QgsMeshLayer

from bsp_triangulate.formats.mesh import merge_meshes, write_2dm, write_ply


@pytest.fixture
def terrain_mesh():
    """Two grids of triangles on z = 0.1 x - 0.05 y + 3 that share their common edge."""
    parts = []
    for x0 in (0.0, 50.0):
        xs, ys = np.meshgrid(np.linspace(x0, x0 + 50, 6), np.linspace(0, 40, 5))
        vertices = np.column_stack(
            [xs.ravel(), ys.ravel(), 0.1 * xs.ravel() - 0.05 * ys.ravel() + 3]
        )
        cells = np.arange(30).reshape(5, 6)[:-1, :-1].ravel()
        triangles = np.vstack(
            [np.c_[cells, cells + 1, cells + 7], np.c_[cells, cells + 7, cells + 6]]
        )
        parts.append((vertices, triangles))
    vertices, faces, part = merge_meshes(parts)
    return vertices, faces, {"feature_id": part + 100, "depth": np.arange(len(faces)) % 7}


def _load(path, extra=None):
    layer = QgsMeshLayer(str(path), "mesh", "mdal")
    assert layer.isValid(), layer.error().summary()
    provider = layer.dataProvider()
    if extra is not None:
        assert provider.addDataset(str(extra))
    mesh = QgsMesh()
    provider.populateMesh(mesh)
    return layer, mesh


def _face_groups(provider) -> dict[str, np.ndarray]:
    groups = {}
    for group in range(provider.datasetGroupCount()):
        meta = provider.datasetGroupMetadata(group)
        if meta.dataType() != QgsMeshDatasetGroupMetadata.DataOnFaces:
            continue
        values = provider.datasetValues(QgsMeshDatasetIndex(group, 0), 0, provider.faceCount())
        groups[meta.name()] = np.array([values.value(i).scalar() for i in range(values.count())])
    return groups


def _check_geometry(provider, mesh, vertices, faces):
    assert provider.vertexCount() == len(vertices) == 60 - 5
    assert provider.faceCount() == len(faces) == 80
    got = np.array(
        [[mesh.vertex(i).x(), mesh.vertex(i).y(), mesh.vertex(i).z()] for i in range(len(vertices))]
    )
    np.testing.assert_array_equal(got, vertices)
    np.testing.assert_array_equal(np.array([mesh.face(i) for i in range(len(faces))]), faces)


@pytest.mark.parametrize("binary", [True, False])
def test_ply_loads_with_z_and_face_datasets(qgis_app, tmp_path, terrain_mesh, binary):
    vertices, faces, datasets = terrain_mesh
    path = write_ply(tmp_path / "terrain.ply", vertices, faces, datasets, binary=binary)
    layer, mesh = _load(path)
    provider = layer.dataProvider()
    _check_geometry(provider, mesh, vertices, faces)
    groups = _face_groups(provider)
    assert set(groups) == {"feature_id", "depth"}
    np.testing.assert_array_equal(groups["feature_id"], datasets["feature_id"])
    np.testing.assert_array_equal(groups["depth"], datasets["depth"])


def test_2dm_loads_with_z_and_els_dat_face_datasets(qgis_app, tmp_path, terrain_mesh):
    vertices, faces, datasets = terrain_mesh
    mesh_path, dat_path = write_2dm(tmp_path / "terrain.2dm", vertices, faces, datasets)
    layer, mesh = _load(mesh_path, extra=dat_path)
    provider = layer.dataProvider()
    _check_geometry(provider, mesh, vertices, faces)
    assert provider.extraDatasets() == [str(dat_path)]
    groups = _face_groups(provider)
    assert set(groups) == {"feature_id", "depth"}
    np.testing.assert_array_equal(groups["depth"], datasets["depth"])


def test_2dm_full_precision_and_exponent_tokens_load_bit_for_bit(qgis_app, tmp_path, terrain_mesh):
    # 17-digit coordinates, repr's exponent notation (1e-07, 1e+22), -0.0 and negative values
    # as MDAL's atof reads them, in the mesh and in the _els.dat face values.
    vertices, faces, _ = terrain_mesh
    rng = np.random.default_rng(3)
    vertices = vertices + np.array([351182.0, 6.0e6, 0.0]) + rng.uniform(0, 1, vertices.shape)
    vertices[:4, 2] = [-0.0, 1e-7, -1e22, 2.0**53 + 2]
    values = rng.uniform(-1e3, 1e3, len(faces))
    values[:5] = [0.1, 1e-7, 1e22, -2.5, 0.30000000000000004]
    mesh_path, dat_path = write_2dm(tmp_path / "precise.2dm", vertices, faces, {"h": values})
    assert b"1e-07" in mesh_path.read_bytes() and b"1e+22" in dat_path.read_bytes()
    layer, mesh = _load(mesh_path, extra=dat_path)
    provider = layer.dataProvider()
    got = np.array(
        [[mesh.vertex(i).x(), mesh.vertex(i).y(), mesh.vertex(i).z()] for i in range(len(vertices))]
    )
    assert np.array_equal(got.view(np.uint64), vertices.view(np.uint64))
    np.testing.assert_array_equal(np.array([mesh.face(i) for i in range(len(faces))]), faces)
    assert np.array_equal(_face_groups(provider)["h"], values)
