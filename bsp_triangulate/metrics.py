"""Vectorised per-triangle attributes (areas, angles, slope, aspect) and a quality summary."""

from __future__ import annotations

import numpy as np

# A normal whose horizontal part is this small relative to its length counts as flat.
_FLAT_EPS = 1e-12


def _corners(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, ...]:
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] not in (2, 3):
        raise ValueError("vertices must be an (N, 2) or (N, 3) array")
    if vertices.shape[1] == 2:
        vertices = np.column_stack([vertices, np.zeros(len(vertices))])
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    return vertices[triangles[:, 0]], vertices[triangles[:, 1]], vertices[triangles[:, 2]]


def _normals(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Right-hand normals (b - a) x (c - a); length is twice the 3D area."""
    return np.cross(b - a, c - a)


def area_2d(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area of each triangle's XY projection (non-negative)."""
    a, b, c = _corners(vertices, triangles)
    return 0.5 * np.abs(_normals(a, b, c)[:, 2])


def area_3d(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area of each triangle in 3D."""
    a, b, c = _corners(vertices, triangles)
    return 0.5 * np.linalg.norm(_normals(a, b, c), axis=1)


def min_angle(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Smallest interior angle in 3D, degrees (0 for degenerate triangles)."""
    a, b, c = _corners(vertices, triangles)
    angles = []
    for apex, p, q in ((a, b, c), (b, c, a), (c, a, b)):
        u, v = p - apex, q - apex
        # atan2(|u x v|, u . v) stays accurate for angles near 0 and 180 degrees.
        angles.append(np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), (u * v).sum(axis=1)))
    return np.degrees(np.min(angles, axis=0))


def slope(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Angle between the triangle's plane and the horizontal, degrees (NaN if degenerate)."""
    a, b, c = _corners(vertices, triangles)
    n = _normals(a, b, c)
    horizontal = np.hypot(n[:, 0], n[:, 1])
    with np.errstate(invalid="ignore"):
        result = np.degrees(np.arctan2(horizontal, np.abs(n[:, 2])))
    result[np.linalg.norm(n, axis=1) == 0] = np.nan
    return result


def aspect(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Downslope direction, degrees clockwise from north (GIS convention), NaN when flat.

    It is the azimuth of the horizontal part of the upward normal. For vertical triangles
    (no upward side) the right-hand normal of the vertex order is used.
    """
    a, b, c = _corners(vertices, triangles)
    n = _normals(a, b, c)
    n = np.where(n[:, 2:3] < 0, -n, n)
    horizontal = np.hypot(n[:, 0], n[:, 1])
    result = np.degrees(np.arctan2(n[:, 0], n[:, 1])) % 360.0
    flat = horizontal <= _FLAT_EPS * np.linalg.norm(n, axis=1)
    result[flat] = np.nan
    return result


def centroid(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(M, 3) mean of each triangle's corners."""
    a, b, c = _corners(vertices, triangles)
    return (a + b + c) / 3.0


def triangle_metrics(vertices: np.ndarray, triangles: np.ndarray) -> dict[str, np.ndarray]:
    """All per-triangle attributes by name (area_2d, area_3d, min_angle, slope, aspect)."""
    return {
        "area_2d": area_2d(vertices, triangles),
        "area_3d": area_3d(vertices, triangles),
        "min_angle": min_angle(vertices, triangles),
        "slope": slope(vertices, triangles),
        "aspect": aspect(vertices, triangles),
    }


def triangulation_quality(
    vertices: np.ndarray, triangles: np.ndarray, sliver_angle: float = 5.0
) -> dict[str, float]:
    """Summary numbers of a triangulation: count, total areas, angle statistics, slivers.

    ``slivers`` counts triangles whose smallest angle is below ``sliver_angle`` degrees;
    ``degenerate`` those with zero XY area.
    """
    angles = min_angle(vertices, triangles)
    areas = area_2d(vertices, triangles)
    count = len(angles)
    return {
        "triangles": count,
        "area_2d": float(areas.sum()),
        "area_3d": float(area_3d(vertices, triangles).sum()),
        "min_angle": float(angles.min()) if count else float("nan"),
        "mean_min_angle": float(angles.mean()) if count else float("nan"),
        "slivers": int((angles < sliver_angle).sum()),
        "degenerate": int((areas == 0).sum()),
    }
