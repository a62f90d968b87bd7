"""Densification of ring edges so that long edges follow the terrain once z is re-sampled."""

from __future__ import annotations

import numpy as np


def densify_ring(
    ring: np.ndarray, max_segment_length: float | None, closed: bool = True
) -> np.ndarray:
    """Insert evenly spaced points on every edge longer than ``max_segment_length``.

    An edge of XY length L is split into ``ceil(L / max_segment_length)`` equal pieces; z (and
    any further column) is interpolated linearly. The original vertices are kept, exactly and
    in order. ``closed`` includes the edge from the last vertex back to the first (a repeated
    closing point just makes that edge zero-length). ``None`` or a length <= 0 disables it.
    """
    ring = np.asarray(ring, dtype=np.float64)
    if not max_segment_length or max_segment_length <= 0 or len(ring) < 2:
        return ring.copy()
    if not np.isfinite(max_segment_length):
        return ring.copy()
    ends = np.roll(ring, -1, axis=0) if closed else ring[1:]
    starts = ring if closed else ring[:-1]
    deltas = ends - starts
    lengths = np.hypot(deltas[:, 0], deltas[:, 1])
    lengths[~np.isfinite(lengths)] = 0.0  # an edge with a NaN/inf end is left as it is
    pieces = np.maximum(np.ceil(lengths / max_segment_length), 1).astype(np.int64)
    edge = np.repeat(np.arange(len(starts)), pieces)
    first_row = np.cumsum(pieces) - pieces
    step = np.arange(len(edge)) - first_row[edge]
    fraction = step / pieces[edge]
    out = starts[edge] + fraction[:, None] * deltas[edge]
    out[first_row] = starts
    if not closed:
        out = np.vstack([out, ring[-1:]])
    return out


def densify_rings(rings: list[np.ndarray], max_segment_length: float | None) -> list[np.ndarray]:
    """:func:`densify_ring` applied to each closed ring of a polygon."""
    return [densify_ring(ring, max_segment_length) for ring in rings]
