"""QGIS Processing glue of BSP Triangulate: provider and algorithms (thin layer over the core)."""
