"""Mesh merging and the 2DM / PLY writers, read back with plain numpy."""

from __future__ import annotations

import numpy as np
import pytest

from bsp_triangulate.formats import mesh as mesh_module
from bsp_triangulate.formats.mesh import merge_meshes, write_2dm, write_face_dat, write_ply

SQUARE = (
    np.array([[0, 0, 1.5], [10, 0, 2.25], [10, 10, 3.125], [0, 10, 0.1]]),
    np.array([[0, 1, 2], [0, 2, 3]]),
)
# Shares the edge (10, 0, 2.25)-(10, 10, 3.125) with SQUARE; one vertex differs only in z.
NEIGHBOUR = (
    np.array([[10, 0, 2.25], [20, 5, 7.0], [10, 10, 3.125], [0, 10, 99.0]]),
    np.array([[0, 1, 2], [2, 3, 0]]),
)


def _read_ply(path, encoding="ascii"):
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode(encoding).splitlines()
    return header, data[end:]


def test_merge_shares_vertices_equal_in_xyz_and_keeps_first_appearance_order():
    vertices, faces, part = merge_meshes([SQUARE, NEIGHBOUR])
    assert len(vertices) == 6  # 4 + 4 minus the two shared corners
    np.testing.assert_array_equal(vertices[:4], SQUARE[0])
    np.testing.assert_array_equal(vertices[4:], [[20, 5, 7.0], [0, 10, 99.0]])
    np.testing.assert_array_equal(part, [0, 0, 1, 1])
    for index, (v, t) in enumerate([SQUARE, NEIGHBOUR]):
        np.testing.assert_array_equal(vertices[faces[part == index]], v[t])


