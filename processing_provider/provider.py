"""The ``bsptriangulate`` Processing provider."""

from __future__ import annotations

import traceback
from pathlib import Path

from qgis.core import Qgis, QgsMessageLog, QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

ICONS = Path(__file__).resolve().parent.parent / "icons"


class BspTriangulateProvider(QgsProcessingProvider):
    """Provider ``bsptriangulate``: BSP-tree polygon triangulation to 3D meshes."""

    def id(self) -> str:
        return "bsptriangulate"

    def name(self) -> str:
        return self.tr("BSP Triangulate")

    def longName(self) -> str:  # noqa: N802 - QGIS API name
        return self.tr("BSP Triangulate: recursive BSP-tree polygon triangulation")

    def icon(self) -> QIcon:
        return QIcon(self.svgIconPath())

    def svgIconPath(self) -> str:  # noqa: N802 - QGIS API name
        return str(ICONS / "provider.svg")

    def loadAlgorithms(self) -> None:  # noqa: N802 - QGIS API name
        # Called from C++: an exception escaping here would abort the whole application,
        # so a broken algorithm module is logged and leaves the provider empty instead.
        try:
            from .triangulate_algorithm import TriangulateAlgorithm

            self.addAlgorithm(TriangulateAlgorithm())
        except Exception:
            QgsMessageLog.logMessage(
                traceback.format_exc(), self.name(), Qgis.MessageLevel.Critical
            )
        try:
            from .buildings_algorithm import BuildingsAlgorithm

            self.addAlgorithm(BuildingsAlgorithm())
        except Exception:
            QgsMessageLog.logMessage(
                traceback.format_exc(), self.name(), Qgis.MessageLevel.Critical
            )
