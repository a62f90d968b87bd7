"""Interior points of the triangulate algorithm: survey points from a point layer, and DEM
cell centres added until the mesh is within a vertical tolerance of the DEM."""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable

import numpy as np
from qgis.core import (
    NULL,
    QgsCoordinateTransform,
    QgsFeatureRequest,
    QgsProcessingFeatureSource,
    QgsProcessingFeedback,
    QgsWkbTypes,
)

from ..bsp_triangulate import triangulate_many
from ..bsp_triangulate.terrain.refine import CellGrid, Refinement, refine_many
from .elevation import DemSampler, transform_xy
from .engine_runs import (
    EngineOptions,
    EngineRunner,
    FeaturePoints,
    share_count,
    wait_for,
    with_mesh,
)
from .geometry_io import FeatureRings

# DEM cells (of the parts' boxes) per share of a batch refined in a worker, at least: a
# smaller batch is refined in QGIS's process
MIN_SHARE_CELLS = 50_000


class CancelledError(Exception):
    """The run was cancelled while points were added."""


class SurveyPoints:
    """Points (x, y, z) in the polygon layer's CRS, sorted by x to find those in a box."""

    def __init__(self, xyz: np.ndarray) -> None:
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        self.xyz = xyz[np.argsort(xyz[:, 0], kind="stable")]

    def __len__(self) -> int:
        return len(self.xyz)

    def in_box(self, xmin: float, ymin: float, xmax: float, ymax: float) -> np.ndarray:
        """The points in the closed box, in x order."""
        first = int(np.searchsorted(self.xyz[:, 0], xmin, side="left"))
        last = int(np.searchsorted(self.xyz[:, 0], xmax, side="right"))
        chosen = self.xyz[first:last]
        return chosen[(chosen[:, 1] >= ymin) & (chosen[:, 1] <= ymax)]

    @classmethod
    def read(
        cls,
        source: QgsProcessingFeatureSource,
        z_field: str,
        transform: QgsCoordinateTransform | None,
        feedback: QgsProcessingFeedback,
    ) -> tuple[SurveyPoints, int]:
        """The points of a point layer (multipoints split) with z from ``z_field`` or, when
        it is empty, from the geometry; and how many were left out (no z, no geometry)."""
        request = QgsFeatureRequest()
        field_index = source.fields().lookupField(z_field) if z_field else -1
        request.setSubsetOfAttributes([field_index] if field_index >= 0 else [])
        rows: list[tuple[float, float, float]] = []
        skipped = 0
        for feature in source.getFeatures(request):
            if feedback.isCanceled():
                raise CancelledError
            geometry = feature.geometry()
            if geometry is None or geometry.isEmpty():
                skipped += 1
                continue
            value = None
            if field_index >= 0:
                value = feature.attribute(field_index)
                try:
                    value = None if value is None or value == NULL else float(value)
                except (TypeError, ValueError):
                    value = None
                if value is None or not np.isfinite(value):
                    skipped += 1
                    continue
            for vertex in geometry.vertices():
                z = value if value is not None else vertex.z()
                if z is None or not np.isfinite(z):
                    skipped += 1
                    continue
                rows.append((vertex.x(), vertex.y(), z))
        xyz = np.array(rows, dtype=np.float64).reshape(-1, 3)
        if transform is not None and len(xyz):
            xyz[:, :2] = transform_xy(xyz[:, :2], transform)
        finite = np.isfinite(xyz).all(axis=1)
        skipped += int((~finite).sum())
        return cls(xyz[finite]), skipped


def has_z(source: QgsProcessingFeatureSource) -> bool:
    return QgsWkbTypes.hasZ(source.wkbType())


