"""Real polygons with many islands, made from the Swellendam training data in ../shared/data.

- :func:`ground_around_buildings`: one polygon, the ground around the town's buildings (the
  convex hull of the 4,708 footprints, 50 m wider, with every footprint an island; footprints
  that touch are merged into one), in EPSG:32733. A ring of touching buildings around a
  courtyard cuts the ground's interior in two: the polygon is invalid, taken as given.
- :func:`urban_areas`: the 550 polygons of the urban areas layer (434 islands, many of them
  touching their shell or each other, as they come from a national data set).
- :func:`road_network`: the roads buffered 10 m and merged, the largest part: one polygon of
  long thin corridors whose islands are the blocks between the roads.

Each returns None where the shared data is missing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import shapely
from common import SHARED_DATA
from osgeo import ogr, osr

SWELLENDAM = SHARED_DATA / "swellendam"
GROUND_MARGIN = 50.0  # metres around the buildings' convex hull
ROAD_WIDTH = 10.0  # metres on either side of a road's centre line

Rings = list[np.ndarray]

EPSG = 32733  # the layers' own CRS, where the others are reprojected to


def layer_geometries(path: Path, layer_name: str | None = None) -> np.ndarray:
    """The geometries of the layer (by name, or the first) as 2D shapely ones in ``EPSG``;
    a corrupt record is left out (GDAL reports it and returns no geometry)."""
    dataset = ogr.Open(str(path))
    layer = dataset.GetLayerByName(layer_name) if layer_name else dataset.GetLayer(0)
    target = osr.SpatialReference()
    target.ImportFromEPSG(EPSG)
    target.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    source = layer.GetSpatialRef()
    source.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    transform = None if source.IsSame(target) else osr.CoordinateTransformation(source, target)
    geometries = []
    raised = ogr.GetUseExceptions()
    ogr.DontUseExceptions()
    try:
        for feature in layer:
            geometry = feature.GetGeometryRef()
            if geometry is None:
                continue
            geometry = geometry.Clone()
            if transform is not None:
                geometry.Transform(transform)
            geometries.append(shapely.from_wkb(bytes(geometry.ExportToIsoWkb())))
    finally:
        if raised:
            ogr.UseExceptions()
    return shapely.force_2d(np.array(geometries))


def _rings(polygon: shapely.Polygon) -> Rings:
    return [shapely.get_coordinates(ring)[:-1] for ring in (polygon.exterior, *polygon.interiors)]


def ground_around_buildings() -> Rings | None:
    """The ground around Swellendam's buildings, every building an island (see above)."""
    path = SWELLENDAM / "training_data.gpkg"
    if not path.exists():
        return None
    buildings = layer_geometries(path, "buildings")
    merged = shapely.union_all(shapely.make_valid(buildings))
    islands = [p for p in shapely.get_parts(merged) if p.geom_type == "Polygon"]
    shell = shapely.convex_hull(merged).buffer(GROUND_MARGIN)
    return [_rings(shell)[0], *(_rings(island)[0] for island in islands)]


def urban_areas() -> list[Rings] | None:
    """Every polygon of Swellendam's urban areas layer, with its islands."""
    path = SWELLENDAM / "urban_33S.shp"
    if not path.exists():
        return None
    parts = shapely.get_parts(layer_geometries(path))
    return [_rings(p) for p in parts if p.geom_type == "Polygon"]


def road_network() -> Rings | None:
    """Swellendam's roads buffered ``ROAD_WIDTH`` and merged: the part with the most islands."""
    path = SWELLENDAM / "roads_33S.shp"
    if not path.exists():
        return None
    roads = layer_geometries(path)
    merged = shapely.union_all(shapely.buffer(roads, ROAD_WIDTH, quad_segs=2))
    parts = [p for p in shapely.get_parts(merged) if p.geom_type == "Polygon"]
    return _rings(max(parts, key=lambda part: len(part.interiors)))
