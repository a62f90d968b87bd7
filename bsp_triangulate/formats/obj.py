"""Writing a triangle mesh as Wavefront OBJ, pure numpy and the standard library.

Same input as the writers of :mod:`.mesh` (vertices (N, 3), faces (M, 3), per-face values).

- **Frame and origin.** Vertices are written in the map frame (x east, y north, z up), relative
  to a local origin (by default the centre of the bounding box, rounded to whole units), with
  full double precision (they read back as the same doubles as ``vertex - origin``). OBJ has
  no place for an offset or a CRS: the origin is in a header comment (``# origin x y z``) and,
  with the CRS WKT and the axes, in the sidecar ``<stem>.origin.json``; with a CRS the WKT also
  goes to ``<stem>.prj``. Importers that take OBJ as Y-up (Blender's default) need their
  "Z up" option.
- **Groups.** Faces are grouped by their per-face values: ``g feature_id_12`` before each run
  of faces of one value (a run repeats a group where the faces of a value are not
  contiguous). ``group_by`` names the properties that make groups (by default the first one,
  normally the source feature id: a finer one such as the BSP depth would start a group at
  almost every face); several names give lines such as ``g building_3 surface_roof``, a face
  then belonging to both groups. ``labels`` turns integer values into names
  (``{"surface": ("roof", "wall", "floor")}``).
- **Normals.** None are written: every face is counter-clockwise seen from above (or from
  outside a solid), so importers compute the same flat normals.
- Faces refer to vertices by 1-based index, as ``f a b c``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .mesh import _write_blocks, _xyz_line
from .model_origin import checked_model, origin_record
from .number_text import int_field, join_rows

_CHUNK = 100_000
AXES = "x east, y north, z up; map coordinates = vertex + origin"


def _group_tokens(
    name: str, values: np.ndarray, labels: Sequence[str] | None
) -> tuple[np.ndarray, list[str]]:
    """Per face, the index of its group token; the tokens (``name_value``)."""
    unique, inverse = np.unique(values, return_inverse=True)
    tokens = []
    for value in unique.tolist():
        if labels is not None and isinstance(value, int) and 0 <= value < len(labels):
            text = str(labels[value])
        elif isinstance(value, float) and value.is_integer():
            text = str(int(value))
        else:
            text = str(value)
        tokens.append("".join(c if c.isalnum() or c in "-." else "_" for c in f"{name}_{text}"))
    return inverse.ravel(), tokens


def write_obj(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    face_properties: Mapping[str, np.ndarray] | None = None,
    crs_wkt: str | None = None,
    origin: np.ndarray | None = None,
    group_by: Sequence[str] | None = None,
    labels: Mapping[str, Sequence[str]] | None = None,
) -> list[Path]:
    """Write an OBJ mesh and its ``.origin.json`` (and ``.prj`` with a CRS) sidecars.
    Returns the written paths, the ``.obj`` first."""
    vertices, faces, properties, origin = checked_model(vertices, faces, face_properties, origin)
    if group_by is None:
        group_by = list(properties)[:1]
    for key in group_by:
        if key not in properties:
            raise ValueError(f"group_by names {key!r}, which is not a face property")
    path = Path(path)
    local = vertices - origin
    origin_text = " ".join(repr(float(v)) for v in origin)
    header = [
        f"# {path.name}: {len(vertices)} vertices, {len(faces)} triangles",
        "# axes: x east, y north, z up (map frame)",
        f"# origin {origin_text}",
        "# map coordinates = vertex + origin",
    ]
    if crs_wkt:
        header.append("# crs " + " ".join(crs_wkt.split()))
    # groups: per face a tuple of token indices; a run starts where it changes
    columns, names = [], []
    for key in group_by:
        inverse, tokens = _group_tokens(key, properties[key], (labels or {}).get(key))
        columns.append(inverse)
        names.append(tokens)
    if columns and len(faces):
        changed = np.zeros(len(faces), dtype=bool)
        changed[0] = True
        for column in columns:
            changed[1:] |= column[1:] != column[:-1]
        run_starts = np.flatnonzero(changed)
    else:
        run_starts = np.zeros(0, dtype=np.int64)
    with open(path, "wb") as handle:
        handle.write(("\n".join(header) + "\n").encode("utf-8"))
        _write_blocks(handle, len(local), lambda a, b: [b"v ", *_xyz_line(local, a, b)])
        _write_faces(handle, faces, run_starts, columns, names)
    written = [path]
    sidecar = path.with_name(path.stem + ".origin.json")
    sidecar.write_text(json.dumps(origin_record(origin, crs_wkt, AXES), indent=1), encoding="utf-8")
    written.append(sidecar)
    if crs_wkt:
        prj = path.with_suffix(".prj")
        prj.write_text(crs_wkt, encoding="utf-8")
        written.append(prj)
    return written


def _write_faces(
    handle,
    faces: np.ndarray,
    run_starts: np.ndarray,
    columns: list[np.ndarray],
    names: list[list[str]],
) -> None:
    """The ``f`` lines, a ``g`` line before each run; text made a block of faces at a time."""
    runs = run_starts.tolist()
    run = 0
    for start in range(0, len(faces), _CHUNK):
        stop = min(start + _CHUNK, len(faces))
        block = faces[start:stop].astype(np.int64) + 1
        text = join_rows(
            [
                b"f ",
                int_field(block[:, 0]),
                b" ",
                int_field(block[:, 1]),
                b" ",
                int_field(block[:, 2]),
                b"\n",
            ]
        )
        if not runs:
            handle.write(text)
            continue
        lines = text.split(b"\n")
        pieces = []
        position = start
        while position < stop:
            while run + 1 < len(runs) and runs[run + 1] <= position:
                run += 1
            if runs[run] == position:
                tokens = [names[k][int(columns[k][position])] for k in range(len(columns))]
                pieces.append(("g " + " ".join(tokens) + "\n").encode("utf-8"))
            end = runs[run + 1] if run + 1 < len(runs) else stop
            end = min(end, stop)
            pieces.append(b"\n".join(lines[position - start : end - start]) + b"\n")
            position = end
        handle.writelines(pieces)
