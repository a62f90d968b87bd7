"""Snapping of nearly planar polygons onto planes (Liu, section 4.2 "shape optimisation").

Digitised roof outlines should be planar but carry elevation noise. The rule, applied to one
polygon (outer ring and islands) with tolerance ``t`` > 0; only z ever changes:

1. Polygon plane: fit z = a x + b y + c by least squares (vertical residuals) to all vertices
   of all rings. If every vertex is within ``t`` of it (vertically), every z is replaced by the
   plane's value and the polygon is exactly planar (up to float rounding).
2. Otherwise, runs along each ring: going round the ring, a run is a maximal sequence of at
   least 4 adjacent vertices whose own least-squares plane is within ``t`` of each of them;
   its vertices are put on that plane. Runs are grown one vertex at a time, greedily: the run
   holding the ring's first vertex is grown forwards and then backwards, the others follow it
   in ring order; a vertex that starts no such run is left alone. Runs do not overlap. If a
   run's vertices are collinear in XY, its "plane" is the least-squares line z(s) along it.
   Three points are always coplanar, so shorter runs change nothing.

Guarantee: no vertex moves by more than ``t``; every candidate change is checked against the
tolerance with the exact values that would be written, and a change that would break it is not
made. Vertical polygons (all vertices collinear in XY, where z = a x + b y + c does not exist)
are returned unchanged. A ring's repeated closing point is kept equal to its first point.
"""

from __future__ import annotations

import numpy as np

# Relative size of the smaller XY singular value below which points count as collinear.
_COLLINEAR = 1e-9


def _fitted_z(points: np.ndarray, allow_collinear: bool) -> np.ndarray | None:
    """z of the least-squares plane at each point; None when XY is degenerate (not allowed)."""
    xy = points[:, :2] - points[:, :2].mean(axis=0)
    z = points[:, 2]
    singular = np.linalg.svd(xy, compute_uv=False)
    if singular[0] == 0:
        return np.full(len(z), z.mean()) if allow_collinear else None
    if singular[-1] <= _COLLINEAR * singular[0]:
        if not allow_collinear:
            return None
        _, _, axes = np.linalg.svd(xy, full_matrices=False)
        along = xy @ axes[0]
        design = np.column_stack([along, np.ones(len(z))])
    else:
        design = np.column_stack([xy, np.ones(len(z))])
    coefficients, *_ = np.linalg.lstsq(design, z, rcond=None)
    return design @ coefficients


def _within(points: np.ndarray, fitted: np.ndarray | None, tolerance: float) -> bool:
    return fitted is not None and bool(np.all(np.abs(fitted - points[:, 2]) <= tolerance))


def _run_fit(ring: np.ndarray, start: int, length: int, tolerance: float) -> np.ndarray | None:
    """Fitted z of the run of ``length`` vertices from ``start`` (cyclic), if within tolerance."""
    points = ring[(start + np.arange(length)) % len(ring)]
    fitted = _fitted_z(points, allow_collinear=True)
    return fitted if _within(points, fitted, tolerance) else None


def _grow(
    ring: np.ndarray,
    run: tuple[int, int, np.ndarray | None],
    step: int,
    limit: int,
    tolerance: float,
) -> tuple[int, int, np.ndarray | None]:
    """Grow a run (start, length, fitted z) one vertex at a time forwards (+1) or backwards."""
    start, length, fitted = run
    while length < limit:
        new_start = start if step > 0 else start - 1
        candidate = _run_fit(ring, new_start, length + 1, tolerance)
        if candidate is None:
            break
        start, length, fitted = new_start, length + 1, candidate
    return start, length, fitted


def _snap_ring_runs(ring: np.ndarray, tolerance: float) -> np.ndarray:
    n = len(ring)
    out = ring.copy()
    if n < 4:
        return out
    whole = _run_fit(ring, 0, n, tolerance)
    if whole is not None:
        out[:, 2] = whole
        return out
    # Seeds are 3 vertices (always coplanar, left as they are until a 4th joins).
    first = _grow(ring, (0, 3, None), +1, n, tolerance)
    first = _grow(ring, first, -1, n, tolerance)
    if first[2] is None:
        runs, position, end = [], 1, n
    else:
        runs, position, end = [first], first[0] + first[1], first[0] + n
    while end - position >= 4:
        run = _grow(ring, (position, 3, None), +1, end - position, tolerance)
        if run[2] is None:
            position += 1
        else:
            runs.append(run)
            position += run[1]
    for start, length, fitted in runs:
        out[(start + np.arange(length)) % n, 2] = fitted
    return out


def _split_closing(ring: np.ndarray) -> tuple[np.ndarray, bool]:
    closed = len(ring) > 1 and bool(np.all(ring[0] == ring[-1]))
    return (ring[:-1] if closed else ring), closed


def snap_to_plane(rings: list[np.ndarray], tolerance: float) -> list[np.ndarray]:
    """Put nearly planar vertices of one polygon onto planes; see the module docstring.

    ``rings`` are (n, 3) arrays, outer ring first. Returns new arrays of the same shapes with
    only z changed and no vertex moved by more than ``tolerance``. A tolerance of 0/None,
    rings without z or with a non-finite coordinate give unchanged copies.
    """
    rings = [np.array(ring, dtype=np.float64) for ring in rings]
    if not tolerance or tolerance <= 0 or not rings or any(r.ndim != 2 for r in rings):
        return rings
    if any(r.shape[1] < 3 for r in rings) or not all(np.isfinite(r).all() for r in rings):
        return rings
    opened = [_split_closing(ring) for ring in rings]
    cores = [core for core, _ in opened]
    every = np.concatenate(cores)
    if len(every) < 3:
        return rings
    fitted = _fitted_z(every, allow_collinear=False)
    if fitted is None:
        return rings  # vertical polygon: no plane z = a x + b y + c
    if _within(every, fitted, tolerance):
        snapped, offset = [], 0
        for core in cores:
            core = core.copy()
            core[:, 2] = fitted[offset : offset + len(core)]
            offset += len(core)
            snapped.append(core)
    else:
        snapped = [_snap_ring_runs(core, tolerance) for core in cores]
    return [
        np.vstack([core, core[:1]]) if closed else core
        for core, (_, closed) in zip(snapped, opened)
    ]
