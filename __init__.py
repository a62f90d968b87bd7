"""QGIS plugin entry point of BSP Triangulate."""


def classFactory(iface):  # noqa: N802 - name required by QGIS
    """Return the plugin instance QGIS asks for."""
    from .plugin import BspTriangulatePlugin

    return BspTriangulatePlugin(iface)
