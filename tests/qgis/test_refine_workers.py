"""DEM points added in worker processes: the same points, warnings and mesh as in QGIS's own
process; a batch's engine calls cut to spread over the workers; a cancel during the
refinement in the workers stops the run."""

from __future__ import annotations

import concurrent.futures
from pathlib import Path

import numpy as np
import pytest
from qgis.core import QgsFeature, QgsProcessingException, QgsVectorLayer

from tests.conftest import SHARED_DATA
from tests.qgis.helpers import RecordingFeedback, run

pytestmark = pytest.mark.usefixtures("provider")

FARMS = SHARED_DATA / "swellendam" / "farms_33S.shp"
SRTM = SHARED_DATA / "swellendam" / "srtm_41_19.tif"
needs_farms = pytest.mark.skipif(not FARMS.exists(), reason="the Swellendam data is not there")


def some_farms(count: int) -> QgsVectorLayer:
    """The first ``count`` farms in a memory layer."""
    source = QgsVectorLayer(str(FARMS), "farms", "ogr")
    layer = QgsVectorLayer("Polygon?crs=EPSG:32733", "farms", "memory")
    copies = []
    for feature in source.getFeatures():
        if len(copies) == count:
            break
        copy = QgsFeature()
        copy.setGeometry(feature.geometry())
        copies.append(copy)
    assert layer.dataProvider().addFeatures(copies)
    return layer


@pytest.fixture
def recorded(monkeypatch: pytest.MonkeyPatch) -> list:
    """Shares of a few thousand cells and small engine calls, so that a few farms use the
    workers; returns the pools the runs start (they count their refine and engine calls)."""
    from bsptriangulate.processing_provider import engine_runs, terrain_points

    pools: list = []

    class RecordingPool(engine_runs.WorkerPool):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.calls = 0
            self.refines = 0
            pools.append(self)

        def submit(self, *args, **kwargs):
            self.calls += 1
            return super().submit(*args, **kwargs)

        def refine(self, *args, **kwargs):
            self.refines += 1
            return super().refine(*args, **kwargs)

    monkeypatch.setattr(engine_runs, "WorkerPool", RecordingPool)
    monkeypatch.setattr(engine_runs, "MIN_CALL_VERTICES", 2_000)
    monkeypatch.setattr(terrain_points, "MIN_SHARE_CELLS", 2_000)
    return pools


def run_farms(layer: QgsVectorLayer, path: Path, workers: int, feedback, **parameters) -> dict:
    result = run(
        {
            "INPUT": layer,
            "ELEVATION_SOURCE": 3,
            "DEM": str(SRTM),
            "APEX_RULE": 2,
            "MAX_VERTICAL_ERROR": 5.0,
            "WORKERS": workers,
            "OUTPUT_TRIANGLES": "",
            "OUTPUT_MESH": str(path / f"farms_{workers}.2dm"),
            **parameters,
        },
        feedback,
    )
    result["mesh_bytes"] = Path(result["OUTPUT_MESH"]).read_bytes()
    return result


@needs_farms
def test_refinement_in_workers_gives_what_one_process_gives(tmp_path: Path, recorded: list):
    layer = some_farms(150)
    # a cap that some farms reach: their warnings come from the workers' outcomes
    parameters = {"MAX_POINTS": 150}
    alone, apart = RecordingFeedback(), RecordingFeedback()
    expected = run_farms(layer, tmp_path, 1, alone, **parameters)
    assert recorded == []
    got = run_farms(layer, tmp_path, 2, apart, **parameters)
    (pool,) = recorded
    assert pool.refines == 4  # two shares per worker
    assert pool.calls >= 2, apart.warnings
    assert pool.processes() == []
    assert expected["POINTS_ADDED"] > 1_000
    for key in ("FEATURE_COUNT", "TRIANGLE_COUNT", "FAILED_COUNT", "POINTS_ADDED"):
        assert got[key] == expected[key], key
    assert got["mesh_bytes"] == expected["mesh_bytes"]
    assert apart.warnings == alone.warnings
    assert [w for w in alone.warnings if "cap of 150" in w]


@needs_farms
def test_a_worker_that_cannot_start_leaves_the_refinement_here(
    tmp_path: Path, recorded: list, monkeypatch: pytest.MonkeyPatch
):
    from bsptriangulate.bsp_triangulate import workers

    layer = some_farms(60)
    expected = run_farms(layer, tmp_path, 1, RecordingFeedback())
    monkeypatch.setattr(workers, "python_interpreter", lambda: None)
    feedback = RecordingFeedback()
    got = run_farms(layer, tmp_path, 2, feedback)
    assert recorded[0].refines > 1
    assert got["POINTS_ADDED"] == expected["POINTS_ADDED"]
    assert got["mesh_bytes"] == expected["mesh_bytes"]
    (warning,) = [w for w in feedback.warnings if "Worker processes" in w]
    assert "no Python executable" in warning