def test_merge_treats_negative_zero_as_zero_and_handles_empty_input():
    a = (np.array([[0.0, 0.0, 0.0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    b = (np.array([[-0.0, 0.0, -0.0], [1, 0, 0], [0, -1, 0]]), np.array([[0, 2, 1]]))
    vertices, faces, _ = merge_meshes([a, b])
    assert len(vertices) == 4
    assert faces[1, 0] == faces[0, 0]
    vertices, faces, part = merge_meshes([])
    assert vertices.shape == (0, 3) and faces.shape == (0, 3) and part.shape == (0,)
    with pytest.raises(ValueError, match="part 0"):
        merge_meshes([(SQUARE[0], SQUARE[1] + 2)])


def test_2dm_lines_are_one_based_and_coordinates_round_trip_exactly(tmp_path):
    rng = np.random.default_rng(5)
    vertices = rng.uniform(-1e6, 1e6, size=(200, 3))
    faces = rng.integers(0, 200, size=(300, 3))
    path = tmp_path / "mesh.2dm"
    assert write_2dm(path, vertices, faces) == [path]
    lines = path.read_text().splitlines()
    assert lines[0] == "MESH2D"
    nodes = [line.split() for line in lines if line.startswith("ND ")]
    elements = [line.split() for line in lines if line.startswith("E3T ")]
    assert [int(n[1]) for n in nodes] == list(range(1, 201))
    np.testing.assert_array_equal(np.array([n[2:] for n in nodes], dtype=float), vertices)
    np.testing.assert_array_equal(np.array([e[2:5] for e in elements], dtype=int), faces + 1)
    assert {e[5] for e in elements} == {"1"} and len(elements) == 300


def test_2dm_face_datasets_go_to_an_els_dat_companion(tmp_path):
    path = tmp_path / "roofs.2dm"
    written = write_2dm(path, *SQUARE, {"feature_id": np.array([4, 4]), "slope": [0.5, 12.25]})
    assert written == [path, tmp_path / "roofs_els.dat"]
    text = written[1].read_text()
    assert text.startswith("DATASET\nOBJTYPE mesh2d\n")
    assert text.count("BEGSCL") == 2 and text.count("ENDDS") == 2
    assert 'NAME "slope"\nTS 0 0\n0.5\n12.25\nENDDS' in text
    assert 'NAME "feature_id"\nTS 0 0\n4\n4\nENDDS' in text  # whole numbers as integers
    with pytest.raises(ValueError, match="_els"):
        write_face_dat(tmp_path / "plain.dat", 4, 2, {"a": [1, 2]})
    with pytest.raises(ValueError, match="3 values for 2 faces"):
        write_2dm(path, *SQUARE, {"a": [1, 2, 3]})


def test_binary_ply_header_and_records(tmp_path):
    path = write_ply(
        tmp_path / "m.ply",
        *SQUARE,
        {"feature_id": np.array([7, 9], dtype=np.int64), "slope": np.array([1.5, 2.5])},
        crs_wkt='PROJCS["a",\n  GEOGCS["b"]]',
    )
    header, body = _read_ply(path)
    assert header[:3] == [
        "ply",
        "format binary_little_endian 1.0",
        'comment crs: PROJCS["a", GEOGCS["b"]]',
    ]
    assert header[3:] == [
        "element vertex 4",
        "property double x",
        "property double y",
        "property double z",
        "element face 2",
        "property list uchar int vertex_indices",
        "property int feature_id",
        "property double slope",
        "end_header",
    ]
    np.testing.assert_array_equal(np.frombuffer(body[: 4 * 24], "<f8").reshape(4, 3), SQUARE[0])
    face_dtype = np.dtype([("n", "u1"), ("v", "<i4", 3), ("fid", "<i4"), ("slope", "<f8")])
    records = np.frombuffer(body[4 * 24 :], face_dtype)
    assert len(body) == 4 * 24 + 2 * face_dtype.itemsize
    np.testing.assert_array_equal(records["n"], 3)
    np.testing.assert_array_equal(records["v"], SQUARE[1])
    np.testing.assert_array_equal(records["fid"], [7, 9])
    np.testing.assert_array_equal(records["slope"], [1.5, 2.5])


def test_ply_crs_comment_is_keyed_as_mdal_splits_it_and_written_in_utf8(tmp_path):
    # MDAL takes a comment's text up to its first colon as the key and "crs" as the CRS:
    # the key must come first, whatever colons the WKT itself holds.
    wkt = 'PROJCRS["x",\n    USAGE[AREA["12°E to 18°E: south"]]]'
    path = write_ply(tmp_path / "c.ply", *SQUARE, crs_wkt=wkt, binary=False)
    header, _body = _read_ply(path, encoding="utf-8")
    line = 'comment crs: PROJCRS["x", USAGE[AREA["12°E to 18°E: south"]]]'
    assert header[2] == line
    key, value = line[len("comment ") :].split(":", 1)
    assert (key, value.strip()) == ("crs", wkt.replace("\n    ", " "))
    assert mesh_module.ply_crs_comment("EPSG:32733") == "comment crs: EPSG:32733"
    no_crs, _body = _read_ply(write_ply(tmp_path / "n.ply", *SQUARE), encoding="utf-8")
    assert not any(h.startswith("comment") for h in no_crs)


def test_ascii_ply_reads_back_with_loadtxt(tmp_path):
    path = write_ply(tmp_path / "a.ply", *SQUARE, {"depth": np.array([0, 1])}, binary=False)
    header, body = _read_ply(path)
    assert header[1] == "format ascii 1.0"
    rows = body.decode().splitlines()
    np.testing.assert_array_equal(np.loadtxt(rows[:4]), SQUARE[0])
    np.testing.assert_array_equal(
        np.loadtxt(rows[4:], dtype=int), [[3, 0, 1, 2, 0], [3, 0, 2, 3, 1]]
    )


def test_ply_rejects_bad_names_and_out_of_range_faces(tmp_path):
    with pytest.raises(ValueError, match="identifier"):
        write_ply(tmp_path / "x.ply", *SQUARE, {"feature id": [1, 2]})
    with pytest.raises(ValueError, match="outside"):
        write_ply(tmp_path / "x.ply", SQUARE[0], SQUARE[1] + 3)


def test_2dm_coordinates_of_every_kind_read_back_bit_for_bit(tmp_path, monkeypatch):
    monkeypatch.setattr(mesh_module, "_CHUNK_ROWS", 7)  # several blocks: ids run on across them
    rng = np.random.default_rng(8)
    vertices = np.concatenate(
        [
            rng.uniform(3e5, 4e5, (20, 3)),
            np.round(rng.uniform(-6.1e6, 6.1e6, (20, 3)), 3),
            [[-0.0, 0.0, 1e-7], [1e22, -5e-324, 2.0**53 + 2], [0.1, -1e-4, 9999999999999998.0]],
        ]
    )
    faces = rng.integers(0, len(vertices), size=(30, 3)).astype(np.int32)
    path = tmp_path / "mesh.2dm"
    write_2dm(path, vertices, faces, {"id": np.arange(30), "h": np.linspace(-1, 1, 30)})
    lines = path.read_text(encoding="ascii").splitlines()
    nodes = [line.split(" ") for line in lines if line.startswith("ND ")]
    assert [int(n[1]) for n in nodes] == list(range(1, len(vertices) + 1))
    back = np.array([[float(t) for t in n[2:]] for n in nodes])
    assert np.array_equal(back.view(np.uint64), vertices.view(np.uint64))  # -0.0 too
    elements = [line.split(" ") for line in lines if line.startswith("E3T ")]
    assert [int(e[1]) for e in elements] == list(range(1, 31))
    np.testing.assert_array_equal(np.array([e[2:5] for e in elements], dtype=int), faces + 1)
    # Coordinates with at most 15 significant digits are written exactly as repr writes them.
    for node, row in zip(nodes[20:40], vertices[20:40].tolist()):
        assert node[2:] == [repr(v) for v in row]
    dat = (tmp_path / "mesh_els.dat").read_text(encoding="ascii").split("ENDDS\n")
    assert dat[0].splitlines()[-30:] == [str(i) for i in range(30)]
    h = [float(t) for t in dat[1].splitlines()[-30:]]
    assert h == np.linspace(-1, 1, 30).tolist()


def test_2dm_text_is_what_the_repr_template_wrote(tmp_path):
    rng = np.random.default_rng(9)
    vertices = np.round(rng.uniform(-1e6, 1e6, (500, 3)), 3)
    faces = rng.integers(0, 500, size=(400, 3))
    path = tmp_path / "mesh.2dm"
    write_2dm(path, vertices, faces)
    expected = "MESH2D\n" + "".join(
        f"ND {i} {x!r} {y!r} {z!r}\n" for i, (x, y, z) in enumerate(vertices.tolist(), 1)
    )
    expected += "".join(
        f"E3T {i} {a} {b} {c} 1\n" for i, (a, b, c) in enumerate((faces + 1).tolist(), 1)
    )
    assert path.read_text(encoding="ascii") == expected


def test_ascii_ply_float_and_negative_properties(tmp_path):
    vertices = np.array([[0.1, -0.0, 1e-7], [351182.162, 6e6, -2.5], [1.0, 2.0, 3.0]])
    props = {"a": np.array([-7], dtype=np.int64), "b": np.array([0.30000000000000004])}
    path = write_ply(tmp_path / "a.ply", vertices, np.array([[0, 1, 2]]), props, binary=False)
    _, body = _read_ply(path)
    rows = body.decode("ascii").splitlines()
    assert rows == [
        "0.1 -0.0 1e-07",
        "351182.162 6000000.0 -2.5",
        "1.0 2.0 3.0",
        "3 0 1 2 -7 0.30000000000000004",
    ]


class _PartPool:
    """A pool of two workers whose parts are written here: its call ``fail_call`` fails (as a
    worker that stops does), and calls after ``refuse_after`` are refused (as a closed pool
    refuses them)."""

    count = 2

    def __init__(self, fail_call: int = 0, refuse_after: int | None = None) -> None:
        self.calls = 0
        self.fail_call = fail_call
        self.refuse_after = refuse_after

    def write_rows(self, path, kind, first, rows):
        from concurrent.futures import Future

        self.calls += 1
        if self.refuse_after is not None and self.calls > self.refuse_after:
            raise RuntimeError("cannot schedule new futures after shutdown")
        future = Future()
        if self.calls == self.fail_call:
            future.set_exception(RuntimeError("the worker stopped"))
        else:
            mesh_module.write_rows(path, kind, first, rows)
            future.set_result(None)
        return future


@pytest.fixture
def parts_everywhere(monkeypatch):
    """Every 2DM is written in parts where a pool is given (joined by copying where the
    system has no in-kernel copy)."""
    monkeypatch.setattr(mesh_module, "PARALLEL_LINES", 0)
    monkeypatch.setattr(mesh_module, "_KERNEL_COPY", True)


# a square fan of four faces around its centre
_FAN_VERTICES = np.array([[0, 0, 1.5], [10, 0, 2.25], [10, 10, 3.125], [0, 10, 0.1], [5, 5, 9]])
_FAN_FACES = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])


def test_2dm_parts_that_fail_in_the_workers_are_written_here(tmp_path, parts_everywhere):
    """Where a worker fails its part of a 2DM (the third, after the first two have been
    joined), this process writes the whole file again: the same bytes as without a pool, and
    no part file left."""
    alone = write_2dm(tmp_path / "alone.2dm", _FAN_VERTICES, _FAN_FACES)
    pool = _PartPool(fail_call=3)
    failed = write_2dm(tmp_path / "failed.2dm", _FAN_VERTICES, _FAN_FACES, pool=pool)
    assert pool.calls >= 4
    assert failed[0].read_bytes() == alone[0].read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["alone.2dm", "failed.2dm"]


def test_2dm_with_a_pool_that_refuses_calls_is_written_here(tmp_path, parts_everywhere):
    """A pool that stops taking calls while the parts are handed out (after two): this
    process writes the file, and the parts already written are removed."""
    alone = write_2dm(tmp_path / "alone.2dm", _FAN_VERTICES, _FAN_FACES)
    pool = _PartPool(refuse_after=2)
    refused = write_2dm(tmp_path / "refused.2dm", _FAN_VERTICES, _FAN_FACES, pool=pool)
    assert pool.calls == 3
    assert refused[0].read_bytes() == alone[0].read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["alone.2dm", "refused.2dm"]
