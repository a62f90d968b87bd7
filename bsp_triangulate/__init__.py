"""BSP Triangulate: Qiang Liu's recursive BSP-tree triangulation of polygons with islands.

Pure Python (numpy); no QGIS import anywhere in this package.
"""

from .api import triangulate, triangulate_many, triangulate_packed
from .packed import PackedPolygons, PackedTriangulations
from .rules import RULES, ApexRule, get_rule, register_rule
from .triangulation import Triangulation, TriangulationError

__all__ = [
    "RULES",
    "ApexRule",
    "PackedPolygons",
    "PackedTriangulations",
    "Triangulation",
    "TriangulationError",
    "get_rule",
    "register_rule",
    "triangulate",
    "triangulate_many",
    "triangulate_packed",
]
