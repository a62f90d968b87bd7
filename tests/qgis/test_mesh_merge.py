"""The Processing mesh's vertex merge (hash sort) against the core's exact row merge."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import load_plugin_package

load_plugin_package()

from bsptriangulate.bsp_triangulate.formats.mesh import merge_meshes  # noqa: E402
from bsptriangulate.processing_provider.outputs import merge_identical_vertices  # noqa: E402


@pytest.mark.parametrize("seed", range(6))
def test_merge_matches_the_exact_row_merge(seed):
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 400))
    # few distinct values: many repeated vertices, some differing only in one coordinate
    vertices = rng.choice([0.0, -0.0, 1.0, 2.5, -3.0, np.nan], size=(count, 3))
    if seed % 2:
        vertices = np.vstack([vertices, rng.normal(size=(count, 3))])  # unique ones too
    faces = rng.integers(0, len(vertices), (2 * count, 3)).astype(np.int32)
    expected_vertices, expected_faces, _part = merge_meshes([(vertices.copy(), faces)])
    got_vertices, got_faces = merge_identical_vertices(vertices.copy(), faces)
    # the same vertices (its zeros are all +0.0, as documented) and faces
    np.testing.assert_array_equal(got_vertices, expected_vertices)
    assert not np.signbit(got_vertices[got_vertices == 0]).any()
    np.testing.assert_array_equal(got_faces, expected_faces)


def test_merge_without_repeated_vertices_keeps_the_arrays():
    vertices = np.random.default_rng(1).normal(size=(1000, 3))
    vertices[0, 2] = -0.0
    faces = np.arange(999, dtype=np.int32).reshape(-1, 3)
    got_vertices, got_faces = merge_identical_vertices(vertices, faces)
    assert got_faces is faces
    assert got_vertices[0, 2] == 0.0 and not np.signbit(got_vertices[0, 2])
    expected_vertices, _faces, _part = merge_meshes([(vertices, faces)])
    np.testing.assert_array_equal(got_vertices, expected_vertices)
