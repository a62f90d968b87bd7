"""The ``bsptriangulate`` Processing provider."""

from __future__ import annotations

from pathlib import Path

from qgis.core import QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

ICONS = Path(__file__).resolve().parent.parent / "icons"


class BspTriangulateProvider(QgsProcessingProvider):
    """Provider ``bsptriangulate``: BSP-tree polygon triangulation to 3D meshes."""

    def id(self) -> str:
        return "bsptriangulate"

    def name(self) -> str:
        return self.tr("BSP Triangulate")

    def longName(self) -> str:  # noqa: N802 - QGIS API name
        return self.name()

    def icon(self) -> QIcon:
        return QIcon(str(ICONS / "provider.svg"))

    def loadAlgorithms(self) -> None:  # noqa: N802 - QGIS API name
        from .triangulate_algorithm import TriangulateAlgorithm

        self.addAlgorithm(TriangulateAlgorithm())