@needs_farms
def test_cancelling_during_the_refinement_in_workers_stops_the_run(
    tmp_path: Path, recorded: list, monkeypatch: pytest.MonkeyPatch
):
    from bsptriangulate.processing_provider import terrain_points

    feedback = RecordingFeedback()
    waited = []
    original = terrain_points.InteriorPoints._worker_result

    def cancel_while_waiting(self, future):
        waited.append(future)
        feedback.cancel()
        return original(self, future)

    monkeypatch.setattr(terrain_points.InteriorPoints, "_worker_result", cancel_while_waiting)
    with pytest.raises(QgsProcessingException, match="Cancelled"):
        run_farms(some_farms(60), tmp_path, 2, feedback)
    (pool,) = recorded
    assert pool.refines > 1 and len(waited) == 1
    assert pool.calls == 0  # no engine call after the cancel
    assert pool.processes() == []
    assert list(tmp_path.iterdir()) == []


def runner(workers: int):
    from bsptriangulate.processing_provider.engine_runs import EngineOptions, EngineRunner

    options = EngineOptions("delaunay", 0.0, "fail")
    return EngineRunner(options, workers, RecordingFeedback(), str, 10_000, 250_000)


def circles(count: int, vertices: int) -> list:
    """``count`` features of one ring of ``vertices`` vertices each."""
    from bsptriangulate.processing_provider.geometry_io import FeatureRings

    t = np.linspace(0.0, 2 * np.pi, vertices, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t), np.zeros(vertices)])
    shift = np.array([3.0, 0.0, 0.0])
    return [FeatureRings(QgsFeature(i), [[ring + i * shift]]) for i in range(count)]


def test_with_workers_a_batch_is_cut_into_two_calls_per_worker(monkeypatch: pytest.MonkeyPatch):
    from bsptriangulate.processing_provider import engine_runs

    pools: list = []

    class Pool:
        """Records the calls' polygons, runs nothing."""

        def __init__(self, count: int) -> None:
            self.polygons: list[int] = []
            self.started = 0
            pools.append(self)

        def submit(self, polygons, **options) -> concurrent.futures.Future:
            self.polygons.append(len(polygons.ring_count))
            return concurrent.futures.Future()

        def close(self, cancel: bool = False) -> None:
            pass

    monkeypatch.setattr(engine_runs, "WorkerPool", Pool)
    batch = circles(400, 100)  # 40,000 ring vertices
    points = [[np.zeros((900, 3))] for _ in batch]  # and 360,000 points
    sizes = {}
    for workers in (1, 2, 4, 8, 16):
        engine = runner(workers)
        job = engine.submit(batch, points)
        engine.close(cancel=True)
        sizes[workers] = [len(call.items) for call in job.calls]
    assert sizes[1] == [250, 150]  # the limit of 250,000 vertices
    assert sizes[2] == [100] * 4  # 400,000 / (2 x 2)
    assert sizes[4] == [50] * 8  # 400,000 / (2 x 4)
    assert sizes[8] == [50] * 8  # not below 50,000 vertices
    assert sizes[16] == [50] * 8
    assert [pool.polygons for pool in pools] == [[100] * 4] + [[50] * 8] * 3
    # without points: 40,000 vertices, one call, no pool
    job = runner(8).submit(batch)
    assert [len(call.items) for call in job.calls] == [400]
    assert len(pools) == 4


def test_the_vertices_of_a_call():
    two, four = runner(2), runner(4)
    assert four.call_vertices(41_685) == 41_685  # the farms without points: one call
    assert two.call_vertices(99_999) == 99_999  # under twice 50,000: one call
    assert two.call_vertices(140_000) == 70_000  # one per worker
    assert two.call_vertices(310_000) == 77_500  # two per worker
    assert four.call_vertices(160_000) == 53_334  # fewer calls than workers, 50,000 or more
    assert four.call_vertices(310_000) == 77_500  # one per worker
    assert four.call_vertices(1_000_000) == 125_000  # two per worker
    assert four.call_vertices(4_000_000) == 250_000  # the limit
    assert runner(1).call_vertices(1_000_000) == 250_000


def test_refinement_shares_keep_features_whole_and_spread_the_cells():
    from bsptriangulate.bsp_triangulate.terrain.refine import CellGrid
    from bsptriangulate.processing_provider.terrain_points import InteriorPoints

    def shares(workers: int, cells: list[int], owners: list[int]) -> list[tuple[int, int]]:
        engine = runner(workers)
        interior = InteriorPoints(None, None, 0.0, 0, engine.options, engine.feedback, engine)
        grids = [CellGrid(0.0, 0.0, 1.0, 1.0, np.zeros((1, size))) for size in cells]
        return interior._shares(grids, owners)

    eight = [25_000] * 8
    assert shares(2, eight, list(range(8))) == [(0, 2), (2, 4), (4, 6), (6, 8)]
    # a feature's parts stay in one share
    assert shares(2, eight, [0, 0, 0, 1, 2, 3, 3, 4]) == [(0, 3), (3, 4), (4, 5), (5, 8)]
    assert shares(1, eight, list(range(8))) == [(0, 8)]  # no workers
    assert shares(2, [20_000] * 4, list(range(4))) == [(0, 4)]  # under 100,000 cells
    assert shares(2, [30_000] * 5, list(range(5))) == [(0, 2), (2, 5)]  # 3 shares: 2
    assert shares(4, [30_000] * 5, list(range(5))) == [(0, 2), (2, 3), (3, 5)]  # 3 < 4
    assert shares(2, eight, [0] * 8) == [(0, 8)]  # one feature
