"""The engine calls of the triangulate algorithm: each batch of features is cut into calls of
bounded size, run in QGIS's process or in worker processes, and its results come back in
feature order, with a failure named on its own feature."""

from __future__ import annotations

import concurrent.futures
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from qgis.core import QgsProcessingFeedback

from ..bsp_triangulate import PackedPolygons, PackedTriangulations, triangulate_packed
from ..bsp_triangulate.workers import WorkerError, WorkerPool
from .geometry_io import FeatureRings
from .outputs import EngineChunk

# seconds between cancel checks while waiting for a worker
_POLL = 0.1
# with workers, a batch's calls are cut to spread over them, but none below this many
# vertices (points included): a smaller layer stays one call, in QGIS's process
MIN_CALL_VERTICES = 50_000


class _CancelledError(Exception):
    """The run was cancelled during an engine call in this process."""


def wait_for(
    future: concurrent.futures.Future,
    feedback: QgsProcessingFeedback,
    stop_workers: Callable[[BaseException], None],
) -> Any | None:
    """The result of a task in a worker, waited for with a cancel check every ``_POLL``
    seconds; None when the run is cancelled meanwhile or the task has no result (run it
    here): a worker that could not start or stopped goes to ``stop_workers`` first; an
    error raised in the worker is left to the run here (which names the failing feature,
    or raises as a run without workers does)."""
    while not feedback.isCanceled():
        try:
            return future.result(timeout=_POLL)
        except concurrent.futures.TimeoutError:
            continue
        except (WorkerError, concurrent.futures.CancelledError) as error:
            stop_workers(error)
            return None
        except Exception:  # the task raised in the worker
            return None
    return None


