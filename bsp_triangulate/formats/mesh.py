"""Merging triangulations into one mesh and writing it as 2DM or PLY (both read by MDAL).

Text writers format a block of rows at a time with ``number_text`` (whole numpy columns to
ASCII, no Python per value), so memory stays flat and a 2DM mesh of two million vertices and
faces with full-precision coordinates takes about a second; given a worker pool, a large
2DM's lines are formatted in parts by the workers and joined in order (in the kernel where it
can), which takes about half of that on two cores.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Future
from pathlib import Path
from typing import Protocol

import numpy as np

from .number_text import Part, float_field, int_field, text_pieces

_CHUNK_ROWS = 100_000


class RowWriters(Protocol):
    """What :func:`write_2dm` needs of a worker pool (``workers.WorkerPool``)."""

    count: int

    def write_rows(self, path: str, kind: str, first: int, rows: np.ndarray) -> Future: ...


# numpy scalar kinds to PLY scalar type names.
_PLY_TYPES = {
    np.dtype("int8"): "char",
    np.dtype("uint8"): "uchar",
    np.dtype("int16"): "short",
    np.dtype("uint16"): "ushort",
    np.dtype("int32"): "int",
    np.dtype("uint32"): "uint",
    np.dtype("float32"): "float",
    np.dtype("float64"): "double",
}


def merge_meshes(
    parts: Iterable[tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate (vertices (N, 3), triangles (M, 3)) parts into one mesh.

    Vertices with identical x, y and z (also across parts) become one vertex, kept in order of
    first appearance. Returns ``(vertices, faces, part_index)`` where ``part_index[i]`` is the
    position in ``parts`` of the part that face ``i`` came from.
    """
    vertex_blocks, face_blocks, part_blocks = [], [], []
    offset = 0
    for index, (vertices, triangles) in enumerate(parts):
        vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
        triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if len(triangles) and (triangles.min() < 0 or triangles.max() >= len(vertices)):
            raise ValueError(f"part {index} has a triangle index outside its vertices")
        vertex_blocks.append(vertices)
        face_blocks.append(triangles + offset)
        part_blocks.append(np.full(len(triangles), index, dtype=np.int64))
        offset += len(vertices)
    if not vertex_blocks:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    all_vertices = np.concatenate(vertex_blocks)
    faces = np.concatenate(face_blocks)
    part_index = np.concatenate(part_blocks)
    if len(all_vertices) == 0:
        return all_vertices, faces, part_index
    # +0.0 turns -0.0 into 0.0 so that both compare as the same coordinate bytes.
    keys = np.ascontiguousarray(all_vertices + 0.0).view(np.dtype((np.void, 24))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertices = all_vertices[first[order]]
    return vertices, rank[inverse.ravel()][faces], part_index


def _write_blocks(handle, rows: int, block_parts: Callable[[int, int], Sequence[Part]]) -> None:
    """Write rows ``0..rows-1`` a block at a time; ``block_parts(start, stop)`` gives the
    literal bytes and fields of rows ``start:stop``, so memory stays flat."""
    for start in range(0, rows, _CHUNK_ROWS):
        handle.writelines(text_pieces(block_parts(start, min(start + _CHUNK_ROWS, rows))))


def _write_lines(handle, column: np.ndarray, field: Callable[[np.ndarray], Part]) -> None:
    """One token of ``column`` per line."""
    _write_blocks(handle, len(column), lambda a, b: [field(column[a:b]), b"\n"])


def _ids(start: int, stop: int) -> np.ndarray:
    return np.arange(start + 1, stop + 1, dtype=np.int64)


def _xyz_line(vertices: np.ndarray, start: int, stop: int) -> list[Part]:
    """Pieces of the text lines "x y z" (newline included) of vertex rows start..stop."""
    rows = vertices[start:stop]
    return [
        float_field(rows[:, 0]),
        b" ",
        float_field(rows[:, 1]),
        b" ",
        float_field(rows[:, 2]),
        b"\n",
    ]


def _check_mesh(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces).reshape(-1, 3)
    if not np.issubdtype(faces.dtype, np.integer):
        faces = faces.astype(np.int64)
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError("a face refers to a vertex index outside the vertex array")
    return vertices, faces


def _check_face_values(name: str, values: np.ndarray, face_count: int) -> np.ndarray:
    values = np.asarray(values).ravel()
    if len(values) != face_count:
        raise ValueError(f"face dataset {name!r} has {len(values)} values for {face_count} faces")
    return values


def _node_rows(handle, vertices: np.ndarray, first: int) -> None:
    """The lines ``ND id x y z`` of ``vertices``, ids from ``first`` + 1."""
    _write_blocks(
        handle,
        len(vertices),
        lambda a, b: [
            b"ND ", int_field(_ids(first + a, first + b)), b" ", *_xyz_line(vertices, a, b)
        ],
    )  # fmt: skip


def _face_rows(handle, faces: np.ndarray, first: int) -> None:
    """The lines ``E3T id n1 n2 n3 1`` of ``faces`` (0-based vertex indices), ids from
    ``first`` + 1."""
    _write_blocks(
        handle,
        len(faces),
        lambda a, b: [
            b"E3T ",
            int_field(_ids(first + a, first + b)),
            b" ",
            int_field(faces[a:b, 0].astype(np.int64) + 1),
            b" ",
            int_field(faces[a:b, 1].astype(np.int64) + 1),
            b" ",
            int_field(faces[a:b, 2].astype(np.int64) + 1),
            b" 1\n",
        ],
    )


_ROW_WRITERS = {"ND": _node_rows, "E3T": _face_rows}


def write_rows(path: str | os.PathLike, kind: str, first: int, rows: np.ndarray) -> None:
    """A part of a 2DM file: the ``kind`` ("ND" or "E3T") lines of ``rows``, ids from
    ``first`` + 1 (what :func:`write_2dm` writes for them, byte for byte)."""
    with open(path, "wb") as handle:
        _ROW_WRITERS[kind](handle, rows, first)


# a 2DM of at least this many lines is written in parts by the pool's workers
PARALLEL_LINES = 200_000
_PARTS_PER_WORKER = 4
_KERNEL_COPY = hasattr(os, "copy_file_range")


def write_2dm(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    face_datasets: Mapping[str, np.ndarray] | None = None,
    pool: RowWriters | None = None,
) -> list[Path]:
    """Write a 2DM mesh (``MESH2D``, ``ND id x y z``, ``E3T id n1 n2 n3 1``, 1-based ids).

    Coordinates read back (strtod, as MDAL reads them) as exactly the same doubles: as repr
    writes them where that takes at most 15 significant digits, else with 17 (see
    ``number_text``).
    2DM itself carries no named face values, so ``face_datasets`` go to a companion
    ``<name>_els.dat`` (ASCII DAT, one scalar group per dataset, on faces), which MDAL reads
    when it is added to the mesh layer as an extra dataset (QGIS does not find it by itself).
    2DM has no place for a CRS either, and MDAL's 2DM driver reads none (no ``.prj`` beside
    it): a 2DM opened later has no CRS; PLY carries both (:func:`write_ply`). Returns the
    written paths.

    With a ``pool`` (``workers.WorkerPool``) a large mesh's lines are written in parts by its
    workers, in parallel, and joined (the text is formatted in Python, one core per process);
    the file is the same, byte for byte. Where a worker fails, this process writes it all.
    """
    vertices, faces = _check_mesh(vertices, faces)
    for name, values in (face_datasets or {}).items():
        _check_face_values(name, values, len(faces))
    path = Path(path)
    parts = _parts_in_workers(path, vertices, faces, pool)
    try:
        if face_datasets:
            # meanwhile, in this process
            dat = path.with_name(path.stem + "_els.dat")
            write_face_dat(dat, len(vertices), len(faces), face_datasets)
        _write_nodes_and_faces(path, vertices, faces, parts)
    finally:
        _discard(parts)
    return [path, dat] if face_datasets else [path]


def _parts_in_workers(
    path: Path, vertices: np.ndarray, faces: np.ndarray, pool: RowWriters | None
) -> list[tuple[Future, Path]]:
    """The 2DM's lines submitted to the pool's workers in parts of about equal work (node
    lines take about three times as long as face lines), or none; several parts per worker, so
    that the parts written first are joined while the workers write the others."""
    # without an in-kernel copy (Linux's copy_file_range), joining the parts costs about what
    # the workers save
    if pool is None or len(vertices) + len(faces) < PARALLEL_LINES or not _KERNEL_COPY:
        return []
    # lines 0 .. n - 1 are the nodes, n .. n + m - 1 the faces; a node line costs about as
    # much as 3 face lines
    n, m = len(vertices), len(faces)
    count = _PARTS_PER_WORKER * pool.count
    work = [k * (3 * n + m) // count for k in range(1, count)]
    cuts = [w // 3 if w <= 3 * n else n + w - 3 * n for w in work]
    bounds = sorted({0, n, n + m, *cuts})
    parts: list[tuple[Future, Path]] = []
    try:
        for index, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            part = path.with_name(f".{path.name}.{index}.part")
            if b <= n:
                future = pool.write_rows(str(part), "ND", a, vertices[a:b])
            else:
                future = pool.write_rows(str(part), "E3T", a - n, faces[a - n : b - n])
            parts.append((future, part))
    except Exception:  # the pool takes no more calls (closed): this process writes it all
        _discard(parts)
        return []
    return parts


def _discard(parts: list[tuple[Future, Path]]) -> None:
    """Wait for the parts' workers (or cancel the calls not started) and remove the parts."""
    for future, part in parts:
        future.cancel()
        with contextlib.suppress(Exception):
            future.result()
        part.unlink(missing_ok=True)


def _append(source, target) -> None:
    """Copy the file ``source`` to the end of ``target`` (in the kernel where it can)."""
    size = os.fstat(source.fileno()).st_size
    copy = getattr(os, "copy_file_range", None)
    done = 0
    if copy is not None:
        with contextlib.suppress(OSError):
            while done < size:
                step = copy(source.fileno(), target.fileno(), size - done)
                if step == 0:
                    break
                done += step
    if done < size:
        source.seek(done)
        target.seek(0, os.SEEK_END)
        shutil.copyfileobj(source, target, 1 << 22)
        target.flush()


def _write_nodes_and_faces(
    path: Path, vertices: np.ndarray, faces: np.ndarray, parts: list[tuple[Future, Path]]
) -> None:
    """The 2DM file: the ``parts`` joined in order, each as soon as it is written (while the
    workers write the next ones); where a worker failed, this process writes it all."""
    with open(path, "wb") as handle:
        handle.write(b"MESH2D\n")
        try:
            handle.flush()
            for future, part in parts:
                future.result()
                with open(part, "rb") as source:
                    _append(source, handle)
                part.unlink()
            if parts:
                return
        except Exception:  # a worker failed or stopped: this process writes it all
            handle.seek(0)
            handle.truncate()
            handle.write(b"MESH2D\n")
        _node_rows(handle, vertices, 0)
        _face_rows(handle, faces, 0)


def write_face_dat(
    path: str | os.PathLike,
    vertex_count: int,
    face_count: int,
    face_datasets: Mapping[str, np.ndarray],
) -> Path:
    """Write face-centred scalar datasets as an ASCII DAT file for a 2DM mesh.

    MDAL treats a DAT file as face-centred only when its file name contains ``_els``.
    """
    path = Path(path)
    if "_els" not in path.name:
        raise ValueError("MDAL reads a DAT file as face values only if its name contains _els")
    if not face_datasets:
        raise ValueError("no face dataset to write")
    with open(path, "wb") as handle:
        handle.write(b"DATASET\nOBJTYPE mesh2d\n")
        for name, values in face_datasets.items():
            values = _check_face_values(name, values, face_count).astype(np.float64)
            if '"' in name:
                raise ValueError(f"dataset name {name!r} may not contain a double quote")
            header = f'BEGSCL\nND {vertex_count}\nNC {face_count}\nNAME "{name}"\nTS 0 0\n'
            handle.write(header.encode("utf-8"))
            integral = np.isfinite(values).all() and (values == np.round(values)).all()
            if integral and len(values) and np.abs(values).max() < 2**53:
                # ids and depths: written as integers, shorter than float reprs
                _write_lines(handle, values.astype(np.int64), int_field)
            else:
                _write_lines(handle, values, float_field)
            handle.write(b"ENDDS\n")
    return path


def _ply_scalar(name: str, values: np.ndarray) -> np.ndarray:
    values = np.asarray(values).ravel()
    if values.dtype == np.bool_:
        values = values.astype(np.uint8)
    elif values.dtype.kind in "iu" and values.dtype.itemsize == 8:
        info = np.iinfo(np.int32)
        if len(values) and (values.min() < info.min or values.max() > info.max):
            values = values.astype(np.float64)
        else:
            values = values.astype(np.int32)
    elif values.dtype.kind == "f" and values.dtype not in _PLY_TYPES:
        values = values.astype(np.float64)
    if values.dtype.newbyteorder("=") not in _PLY_TYPES:
        raise ValueError(f"property {name!r} of dtype {values.dtype} has no PLY scalar type")
    return values.astype(values.dtype.newbyteorder("<"))


def ply_crs_comment(crs: str) -> str:
    """The PLY header line that carries ``crs`` (WKT or an authority id) as MDAL reads it.

    MDAL (libplyxx ``addMetadata``) splits a comment at its first colon into key and value and
    takes the value of key ``crs`` as the mesh CRS, trimmed; MDAL writes ``comment crs: ...``
    itself. A multi-line WKT is joined into one line (each line's indentation dropped, the
    text inside quotes kept).
    """
    text = " ".join(line.strip() for line in crs.strip().splitlines() if line.strip())
    return "comment crs: " + text


def write_ply(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None = None,
    binary: bool = True,
    crs_wkt: str | None = None,
) -> Path:
    """Write a triangle mesh as PLY: vertex x y z (double), face vertex_indices, then scalars.

    Face properties (e.g. feature id, depth) follow ``vertex_indices`` and MDAL shows them as
    face datasets (QGIS 3.22 reads both the binary little-endian default and ``binary=False``
    ASCII). ``crs_wkt`` (WKT, or an authority id such as ``EPSG:32733``) goes into the header
    line ``comment crs: <crs>``, which MDAL reads as the mesh's CRS: its PLY header parser
    takes a comment's text up to the first colon as a metadata key, and the ``crs`` key as the
    CRS (QGIS 3.22's MDAL 0.9.4 and later; without the colon the comment is anonymous and the
    mesh has no CRS). The CRS is written on one line, in UTF-8.
    """
    vertices, faces = _check_mesh(vertices, faces)
    properties = {
        name: _ply_scalar(name, _check_face_values(name, values, len(faces)))
        for name, values in (face_properties or {}).items()
    }
    for name in properties:
        if not name.isidentifier():
            raise ValueError(f"PLY property name {name!r} must be a plain identifier")
    header = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0"]
    if crs_wkt:
        header.append(ply_crs_comment(crs_wkt))
    header += [
        f"element vertex {len(vertices)}",
        "property double x",
        "property double y",
        "property double z",
        f"element face {len(faces)}",
        "property list uchar int vertex_indices",
    ]
    header += [
        f"property {_PLY_TYPES[v.dtype.newbyteorder('=')]} {n}" for n, v in properties.items()
    ]
    header.append("end_header")
    path = Path(path)
    with open(path, "wb") as handle:
        handle.write(("\n".join(header) + "\n").encode("utf-8"))
        if binary:
            # no copy where the vertices are little-endian doubles already
            np.ascontiguousarray(vertices, dtype="<f8").tofile(handle)
            fields = [("count", "u1"), ("indices", "<i4", (3,))]
            fields += [(f"p{i}", v.dtype) for i, v in enumerate(properties.values())]
            records = np.empty(len(faces), dtype=np.dtype(fields))
            records["count"] = 3
            records["indices"] = faces
            for i, values in enumerate(properties.values()):
                records[f"p{i}"] = values
            records.tofile(handle)
            return path
    with open(path, "ab") as handle:
        _write_blocks(
            handle,
            len(vertices),
            lambda a, b: _xyz_line(vertices, a, b),
        )

        def face_rows(a: int, b: int) -> list[Part]:
            parts: list[Part] = [b"3"]
            for corner in range(3):
                parts += [b" ", int_field(faces[a:b, corner])]
            for values in properties.values():
                column = values[a:b]
                kind = values.dtype.kind
                parts += [b" ", float_field(column) if kind == "f" else int_field(column)]
            return [*parts, b"\n"]

        _write_blocks(handle, len(faces), face_rows)
    return path
