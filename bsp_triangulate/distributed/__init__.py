"""The engine on a Dask cluster: :func:`triangulate_dataset` triangulates a whole layer
(GeoParquet, GeoPackage or a dask-geopandas GeoDataFrame) partition by partition.

Optional: it needs dask, distributed, dask-geopandas, geopandas, pyarrow and pyogrio (GDAL's
Python bindings for a DEM), which nothing else in ``bsp_triangulate`` imports; the plugin does
not use it. Command line: ``python -m bsp_triangulate.distributed INPUT OUT_DIR``.
"""

from __future__ import annotations

from .dataset import triangulate_dataset

__all__ = ["triangulate_dataset"]