def share_count(total: int, workers: int, minimum: int) -> int:
    """How many shares of about equal size ``total`` (vertices, DEM cells) is cut into over
    ``workers``: two per worker where each keeps at least ``minimum``, else fewer, a
    multiple of the workers where there are as many (they end together); may be below 2."""
    count = min(2 * workers, total // max(minimum, 1))
    if count >= workers:
        count -= count % workers
    return count


@dataclass
class EngineOptions:
    """The engine's options of one run: apex rule, planar tolerance, what to do with rings
    that are not valid (``fail`` or ``as_given``), the working plane (``auto`` or ``xy``)."""

    rule: str
    tolerance: float
    invalid: str
    plane: str = "xy"

    def keywords(self) -> dict:
        return {
            "rule": self.rule,
            "planar_tolerance": self.tolerance,
            "on_error": "return",
            "invalid": self.invalid,
            "plane": self.plane,
        }


# parts per feature, the parts packed, their proven flags and the engine's keywords for their
# interior points (``points``, ``meshes``), or None without points (``_pack``)
Packed = tuple[np.ndarray, PackedPolygons, np.ndarray, "dict | None"]
# per feature of a batch: its interior points, one (k, 3) array per part, or None for none
FeaturePoints = list[list[np.ndarray] | None]


class PartPoints(np.ndarray):
    """A part's interior points (k, 3) that carry, where the refinement made it, the part's
    triangulation with them (``mesh``, see ``bsp_triangulate.triangulate``)."""

    mesh: np.ndarray | None = None


def with_mesh(points: np.ndarray, mesh: np.ndarray | None) -> np.ndarray:
    """``points`` as :class:`PartPoints` carrying ``mesh`` (the array itself without one)."""
    if mesh is None:
        return points
    carried = np.asarray(points).view(PartPoints)
    carried.mesh = mesh
    return carried


@dataclass(eq=False)
class _Call:
    """One engine call: its features, their parts ``packed`` (None if they cannot be), the
    features' interior points (None for none) and the future of its result in a worker."""

    items: list[FeatureRings]
    packed: Packed | None
    points: FeaturePoints | None = None
    future: concurrent.futures.Future | None = None


@dataclass
class BatchJob:
    """The engine calls of one batch of features."""

    batch: list[FeatureRings]
    calls: list[_Call] = field(default_factory=list)


def _pack(items: list[FeatureRings], points: FeaturePoints | None = None) -> Packed:
    """Parts per item, all parts packed, their proven flags and interior points (raises
    when the rings cannot be packed)."""
    rings = [ring for item in items for part in item.parts for ring in part]
    part_count = np.fromiter((len(item.parts) for item in items), np.int64, len(items))
    proven = np.repeat([item.proven for item in items], part_count)
    polygons = PackedPolygons(
        np.concatenate(rings) if rings else np.zeros((0, 3)),
        np.fromiter((len(ring) for ring in rings), np.int64, len(rings)),
        np.fromiter(
            (len(part) for item in items for part in item.parts), np.int64, part_count.sum()
        ),
    )
    return part_count, polygons, proven, _pack_points(items, points)


def _pack_points(items: list[FeatureRings], points: FeaturePoints | None) -> dict | None:
    """The engine's keywords for the items' interior points: ``points`` as (coordinates
    (K, 3), counts per part), and ``meshes`` as (triangles, counts per part) where the
    refinement made any; None without points."""
    if points is None or all(p is None for p in points):
        return None
    arrays: list[np.ndarray] = []
    meshes: list[np.ndarray] = []
    for item, of_item in zip(items, points):
        for index in range(len(item.parts)):
            part = of_item[index] if of_item is not None and index < len(of_item) else None
            arrays.append(np.zeros((0, 3)) if part is None else np.asarray(part, np.float64))
            mesh = getattr(part, "mesh", None)
            meshes.append(np.zeros((0, 3), np.int64) if mesh is None else mesh)
    counts = np.fromiter((len(a) for a in arrays), np.int64, len(arrays))
    keywords: dict = {"points": ((np.concatenate(arrays) if arrays else np.zeros((0, 3))), counts)}
    mesh_counts = np.fromiter((len(m) for m in meshes), np.int64, len(meshes))
    if mesh_counts.any():
        keywords["meshes"] = (np.concatenate(meshes).astype(np.int64), mesh_counts)
    return keywords


def _call(items: list[FeatureRings], points: FeaturePoints | None = None) -> _Call:
    """The call of ``items``; one whose rings cannot be packed runs in this process, which
    names the feature."""
    try:
        return _Call(items, _pack(items, points), points)
    except Exception:
        return _Call(items, None, points)


class EngineRunner:
    """Runs the engine calls of batches, in up to ``workers`` worker processes.

    With more than one worker, the pool starts once two calls are waiting (a layer of one
    call stays in QGIS's process); :meth:`submit` then returns at once and :meth:`finish`
    waits for the results, so that the next batch is read while the workers triangulate.
    A worker that cannot start or stops ends the use of workers for the run (a warning says
    why); a call that fails in a worker is run again here, which names the failing feature.
    """

    def __init__(
        self,
        options: EngineOptions,
        workers: int,
        feedback: QgsProcessingFeedback,
        tr: Callable[[str], str],
        chunk_features: int,
        chunk_vertices: int,
        min_call_vertices: int | None = None,
    ) -> None:
        self.options = options
        self.workers = workers
        self.feedback = feedback
        self.tr = tr
        self.chunk_features = chunk_features
        self.chunk_vertices = chunk_vertices
        self.min_call_vertices = (
            MIN_CALL_VERTICES if min_call_vertices is None else min_call_vertices
        )
        self._pool: WorkerPool | None = None
        self._waiting: list[_Call] = []
        # engine calls run, of them in workers, and the workers started
        self.calls = 0
        self.calls_in_workers = 0
        self.workers_started = 0

    @property
    def pool(self) -> WorkerPool | None:
        """The running workers, if any (they can write a large 2DM mesh's lines too)."""
        return self._pool

    def worker_pool(self) -> WorkerPool | None:
        """The workers for other tasks of the run (refinement), started if the run uses
        workers; None when it does not (or no longer does)."""
        if not self.parallel:
            return None
        if self._pool is None:
            self._pool = WorkerPool(self.workers)
        return self._pool

    @property
    def parallel(self) -> bool:
        """Calls may run in workers: finish a batch after submitting the next one."""
        return self.workers > 1

    def call_vertices(self, total: int) -> int:
        """The vertices (points included) after which a call of a batch of ``total`` is cut.
        With workers: calls of about equal size, two per worker where each keeps at least
        ``min_call_vertices`` (else fewer, a multiple of the workers where there are as many:
        they end together), one call under twice that; never above ``chunk_vertices``."""
        if not self.parallel:
            return self.chunk_vertices
        calls = share_count(total, self.workers, self.min_call_vertices)
        calls = max(calls, 1, -(-total // self.chunk_vertices))
        return max(-(-total // calls), 1)

    def submit(self, batch: list[FeatureRings], points: FeaturePoints | None = None) -> BatchJob:
        """The batch cut into engine calls, started in the workers when they are used;
        ``points``: per feature of the batch, its interior points (or None)."""
        job = BatchJob(batch)
        sizes = [
            item.vertex_count()
            + (sum(len(part) for part in points[index] or ()) if points is not None else 0)
            if item.ok
            else 0
            for index, item in enumerate(batch)
        ]
        limit = self.call_vertices(sum(sizes))
        chunk: list[FeatureRings] = []
        chunk_points: FeaturePoints = []
        vertices = 0
        for index, item in enumerate(batch):
            if item.ok:
                chunk.append(item)
                chunk_points.append(points[index] if points is not None else None)
                vertices += sizes[index]
            last = index == len(batch) - 1
            if chunk and (last or len(chunk) >= self.chunk_features or vertices >= limit):
                job.calls.append(_call(chunk, chunk_points if points is not None else None))
                chunk, chunk_points, vertices = [], [], 0
        if self.parallel:
            self._waiting += [call for call in job.calls if call.packed is not None]
            if self._pool is None and len(self._waiting) > 1:
                self._pool = WorkerPool(self.workers)
            if self._pool is not None:
                for call in self._waiting:
                    _part_count, polygons, proven, points = call.packed
                    call.future = self._pool.submit(
                        polygons, proven=proven, **self.options.keywords(), **_points_option(points)
                    )
                self._waiting = []
        return job

    def finish(self, job: BatchJob, report: Callable[[float], None]) -> list[EngineChunk] | None:
        """The results of the job's calls in order (None when the run was cancelled)."""
        results: list[EngineChunk] = []
        done = 0
        for call in job.calls:
            outcome = self._worker_result(call)
            if self.feedback.isCanceled():
                return None
            self.calls += 1
            if outcome is None:

                def part_done(part: float, first: int = done, size: int = len(call.items)) -> None:
                    report((first + part * size) / max(len(job.batch), 1))

                try:
                    results += self.run_here(call.items, call.packed, part_done, call.points)
                except _CancelledError:
                    return None
            else:
                self.calls_in_workers += 1
                results.append(self._chunk(call.items, call.packed[0], outcome))
            self._waiting = [other for other in self._waiting if other is not call]
            done += len(call.items)
            report(done / max(len(job.batch), 1))
            if self.feedback.isCanceled():
                return None
        return results

    def _worker_result(self, call: _Call) -> PackedTriangulations | None:
        """The call's result from its worker; None when it has none (run it here)."""
        if call.future is None:
            return None
        return wait_for(call.future, self.feedback, self.stop_workers)

    def stop_workers(self, error: BaseException) -> None:
        """End the use of workers for the run (a worker could not start or stopped): a
        warning names ``error``, the calls run in QGIS's process from now on."""
        if self._pool is None:
            return
        self.feedback.pushWarning(
            self.tr("Worker processes stopped ({}); triangulating in this process.").format(error)
        )
        self.close(cancel=True)
        self.workers = 1

    def close(self, cancel: bool = False) -> None:
        """Stop the workers (at once when ``cancel``)."""
        if self._pool is not None:
            self._pool.close(cancel=cancel)
            self.workers_started += self._pool.started
            self._pool = None

    def run_here(
        self,
        items: list[FeatureRings],
        packed: Packed | None = None,
        report: Callable[[float], None] | None = None,
        points: FeaturePoints | None = None,
    ) -> list[EngineChunk]:
        """All parts of ``items`` (``packed`` already, or packed here with ``points``) in one
        engine call in this process; a failure goes to its feature. ``report`` takes the
        share done; a cancelled run raises ``_CancelledError`` out of the call."""

        def progress(part: float) -> None:
            if self.feedback.isCanceled():
                raise _CancelledError
            if report is not None:
                report(part)

        try:
            part_count, polygons, proven, packed_points = packed or _pack(items, points)
            outcome = triangulate_packed(
                polygons,
                proven=proven,
                progress=progress,
                **self.options.keywords(),
                **_points_option(packed_points),
            )
        except _CancelledError:
            raise
        except Exception as error:  # isolate the feature that breaks the call
            if len(items) == 1:
                items[0].error = self.tr("cannot be triangulated: {}").format(error)
                return []
            return [
                result
                for index, item in enumerate(items)
                if not self.feedback.isCanceled()
                for result in self.run_here(
                    [item], points=[points[index]] if points is not None else None
                )
            ]
        return [self._chunk(items, part_count, outcome)]

    def _chunk(
        self, items: list[FeatureRings], part_count: np.ndarray, outcome: PackedTriangulations
    ) -> EngineChunk:
        """The call's results; the first failed part of an item names its error."""
        item_kept = np.ones(len(items), dtype=bool)
        if outcome.errors:
            first_part = np.cumsum(part_count) - part_count
            owner = np.repeat(np.arange(len(items)), part_count)
            for part in sorted(outcome.errors):
                row = int(owner[part])
                if not item_kept[row]:
                    continue
                item_kept[row] = False
                count = int(part_count[row])
                index = part - int(first_part[row])
                where = self.tr(" (part {})").format(index) if count > 1 else ""
                items[row].error = self.tr("cannot be triangulated{}: {}").format(
                    where, outcome.errors[part]
                )
        return EngineChunk(items, part_count, outcome, item_kept)


def _points_option(points: dict | None) -> dict:
    """The engine's ``points`` (and ``meshes``) keywords, left out when there are none."""
    return {} if points is None else points
