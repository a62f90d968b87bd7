"""``triangulate_packed`` in worker processes: the same results as in this process, and
workers that fail, stop or cannot start fail their calls without hanging the caller."""

from __future__ import annotations

import json
import random
import subprocess
import sys

import numpy as np
import pytest

from bsp_triangulate import PackedPolygons, TriangulationError, triangulate_packed
from bsp_triangulate.workers import WorkerCallError, WorkerError, WorkerPool, python_interpreter

from ..conftest import SHARED_DATA
from .random_polygons import random_polygon, with_z
from .test_packed import as_arrays
from .tree.test_batch import farm_polygons

EARCUT = SHARED_DATA / "earcut" / "fixtures"
FIELDS = (
    "vertices", "vertex_count", "triangles", "triangle_count", "parent", "depth", "side",
    "point_ids", "point_count",
)  # fmt: skip
TRIANGLE = [[(0.0, 0.0), (2.0, 0.0), (0.0, 2.0)]]
BOWTIE = [[(0.0, 0.0), (4.0, 4.0), (4.0, 0.0), (0.0, 4.0)]]


def packed_differences(got, want) -> list[str]:
    """Fields (values or dtypes) and errors that differ between two packed results."""
    problems = [
        name
        for name in FIELDS
        if getattr(got, name).dtype != getattr(want, name).dtype
        or not np.array_equal(getattr(got, name), getattr(want, name))
    ]
    mine = {index: (type(error), str(error)) for index, error in got.errors.items()}
    theirs = {index: (type(error), str(error)) for index, error in want.errors.items()}
    if mine != theirs:
        problems.append("errors")
    return problems


