"""The triangulate algorithm with worker processes: the same mesh file, triangles, counts and
per-feature errors as in QGIS's own process; without a Python for the workers, a warning and
still the same outputs; a cancel ends the workers."""

from __future__ import annotations

from math import nan
from pathlib import Path

import numpy as np
import pytest
from qgis.core import NULL, QgsProcessingContext, QgsProcessingException, QgsProject

from tests.conftest import SHARED_DATA
from tests.qgis.test_algorithm import RecordingFeedback

ALG = "bsptriangulate:triangulate"
FARMS = SHARED_DATA / "swellendam" / "farms_33S.shp"
SRTM = SHARED_DATA / "swellendam" / "srtm_41_19.tif"

# the last attributes: area_2d, area_3d, min_angle, slope, aspect (computed from the same
# vertices in QGIS's process either way, but numpy's arctan2 has given aspects one unit in the
# last place apart between two runs of the same batch)
METRICS = 5

pytestmark = pytest.mark.usefixtures("provider")


def assert_same_rows(got: list, expected: list) -> None:
    assert len(got) == len(expected)
    assert [(head, wkb) for head, _, wkb in got] == [(head, wkb) for head, _, wkb in expected]
    mine, theirs = (
        np.array([[nan if v == NULL else v for v in m] for _, m, _ in rows], dtype=float)
        for rows in (got, expected)
    )
    assert np.allclose(mine, theirs, rtol=1e-13, atol=0.0, equal_nan=True)


@pytest.fixture
def small_calls(monkeypatch: pytest.MonkeyPatch) -> list:
    """Engine calls and batches small enough that the farms make many of each; returns the
    pools the runs start (they record their calls)."""
    from bsptriangulate.processing_provider import engine_runs
    from bsptriangulate.processing_provider.triangulate_algorithm import TriangulateAlgorithm

    pools: list = []

    class RecordingPool(engine_runs.WorkerPool):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.calls = 0
            self.parts = 0
            pools.append(self)

        def submit(self, *args, **kwargs):
            self.calls += 1
            return super().submit(*args, **kwargs)

        def write_rows(self, *args, **kwargs):
            self.parts += 1
            return super().write_rows(*args, **kwargs)

    monkeypatch.setattr(engine_runs, "WorkerPool", RecordingPool)
    monkeypatch.setattr(TriangulateAlgorithm, "CHUNK_VERTICES", 4_000)
    monkeypatch.setattr(TriangulateAlgorithm, "BATCH_VERTICES", 10_000)
    return pools


def run_farms(path: Path, workers: int, feedback: RecordingFeedback, **parameters) -> tuple:
    """Counts, mesh file bytes and triangle rows of the farms on the SRTM DEM."""
    import processing

    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    mesh = path / f"farms_{workers}.2dm"
    result = processing.run(
        ALG,
        {
            "INPUT": str(FARMS),
            "ELEVATION_SOURCE": 3,
            "DEM": str(SRTM),
            "WORKERS": workers,
            "OUTPUT_MESH": str(mesh),
            "OUTPUT_TRIANGLES": "memory:",
            **parameters,
        },
        feedback=feedback,
        context=context,
    )
    rows = [
        (values[:-METRICS], values[-METRICS:], row.geometry().asWkb().data())
        for row in result["OUTPUT_TRIANGLES"].getFeatures()
        for values in [row.attributes()]  # once per row: a copy of every value each time
    ]
    counts = {key: result[key] for key in ("FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT")}
    return counts, mesh.read_bytes(), rows


@pytest.fixture(scope="module")
def one_process(tmp_path_factory: pytest.TempPathFactory):
    """``run(invalid)``: the outputs (as ``run_farms``) and feedback of the farms in QGIS's own
    process (``WORKERS`` 1), run once per ``invalid`` and module, in the first test that asks,
    under its ``small_calls`` (a run in one process starts no pool, so the 2DM's lines written
    in parts never apply to it)."""
    runs: dict[int, tuple] = {}

    def run(invalid: int) -> tuple:
        if invalid not in runs:
            feedback = RecordingFeedback()
            path = tmp_path_factory.mktemp("one-process")
            runs[invalid] = (run_farms(path, 1, feedback, INVALID_POLYGONS=invalid), feedback)
        return runs[invalid]

    return run


