"""The plugin object: registers the Processing provider and a menu entry that opens the tool."""

from __future__ import annotations

from qgis.core import QgsApplication
from qgis.PyQt.QtCore import QCoreApplication
from qgis.PyQt.QtGui import QIcon

from .processing_provider.provider import ICONS, BspTriangulateProvider

TRIANGULATE_ID = "bsptriangulate:triangulate"


class BspTriangulatePlugin:
    """Registers the ``bsptriangulate`` Processing provider (also under qgis_process)."""

    def __init__(self, iface=None) -> None:
        self.iface = iface
        self.provider: BspTriangulateProvider | None = None
        self.action = None

    @staticmethod
    def tr(text: str) -> str:
        return QCoreApplication.translate("BspTriangulatePlugin", text)

    def initProcessing(self) -> None:  # noqa: N802 - QGIS API name
        # QGIS calls this and then initGui; register once and keep the reference,
        # since a provider without one loses its algorithms.
        if self.provider is None:
            self.provider = BspTriangulateProvider()
            QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self) -> None:  # noqa: N802 - QGIS API name
        self.initProcessing()
        if self.iface is None:
            return
        from .processing_provider.qgis_compat import QAction

        self.action = QAction(
            QIcon(str(ICONS / "triangulate.svg")),
            self.tr("Triangulate polygons to a 3D mesh…"),
            self.iface.mainWindow(),
        )
        self.action.triggered.connect(self.open_dialog)
        self.iface.addPluginToMenu(self.tr("BSP Triangulate"), self.action)

    def open_dialog(self) -> None:
        """Open the Processing dialog of the triangulate algorithm."""
        import processing

        processing.execAlgorithmDialog(TRIANGULATE_ID)

    def unload(self) -> None:
        if self.action is not None and self.iface is not None:
            self.iface.removePluginMenu(self.tr("BSP Triangulate"), self.action)
            self.action = None
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