def in_calls(polygons: list, calls: int) -> list[PackedPolygons]:
    size = -(-len(polygons) // calls)
    return [PackedPolygons.of(polygons[i : i + size]) for i in range(0, len(polygons), size)]


def test_workers_give_the_results_of_this_process_on_earcut_fixtures_and_farms() -> None:
    polygons = as_arrays(json.loads(path.read_text()) for path in sorted(EARCUT.glob("*.json")))
    polygons += farm_polygons(120)
    calls = in_calls(polygons, 5)
    with WorkerPool(2) as pool:
        futures = [pool.submit(call, on_error="return") for call in calls]
        results = [future.result(timeout=300) for future in futures]
    failed = 0
    for call, result in zip(calls, results):
        expected = triangulate_packed(call, on_error="return")
        assert packed_differences(result, expected) == []
        failed += len(result.errors)
    # the fixtures include self-intersecting rings: their errors come back with their messages
    assert 0 < failed < 20


def test_workers_pass_the_options_and_proven_flags() -> None:
    rnd = random.Random(12)
    polygons = [with_z(rnd, random_polygon(rnd, islands=rnd.randint(0, 2))) for _ in range(60)]
    call = PackedPolygons.of(polygons)
    proven = np.zeros(len(polygons), dtype=bool)
    with WorkerPool(1) as pool:
        counts = np.array([rnd.randint(0, 3) for _ in polygons], dtype=np.int64)
        inside = np.array(
            [[rnd.uniform(-1, 1), rnd.uniform(-1, 1), 0.0] for _ in range(counts.sum())]
        )
        for options in (
            {"rule": "elevation"},
            {"planar_tolerance": 0.5},
            {"invalid": "as_given", "proven": proven},
            {"rule": "delaunay", "points": (inside, counts)},
        ):
            got = pool.submit(call, on_error="return", **options).result(timeout=300)
            want = triangulate_packed(call, on_error="return", **options)
            assert packed_differences(got, want) == [], options


def test_a_call_that_raises_fails_with_its_error_and_the_worker_serves_the_next() -> None:
    call = PackedPolygons.of(as_arrays([TRIANGLE, BOWTIE]))
    with WorkerPool(1) as pool:
        with pytest.raises(WorkerCallError, match=r"ValueError: .*nope"):
            pool.submit(call, rule="nope").result(timeout=120)
        with pytest.raises(TriangulationError) as raised:
            pool.submit(call).result(timeout=120)
        with pytest.raises(TriangulationError) as here:
            triangulate_packed(call)
        assert str(raised.value) == str(here.value)
        assert len(pool.submit(call, on_error="return").result(timeout=120).errors) == 1
        assert len(pool.processes()) == 1


def test_a_worker_that_stops_fails_its_call_and_the_next_call_gets_a_new_worker() -> None:
    call = PackedPolygons.of(as_arrays([TRIANGLE]))
    with WorkerPool(1) as pool:
        pool.submit(call).result(timeout=120)
        (first,) = pool.processes()
        first.kill()
        first.wait()
        with pytest.raises(WorkerError, match="stopped"):
            pool.submit(call).result(timeout=120)
        assert len(pool.submit(call).result(timeout=120).triangles) == 1
        (second,) = pool.processes()
        assert second.pid != first.pid


@pytest.mark.parametrize("python", ["/bin/true", "/nonexistent/python3"])
def test_an_executable_that_is_not_a_worker_fails_the_call(python: str) -> None:
    with WorkerPool(1, python=python) as pool:
        with pytest.raises(WorkerError):
            pool.submit(PackedPolygons.of(as_arrays([TRIANGLE]))).result(timeout=120)
        assert pool.processes() == []


def test_what_a_worker_prints_before_it_stops_is_in_the_error(tmp_path) -> None:
    python = tmp_path / "python3"
    python.write_text("#!/bin/sh\necho 'ModuleNotFoundError: no numpy here' >&2\nexit 1\n")
    python.chmod(0o755)
    call = PackedPolygons.of(as_arrays([TRIANGLE]))
    with (
        WorkerPool(1, python=str(python)) as pool,
        pytest.raises(WorkerError, match="stopped: ModuleNotFoundError: no numpy here"),
    ):
        pool.submit(call).result(timeout=120)


def test_close_ends_every_worker() -> None:
    call = PackedPolygons.of(as_arrays([TRIANGLE] * 4))
    pool = WorkerPool(2)
    futures = [pool.submit(call) for _ in range(6)]
    [future.result(timeout=120) for future in futures]
    processes = pool.processes()
    assert 1 <= len(processes) <= 2
    pool.close()
    assert all(process.poll() is not None for process in processes)
    with pytest.raises(RuntimeError):
        pool.submit(call)


def test_the_interpreter_found_is_this_python_version() -> None:
    python = python_interpreter()
    assert python is not None
    answer = subprocess.run(
        [python, "-c", "import sys; print(sys.version_info[:2])"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert answer.stdout.strip() == str(tuple(sys.version_info[:2]))


def test_workers_write_a_2dm_mesh_in_parts_byte_for_byte(tmp_path, monkeypatch) -> None:
    """A 2DM mesh of the farms written by two workers in parts (every mesh is large enough
    here) is the file this process writes alone, with its face-value companion; no part
    file is left beside it."""
    from bsp_triangulate.formats import mesh

    results = triangulate_packed(
        PackedPolygons.of(farm_polygons(5000)), on_error="return"
    ).to_list()
    parts = [(r.vertices, r.triangles) for r in results if not isinstance(r, Exception)]
    vertices, faces, part = mesh.merge_meshes(parts)
    datasets = {"feature_id": part, "depth": np.arange(len(faces)) % 7}
    alone = mesh.write_2dm(tmp_path / "alone.2dm", vertices, faces, datasets)
    monkeypatch.setattr(mesh, "PARALLEL_LINES", 0)
    monkeypatch.setattr(mesh, "_KERNEL_COPY", True)  # joined by copying where not
    with WorkerPool(2) as pool:
        shared = mesh.write_2dm(tmp_path / "shared.2dm", vertices, faces, datasets, pool)
        assert pool.started == 2
    assert len(faces) > 20_000
    for mine, theirs in zip(shared, alone):
        assert mine.read_bytes() == theirs.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in [*shared, *alone])


def test_a_module_beside_the_package_cannot_shadow_the_standard_library(tmp_path) -> None:
    """A file such as ``inspect.py`` next to the package's folder (beside a checkout or a
    plugin folder) is not imported by the workers in place of the standard library's."""
    import shutil
    from pathlib import Path

    package = Path(triangulate_packed.__code__.co_filename).resolve().parent
    shutil.copytree(
        package, tmp_path / "bsp_triangulate", ignore=shutil.ignore_patterns("__pycache__")
    )
    (tmp_path / "inspect.py").write_text("raise ImportError('the standard inspect is shadowed')\n")
    script = (
        "import sys; sys.path.append(sys.argv[1]); "
        "from bsp_triangulate import PackedPolygons; "
        "from bsp_triangulate.workers import WorkerPool; "
        "pool = WorkerPool(1); "
        "square = [[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]]; "
        "result = pool.submit(PackedPolygons.of([square, square])).result(timeout=60); "
        "pool.close(); print(int(result.triangle_count.sum()))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path.parent,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "4"


def test_refinement_in_workers_in_shares_equals_one_call_here() -> None:
    """``refine_many`` over shares of whole groups in workers: the same points and fields
    as one call over all polygons here, and an engine error comes back with its message."""
    from bsp_triangulate import triangulate_many
    from bsp_triangulate.terrain.refine import refine_many

    from .terrain.test_refine import hill_grid, with_z

    grid = hill_grid()
    squares = [
        [np.array([[x, y], [x + w, y], [x + w, y + w], [x, y + w]], dtype=float)]
        for x, y, w in ((5, 5, 60), (250, 5, 200), (5, 250, 220), (300, 300, 30), (80, 80, 90))
    ]
    polygons = [with_z(rings, grid) for rings in squares]
    polygons.append(with_z([np.array(BOWTIE[0], dtype=float) * 20.0 + 100.0], grid))
    fixed = [None, np.array([[260.0, 20.0, 99.0]]), None, None, None, None]
    groups = [0, 1, 1, 2, 3, 4]
    options = {"rule": "delaunay", "plane": "xy", "invalid": "fail"}
    expected = refine_many(
        polygons, [grid] * 6, 0.7, 40, engine=triangulate_many, fixed=fixed, groups=groups,
        **options,
    )  # fmt: skip
    with WorkerPool(2) as pool:
        shares = ((0, 1), (1, 4), (4, 6))
        futures = [
            pool.refine(
                polygons[a:b],
                [grid] * (b - a),
                0.7,
                40,
                fixed=fixed[a:b],
                groups=groups[a:b],
                **options,
            )
            for a, b in shares
        ]
        got = [result for future in futures for result in future.result(timeout=300)]
    assert len(got) == len(expected) == 6
    for mine, theirs in zip(got, expected):
        np.testing.assert_array_equal(mine.points, theirs.points)
        assert mine.points.dtype == theirs.points.dtype
        for name in ("added", "max_error", "cells", "rounds", "within", "capped"):
            assert getattr(mine, name) == getattr(theirs, name), name
        assert type(mine.error) is type(theirs.error)
        assert str(mine.error) == str(theirs.error)
    assert expected[-1].error is not None  # the bow tie
    assert sum(r.added for r in expected) > 10
