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


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise cross product (several times faster than np.cross on (M, 3) arrays)."""
    out = np.empty_like(u)
    out[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    out[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    out[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return out


def _length(u: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", u, u))


def _normals(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Right-hand normals (b - a) x (c - a); length is twice the 3D area."""
    return _cross(b - a, c - a)


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", u, v)


def _min_angle(a: np.ndarray, b: np.ndarray, c: np.ndarray, n: np.ndarray) -> np.ndarray:
    # |u x v| is the same (|n|) at all three corners, so the smallest angle
    # atan2(|n|, u . v) is the one with the largest dot product; atan2 stays accurate
    # near 0 and 180 degrees.
    dots = np.maximum.reduce([_dot(b - a, c - a), _dot(c - b, a - b), _dot(a - c, b - c)])
    return np.degrees(np.arctan2(_length(n), dots))


def _slope(n: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        result = np.degrees(np.arctan2(np.hypot(n[:, 0], n[:, 1]), np.abs(n[:, 2])))
    result[_length(n) == 0] = np.nan
    return result


def _aspect(n: np.ndarray) -> np.ndarray:
    n = np.where(n[:, 2:3] < 0, -n, n)
    result = np.degrees(np.arctan2(n[:, 0], n[:, 1])) % 360.0
    result[np.hypot(n[:, 0], n[:, 1]) <= _FLAT_EPS * _length(n)] = np.nan
    return result


def area_2d(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area of each triangle's XY projection (non-negative)."""
    a, b, c = _corners(vertices, triangles)
    return 0.5 * np.abs(
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    )


def area_3d(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area of each triangle in 3D."""
    return 0.5 * _length(_normals(*_corners(vertices, triangles)))


def min_angle(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Smallest interior angle in 3D, degrees (0 for degenerate triangles)."""
    a, b, c = _corners(vertices, triangles)
    return _min_angle(a, b, c, _normals(a, b, c))


def slope(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Angle between the triangle's plane and the horizontal, degrees (NaN if degenerate)."""
    return _slope(_normals(*_corners(vertices, triangles)))


def aspect(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Downslope direction, degrees clockwise from north (GIS convention), NaN when flat.

    It is the azimuth of the horizontal part of the upward normal. For vertical triangles
    (no upward side) the right-hand normal of the vertex order is used.
    """
    return _aspect(_normals(*_corners(vertices, triangles)))


def centroid(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(M, 3) mean of each triangle's corners."""
    a, b, c = _corners(vertices, triangles)
    return (a + b + c) / 3.0


# WGS 84: semi-major axis (m) and flattening
WGS84 = (6378137.0, 1.0 / 298.257223563)


def _in_local_metres(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, ellipsoid: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corners in degrees of longitude and latitude as east and north metres from each
    triangle's first corner, at its mean latitude (the ellipsoid's radii of curvature there:
    exact to well under a thousandth over a building or a field)."""
    major, flattening = ellipsoid
    e2 = flattening * (2.0 - flattening)
    latitude = np.radians((a[:, 1] + b[:, 1] + c[:, 1]) / 3.0)
    w = 1.0 - e2 * np.sin(latitude) ** 2
    north = np.radians(major * (1.0 - e2) / w**1.5)  # metres per degree of latitude
    east = np.radians(major / np.sqrt(w) * np.cos(latitude))  # per degree of longitude
    scale = np.column_stack([east, north, np.ones(len(a))])
    return np.zeros_like(a), (b - a) * scale, (c - a) * scale


def triangle_metrics(
    vertices: np.ndarray, triangles: np.ndarray, ellipsoid: tuple[float, float] | None = None
) -> dict[str, np.ndarray]:
    """All per-triangle attributes by name (area_2d, area_3d, min_angle, slope, aspect,
    centroid), sharing one gather of the corners and one normal computation.

    ``ellipsoid`` (semi-major axis in metres, flattening; e.g. :data:`WGS84`): x and y are
    degrees of longitude and latitude, z is metres; areas are then in square metres and
    angles, slope and aspect are those of the real surface. The centroid stays in the
    vertices' own units."""
    a, b, c = _corners(vertices, triangles)
    centre = (a + b + c) / 3.0
    if ellipsoid is not None:
        a, b, c = _in_local_metres(a, b, c, ellipsoid)
    n = _normals(a, b, c)
    return {
        "area_2d": 0.5 * np.abs(n[:, 2]),
        "area_3d": 0.5 * _length(n),
        "min_angle": _min_angle(a, b, c, n),
        "slope": _slope(n),
        "aspect": _aspect(n),
        "centroid": centre,
    }


def triangulation_quality(
    vertices: np.ndarray, triangles: np.ndarray, sliver_angle: float = 5.0
) -> dict[str, float]:
    """Summary numbers of a triangulation: count, total areas, angle statistics, slivers.

    ``slivers`` counts triangles whose smallest angle is below ``sliver_angle`` degrees;
    ``degenerate`` those with zero XY area.
    """
    metrics = triangle_metrics(vertices, triangles)
    angles, areas = metrics["min_angle"], metrics["area_2d"]
    count = len(angles)
    return {
        "triangles": count,
        "area_2d": float(areas.sum()),
        "area_3d": float(metrics["area_3d"].sum()),
        "min_angle": float(angles.min()) if count else float("nan"),
        "mean_min_angle": float(angles.mean()) if count else float("nan"),
        "slivers": int((angles < sliver_angle).sum()),
        "degenerate": int((areas == 0).sum()),
    }
