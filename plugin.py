"""The plugin object: registers the Processing provider and keeps a reference to it."""

from __future__ import annotations

from qgis.core import QgsApplication

from .processing_provider.provider import BspTriangulateProvider


class BspTriangulatePlugin:
    """Registers the ``bsptriangulate`` Processing provider."""

    def __init__(self, iface=None) -> None:
        self.iface = iface
        self.provider: BspTriangulateProvider | None = None

    def initProcessing(self) -> None:  # noqa: N802 - QGIS API name
        # Keep the reference: a provider without one loses its algorithms.
        self.provider = BspTriangulateProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self) -> None:  # noqa: N802 - QGIS API name
        self.initProcessing()

    def unload(self) -> None:
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