class InteriorPoints:
    """Per batch, the interior points of each part of each feature: the survey points in
    its box, then, with a tolerance, DEM cell centres added by ``refine_many`` (all parts of
    the batch at once, a feature's parts sharing its cap of ``max_points``)."""

    def __init__(
        self,
        survey: SurveyPoints | None,
        sampler: DemSampler | None,
        tolerance: float,
        max_points: int,
        options: EngineOptions,
        feedback: QgsProcessingFeedback,
        runner: EngineRunner | None = None,
    ) -> None:
        self.survey = survey
        self.sampler = sampler if tolerance > 0 else None
        self.tolerance = tolerance
        self.max_points = max_points
        self.options = {k: v for k, v in options.keywords().items() if k != "on_error"}
        self.feedback = feedback
        # the run's engine runner: its worker pool, when the run uses one
        self.runner = runner
        self.added = 0

    def for_batch(
        self,
        batch: list[FeatureRings],
        warn: Callable[[int, str], None],
        progress: Callable[[float], None],
    ) -> FeaturePoints:
        """The points of every feature of the batch (z as the rings' z, before any scaling);
        features whose mesh stays farther from the DEM than the tolerance go to ``warn``
        with their id and the error reached. ``progress`` takes the share of the batch done."""
        points: FeaturePoints = [None] * len(batch)
        polygons, fixed, owners = [], [], []
        for index, item in enumerate(batch):
            if not item.ok:
                continue
            of_item = []
            for part in item.parts:
                outer = part[0][:, :2] if len(part) and len(part[0]) else np.zeros((0, 2))
                box = (*outer.min(0), *outer.max(0)) if len(outer) else None
                inside = (
                    self.survey.in_box(*box)
                    if self.survey is not None and box is not None
                    else np.zeros((0, 3))
                )
                of_item.append(inside)
                polygons.append(part)
                fixed.append(inside)
                owners.append(index)
            points[index] = of_item
        if self.sampler is None or not polygons:
            progress(1.0)
            return points
        grids = []
        for part in polygons:
            outer = part[0][:, :2]
            grids.append(self.sampler.cells(*outer.min(0), *outer.max(0)))
        results = self._refine(polygons, grids, fixed, owners, progress)
        progress(1.0)
        slots: dict[int, int] = {}
        for owner, result in zip(owners, results):
            slot = slots.get(owner, 0)
            slots[owner] = slot + 1
            points[owner][slot] = with_mesh(result.points, result.mesh)
            self.added += result.added
        self._report(batch, owners, results, warn)
        return points

    def _refine(
        self,
        polygons: list,
        grids: list[CellGrid],
        fixed: list[np.ndarray],
        owners: list[int],
        progress: Callable[[float], None],
    ) -> list[Refinement]:
        """``refine_many`` over the parts: in shares in the workers when the run uses them
        and the batch is large enough, else here."""
        total = len(polygons)
        shares = self._shares(grids, owners)
        pool = self.runner.worker_pool() if self.runner is not None and len(shares) > 1 else None

        def arguments(first: int, last: int) -> tuple[tuple, dict]:
            """``refine_many``'s arguments over parts first:last, its engine and progress
            aside: (positional, keywords)."""
            return (
                (polygons[first:last], grids[first:last], self.tolerance, self.max_points),
                {"fixed": fixed[first:last], "groups": owners[first:last], **self.options},
            )

        if pool is None:
            return self._refine_here(*arguments(0, total), 0, total, progress)
        calls = [arguments(first, last) for first, last in shares]
        futures = [pool.refine(*positional, **keywords) for positional, keywords in calls]
        results: list[Refinement] = []
        for (first, last), (positional, keywords), future in zip(shares, calls, futures):
            share = self._worker_result(future)
            if share is None:  # no result from the worker: refined here
                share = self._refine_here(positional, keywords, first, total, progress)
            results += share
            progress(last / total)
        return results

    def _worker_result(self, future: concurrent.futures.Future) -> list[Refinement] | None:
        """A share's refinements from its worker, None when it has none (refine it here);
        raises ``CancelledError`` when the run is cancelled meanwhile."""
        share = wait_for(future, self.feedback, self.runner.stop_workers)
        if share is None and self.feedback.isCanceled():
            future.cancel()
            raise CancelledError
        return share

    def _refine_here(
        self,
        positional: tuple,
        keywords: dict,
        first: int,
        total: int,
        progress: Callable[[float], None],
    ) -> list[Refinement]:
        """``refine_many`` in this process over parts ``first``... of ``total``, with the
        share's ``positional`` and ``keywords`` arguments (``_refine``)."""
        count = len(positional[0])

        def rounds(_round: int, active: int) -> None:
            if self.feedback.isCanceled():
                raise CancelledError
            progress((first + count - active) / total)

        return refine_many(*positional, engine=triangulate_many, progress=rounds, **keywords)

    def _shares(self, grids: list[CellGrid], owners: list[int]) -> list[tuple[int, int]]:
        """The parts cut into runs (first, last) of whole features with about equal DEM
        cells: two per worker where each keeps ``MIN_SHARE_CELLS`` (else fewer, a multiple
        of the workers where there are as many), one run without workers."""
        whole = [(0, len(grids))]
        workers = self.runner.workers if self.runner is not None and self.runner.parallel else 1
        if workers < 2:
            return whole
        cells = np.cumsum([grid.values.size for grid in grids])
        count = share_count(int(cells[-1]), workers, MIN_SHARE_CELLS)
        if count < 2:
            return whole
        # a feature's parts share its cap of points: cut only between features
        starts = [i for i in range(1, len(owners)) if owners[i] != owners[i - 1]]
        if not starts:
            return whole
        before = cells[np.array(starts) - 1]
        targets = cells[-1] * np.arange(1, count) / count
        cuts = sorted({starts[int(np.argmin(np.abs(before - t)))] for t in targets})
        bounds = [0, *cuts, len(grids)]
        return list(zip(bounds[:-1], bounds[1:]))

    def _report(
        self,
        batch: list[FeatureRings],
        owners: list[int],
        results: list[Refinement],
        warn: Callable[[int, str], None],
    ) -> None:
        """One warning per feature whose parts are not all within the tolerance."""
        worst: dict[int, Refinement] = {}
        for owner, result in zip(owners, results):
            if result.within:
                continue
            if owner not in worst or result.max_error > worst[owner].max_error:
                worst[owner] = result
        for owner, result in worst.items():
            if result.error is not None:
                reason = "DEM points stopped at {:.3f} m from the DEM (tolerance {:g} m): {}"
                warn(
                    batch[owner].fid,
                    reason.format(result.max_error, self.tolerance, result.error),
                )
            elif result.capped:
                reason = (
                    "mesh within {:.3f} m of the DEM, not {:g} m: the cap of {} added points "
                    "was reached"
                )
                warn(
                    batch[owner].fid,
                    reason.format(result.max_error, self.tolerance, self.max_points),
                )
            else:
                reason = (
                    "mesh within {:.3f} m of the DEM, not {:g} m: the DEM cells farther off "
                    "cannot become vertices (on the boundary or at an input point)"
                )
                warn(batch[owner].fid, reason.format(result.max_error, self.tolerance))


def scale_points(points: FeaturePoints, scale: float, offset: float) -> None:
    """z = z * scale + offset on every point, in place (as ``elevation.scale_z`` on rings)."""
    if scale == 1.0 and offset == 0.0:
        return
    for of_item in points:
        for part in of_item or ():
            part[:, 2] = part[:, 2] * scale + offset
