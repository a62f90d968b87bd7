"""BSP Triangulate: Qiang Liu's recursive BSP-tree triangulation of polygons with islands.

Pure Python (numpy); no QGIS import anywhere in this package.
"""

from .triangulation import Triangulation, TriangulationError

__all__ = ["Triangulation", "TriangulationError", "triangulate", "triangulate_many"]

try:  # the engine lands in its own module
    from .engine import triangulate, triangulate_many
except ImportError:  # pragma: no cover - during bootstrap only
    pass
