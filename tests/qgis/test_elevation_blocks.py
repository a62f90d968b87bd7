"""DEM elevation over features whose rings are rows of one array (FeatureRings.block) and
features with rings of their own: the same z, errors and fills as ring by ring."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import load_plugin_package

load_plugin_package()

from bsptriangulate.bsp_triangulate.terrain.raster_sampling import fill_along_ring  # noqa: E402
from bsptriangulate.processing_provider import elevation  # noqa: E402
from bsptriangulate.processing_provider.geometry_io import FeatureRings  # noqa: E402


class FakeSampler:
    """z = x + 10 y; NaN where x lies in a gap."""

    def __init__(self, gap: tuple[float, float]) -> None:
        self.gap = gap

    def sample(self, xy: np.ndarray) -> np.ndarray:
        values = xy[:, 0] + 10 * xy[:, 1]
        values[(xy[:, 0] >= self.gap[0]) & (xy[:, 0] < self.gap[1])] = np.nan
        return values


def _batch(rng: np.random.Generator) -> list[FeatureRings]:
    """Features with 1-3 parts of 1-3 rings; most are rows of shared arrays, in runs."""
    items = []
    points = rng.uniform(0, 100, (5000, 3))
    row = 0
    for index in range(60):
        parts = []
        start = row
        for _part in range(int(rng.integers(1, 4))):
            rings = []
            for _ring in range(int(rng.integers(1, 4))):
                count = int(rng.integers(4, 12))
                rings.append(points[row : row + count])
                row += count
            parts.append(rings)
        item = FeatureRings(None, parts)
        kind = index % 5
        if kind == 0:
            item.parts = [[ring.copy() for ring in part] for part in parts]  # own arrays
        elif kind == 1:
            row += 3  # a gap in the rows: the next block starts a new run
            item.block = (points, start, row - 3)
        elif kind == 2 and index % 3 == 0:
            item.error = "failed before"
        else:
            item.block = (points, start, row)
        items.append(item)
    return items


def _reference(batch: list[FeatureRings], sampler: FakeSampler, policy: int) -> None:
    """The ring-by-ring procedure (the one before blocks)."""
    rings = [(item, ring) for item in batch if item.ok for part in item.parts for ring in part]
    for item, ring in rings:
        if item.error is not None:
            continue
        z = sampler.sample(ring[:, :2])
        missing = int(np.isnan(z).sum())
        if not missing:
            ring[:, 2] = z
        elif missing == len(z):
            item.error = "no vertex of a ring lies on a valid DEM cell"
        elif policy == elevation.NODATA_FAIL:
            item.error = (
                f"{missing} of {len(z)} vertices of a ring fall on DEM nodata or outside the DEM"
            )
        else:
            ring[:, 2] = fill_along_ring(z, ring[:, :2])


@pytest.mark.parametrize("policy", [elevation.NODATA_FILL, elevation.NODATA_FAIL])
@pytest.mark.parametrize("gap", [(200.0, 300.0), (40.0, 45.0), (0.0, 100.0)])
def test_blocks_give_the_same_z_and_errors_as_ring_by_ring(policy, gap):
    got = _batch(np.random.default_rng(4))
    expected = _batch(np.random.default_rng(4))
    sampler = FakeSampler(gap)
    elevation.DemElevation(sampler, policy).apply(got)
    _reference(expected, sampler, policy)
    for mine, theirs in zip(got, expected):
        assert mine.error == theirs.error
        if theirs.error is None:
            for part, other in zip(mine.parts, theirs.parts):
                for ring, ring_expected in zip(part, other):
                    assert ring.tobytes() == ring_expected.tobytes()


def test_assigning_parts_clears_the_block():
    points = np.zeros((8, 3))
    item = FeatureRings(None, [[points[:4], points[4:]]])
    item.block = (points, 0, 8)
    assert item.vertex_count() == 8
    item.proven = True
    item.parts = [[points[:4]]]
    assert item.block is None and item.vertex_count() == 4
    # new parts (densified, repaired) are no longer the ones the validity proof saw
    assert not item.proven
