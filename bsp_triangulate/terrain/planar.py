"""Snapping of nearly planar polygons onto planes (Liu, section 4.2 "shape optimisation").

Digitised roof outlines should be planar but carry elevation noise. The rule, applied to one
polygon (outer ring and islands) with tolerance ``t`` > 0; only z ever changes:

1. Polygon plane: fit z = a x + b y + c by least squares (vertical residuals) to all vertices
   of all rings. If every vertex is within ``t`` of it (vertically), every z is replaced by the
   plane's value and the polygon is exactly planar (up to float rounding).
2. Otherwise, ring planes: each ring (outer ring or island, e.g. a raised skylight) whose
   vertices are all within ``t`` of the ring's own least-squares plane is put on that plane.
3. Any other ring is left exactly as it is: its elevation differences are real, not noise.

Guarantee: no vertex moves by more than ``t``; every candidate change is checked against the
tolerance with the exact values that would be written, and a change that would break it is not
made. Vertical polygons (all vertices collinear in XY, where z = a x + b y + c does not exist)
are returned unchanged. A ring's repeated closing point is kept equal to its first point.
"""

from __future__ import annotations

import numpy as np

# Relative size of the smaller XY singular value below which points count as collinear.
_COLLINEAR = 1e-9


def _fitted_z(points: np.ndarray) -> np.ndarray | None:
    """z of the least-squares plane at each point; None when the points are collinear in XY."""
    xy = points[:, :2] - points[:, :2].mean(axis=0)
    z = points[:, 2]
    singular = np.linalg.svd(xy, compute_uv=False)
    if singular[0] == 0 or singular[-1] <= _COLLINEAR * singular[0]:
        return None
    design = np.column_stack([xy, np.ones(len(z))])
    coefficients, *_ = np.linalg.lstsq(design, z, rcond=None)
    return design @ coefficients


def _within(points: np.ndarray, fitted: np.ndarray | None, tolerance: float) -> bool:
    return fitted is not None and bool(np.all(np.abs(fitted - points[:, 2]) <= tolerance))


def _snap_ring(ring: np.ndarray, tolerance: float) -> np.ndarray:
    """The ring on its own least-squares plane if every vertex is within the tolerance of it."""
    out = ring.copy()
    fitted = _fitted_z(ring) if len(ring) >= 3 else None
    if _within(ring, fitted, tolerance):
        out[:, 2] = fitted
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
    fitted = _fitted_z(every)
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
        snapped = [_snap_ring(core, tolerance) for core in cores]
    return [
        np.vstack([core, core[:1]]) if closed else core
        for core, (_, closed) in zip(snapped, opened)
    ]
