"""Writing a large mesh: 2DM the old way (``%`` templates with ``%r``) against the current
writer (``number_text``), and binary PLY for reference, all in one process.

The mesh has 2,000,000 vertices and 2,000,000 faces with two integer face datasets
(feature_id, depth), as the Processing algorithm writes them. Two kinds of coordinates:
``full`` (random doubles, UTM-like: x 3e5..4e5, y 6.0e6..6.1e6, z 0..2000, 16-17 significant
digits) and ``3dec`` (the same rounded to 3 decimals). Each writer runs ``--repeat`` times
per kind; the table gives the best wall and CPU seconds and the file sizes. The old and new
2DM files must parse to the same numbers (byte-identical for ``3dec``); ``--verify`` also
parses every token of the ``full`` files (slow).

    .venv/bin/python bench/bench_mesh_write.py [--vertices N] [--faces N] [--repeat N]
        [--kinds full,3dec] [--verify]
"""

from __future__ import annotations

import argparse
import filecmp
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bsp_triangulate.formats.mesh import write_2dm, write_ply  # noqa: E402

_CHUNK_ROWS = 100_000
OLD, NEW, PLY = "2DM old (%r)", "2DM number_text", "PLY binary"


def _old_rows(handle, row_format: str, rows: np.ndarray) -> None:
    for start in range(0, len(rows), _CHUNK_ROWS):
        block = rows[start : start + _CHUNK_ROWS]
        handle.write((row_format * len(block)) % tuple(block.ravel().tolist()))


def _old_numbered_rows(handle, row_format: str, rows: np.ndarray, offset: int = 0) -> None:
    for start in range(0, len(rows), _CHUNK_ROWS):
        block = rows[start : start + _CHUNK_ROWS]
        ids = np.arange(start + 1, start + len(block) + 1, dtype=block.dtype)
        numbered = np.column_stack([ids, block + offset if offset else block])
        handle.write((row_format * len(block)) % tuple(numbered.ravel().tolist()))


def old_write_2dm(path: Path, vertices, faces, face_datasets) -> list[Path]:
    """The 2DM writer before number_text (commit ae25f6e), kept here as the reference."""
    with open(path, "w", encoding="ascii", newline="\n") as handle:
        handle.write("MESH2D\n")
        _old_numbered_rows(handle, "ND %d %r %r %r\n", vertices)
        _old_numbered_rows(handle, "E3T %d %d %d %d 1\n", faces, offset=1)
    dat = path.with_name(path.stem + "_els.dat")
    with open(dat, "w", encoding="utf-8", newline="\n") as handle:
        handle.write("DATASET\nOBJTYPE mesh2d\n")
        for name, values in face_datasets.items():
            values = np.asarray(values).astype(np.float64)
            handle.write(f'BEGSCL\nND {len(vertices)}\nNC {len(faces)}\nNAME "{name}"\n')
            handle.write("TS 0 0\n")
            _old_rows(handle, "%d\n", values.astype(np.int64).reshape(-1, 1))
            handle.write("ENDDS\n")
    return [path, dat]


def make_mesh(vertices: int, faces: int, kind: str, seed: int = 7):
    rng = np.random.default_rng(seed)
    xyz = np.column_stack(
        [
            rng.uniform(3e5, 4e5, vertices),
            rng.uniform(6.0e6, 6.1e6, vertices),
            rng.uniform(0.0, 2000.0, vertices),
        ]
    )
    if kind == "3dec":
        xyz = np.round(xyz, 3)
    triangles = rng.integers(0, vertices, size=(faces, 3)).astype(np.int32)
    datasets = {
        "feature_id": np.sort(rng.integers(0, 50_000, faces)).astype(np.int64),
        "depth": rng.integers(0, 20, faces).astype(np.int32),
    }
    return xyz, triangles, datasets


def measure(function, repeat: int) -> tuple[float, float]:
    """Best wall and CPU seconds of ``repeat`` calls."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        start_wall, start_cpu = time.perf_counter(), time.process_time()
        function()
        wall = min(wall, time.perf_counter() - start_wall)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu


def _numbers(path: Path) -> np.ndarray:
    tokens = [t for line in path.read_bytes().splitlines()[1:] for t in line.split()[1:]]
    return np.array([float(t) for t in tokens])


def run_kind(kind: str, args: argparse.Namespace) -> str:
    """Time the three writers on one kind of coordinates; the summary line."""
    vertices, faces, datasets = make_mesh(args.vertices, args.faces, kind)
    (ROOT / "build").mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory(dir=ROOT / "build") as folder:
        folder = Path(folder)
        writers = {
            OLD: ("old", lambda: old_write_2dm(folder / "old.2dm", vertices, faces, datasets)),
            NEW: ("new", lambda: write_2dm(folder / "new.2dm", vertices, faces, datasets)),
            PLY: ("m", lambda: write_ply(folder / "m.ply", vertices, faces, datasets)),
        }
        times = {}
        for name, (stem, writer) in writers.items():
            times[name] = wall, cpu = measure(writer, args.repeat)
            files = [p for p in folder.iterdir() if p.stem.split("_")[0] == stem]
            size = sum(p.stat().st_size for p in files) / 1e6
            print(f"| {kind} | {name} | {wall:.2f} | {cpu:.2f} | {size:.0f} |")
        same_dat = filecmp.cmp(folder / "old_els.dat", folder / "new_els.dat", shallow=False)
        if kind == "3dec" or args.verify:
            same = filecmp.cmp(folder / "old.2dm", folder / "new.2dm", shallow=False)
            if not same:
                old, new = _numbers(folder / "old.2dm"), _numbers(folder / "new.2dm")
                same = np.array_equal(old.view(np.int64), new.view(np.int64))
            check = "same numbers" if same else "DIFFERENT NUMBERS"
        else:
            check = "not parsed (--verify)"
        return (
            f"{kind}: 2DM old/new wall {times[OLD][0] / times[NEW][0]:.1f}x,"
            f" CPU {times[OLD][1] / times[NEW][1]:.1f}x;"
            f" 2DM minus PLY wall {times[NEW][0] - times[PLY][0]:.2f} s"
            f" (old {times[OLD][0] - times[PLY][0]:.2f} s);"
            f" .2dm {check}, _els.dat {'identical' if same_dat else 'DIFFERENT'}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, default=2_000_000)
    parser.add_argument("--faces", type=int, default=2_000_000)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--kinds", default="full,3dec")
    parser.add_argument("--verify", action="store_true", help="parse every full token too")
    args = parser.parse_args()
    print(f"{args.vertices:,} vertices, {args.faces:,} faces, 2 integer face datasets")
    print("| coordinates | writer | wall s | CPU s | MB written |")
    print("|---|---|---|---|---|")
    summary = [run_kind(kind, args) for kind in args.kinds.split(",")]
    print()
    print("\n".join(summary))


if __name__ == "__main__":
    main()