@pytest.mark.parametrize("invalid", [0, 2], ids=["repaired", "as_given"])
def test_workers_write_what_one_process_writes(
    tmp_path: Path, small_calls: list, invalid, monkeypatch: pytest.MonkeyPatch, one_process
):
    """The same outputs; the workers also write the 2DM's lines in parts (every mesh is
    large enough for that here)."""
    from bsptriangulate.bsp_triangulate.formats import mesh

    monkeypatch.setattr(mesh, "PARALLEL_LINES", 0)
    monkeypatch.setattr(mesh, "_KERNEL_COPY", True)  # joined by copying where not
    apart = RecordingFeedback()
    expected, alone = one_process(invalid)
    assert small_calls == []
    got = run_farms(tmp_path, 2, apart, INVALID_POLYGONS=invalid)
    (pool,) = small_calls
    assert pool.calls > 10
    assert pool.parts >= 4
    assert pool.processes() == []  # closed with the run
    counts, mesh, rows = got
    assert counts == expected[0] and counts["FEATURE_COUNT"] == 2008
    assert counts["TRIANGLE_COUNT"] > 30_000
    assert mesh == expected[1]
    assert_same_rows(rows, expected[2])
    assert apart.errors == alone.errors
    assert apart.warnings == alone.warnings


def test_without_a_python_for_the_workers_the_run_warns_and_writes_the_same(
    tmp_path: Path, small_calls: list, monkeypatch: pytest.MonkeyPatch, one_process
):
    from bsptriangulate.bsp_triangulate import workers

    expected, _ = one_process(0)  # the default: repaired
    monkeypatch.setattr(workers, "python_interpreter", lambda: None)
    feedback = RecordingFeedback()
    counts, mesh, rows = run_farms(tmp_path, 2, feedback)
    assert (counts, mesh) == expected[:2]
    assert_same_rows(rows, expected[2])
    (warning,) = [w for w in feedback.warnings if "Worker processes" in w]
    assert "no Python executable" in warning


def test_a_layer_of_one_engine_call_stays_in_this_process(tmp_path: Path):
    from bsptriangulate.processing_provider import engine_runs

    started = []
    original = engine_runs.WorkerPool

    class Spy(original):
        def __init__(self, *args, **kwargs) -> None:
            started.append(True)
            super().__init__(*args, **kwargs)

    import processing

    engine_runs.WorkerPool = Spy
    try:
        # the farms' 41,685 vertices: one engine call
        result = processing.run(
            ALG,
            {
                "INPUT": str(FARMS),
                "WORKERS": 4,
                "OUTPUT_MESH": str(tmp_path / "one.ply"),
                "OUTPUT_TRIANGLES": "",
            },
        )
    finally:
        engine_runs.WorkerPool = original
    assert result["FEATURE_COUNT"] == 2008
    assert started == []


def test_cancelling_ends_the_workers(tmp_path: Path, small_calls: list):
    import processing

    feedback = RecordingFeedback()
    feedback.progressChanged.connect(lambda progress: progress > 20 and feedback.cancel())
    with pytest.raises(QgsProcessingException, match="Cancelled"):
        processing.run(
            ALG,
            {"INPUT": str(FARMS), "WORKERS": 2, "OUTPUT_MESH": str(tmp_path / "cut.2dm")},
            feedback=feedback,
        )
    (pool,) = small_calls
    assert pool.calls > 0
    assert pool.processes() == []
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("triangles", "pools"), [("", 1), ("memory:", 0)], ids=["mesh_only", "with_triangles"]
)
def test_by_default_workers_run_a_mesh_only_run_and_not_one_writing_triangles(
    tmp_path: Path, small_calls: list, triangles: str, pools: int
):
    import processing

    result = processing.run(
        ALG,
        {
            "INPUT": str(FARMS),
            "OUTPUT_MESH": str(tmp_path / "farms.ply"),
            "OUTPUT_TRIANGLES": triangles,
        },
    )
    assert result["FEATURE_COUNT"] == 2008
    assert len(small_calls) == pools
