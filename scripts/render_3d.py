"""Render the demo's outputs in QGIS's 3D renderer to a PNG.

The terrain is the demo's DEM (QGIS's DEM terrain, textured with the 2D picture's hypsometric
colours and hillshade); on it the triangulate run's triangles of the river and the lake
(triangles.gpkg: DEM points added inside until the surface is within the demo's maximum vertical
error of the DEM, coloured by BSP depth as in the 2D picture, with their edges)
and the buildings run's solids (buildings.gpkg: roofs, walls and floors as 3D triangles). QGIS
3.22 cannot open the GLB models, and its 3D mesh renderer drew nothing of the 2DM mesh in a
script, so the GeoPackages the same runs wrote are drawn. The picture is a print layout's 3D
map item, which renders with QGIS's own 3D engine (Qt 3D on OpenGL) and waits until the scene is
loaded: it needs an X display (Xvfb will do; Mesa's software OpenGL is enough), not Qt's offscreen
platform.

Usage: python scripts/render_3d.py [DEMO_DIR] [OUTPUT.png]   (defaults: build/demo and
DEMO_DIR/demo-3d.png). scripts/demo.py runs it under xvfb-run when there is no display.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

if not os.environ.get("DISPLAY"):
    sys.exit("render_3d.py needs an X display: run it under xvfb-run -a")
os.environ["QT_QPA_PLATFORM"] = "xcb"
os.environ.setdefault("QGIS_CUSTOM_CONFIG_PATH", tempfile.mkdtemp(prefix="bsptri-render3d-"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import render
from qgis._3d import (
    Qgs3D,
    Qgs3DMapSettings,
    Qgs3DTypes,
    QgsCameraPose,
    QgsLayoutItem3DMap,
    QgsPhongMaterialSettings,
    QgsPolygon3DSymbol,
    QgsRuleBased3DRenderer,
)
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsLayoutExporter,
    QgsLayoutPoint,
    QgsLayoutSize,
    QgsMapLayer,
    QgsNullSymbolRenderer,
    QgsPointXY,
    QgsPrintLayout,
    QgsProject,
    QgsReadWriteContext,
    QgsRectangle,
    QgsUnitTypes,
    QgsVector3D,
)
from qgis.PyQt.QtCore import QSize
from qgis.PyQt.QtGui import QColor
from qgis.PyQt.QtXml import QDomDocument

ROOT = Path(__file__).resolve().parent.parent
TRIANGLE_STYLE = ROOT / "processing_provider" / "styles" / "triangles.qml"
EPSG = 32733
WATER = "#2f7fc1"
SKY = "#dfe8f0"
# the solids' surfaces: (surface value, colour)
SURFACES = (("roof", "#b5473a"), ("wall", "#efe6d2"), ("floor", "#8c8c8c"))
WIDTH_PX, HEIGHT_PX = 1000, 560
GAP_PX = 6
# (width in px, (camera target x, y in the DEM's CRS, distance m, pitch deg, heading deg)):
# the river's bend, the lake and the village; then the village close up
VIEWS = (
    (597, (302_700.0, 6_202_150.0, 2200.0, 58.0, 0.0)),
    (397, (302_500.0, 6_202_480.0, 260.0, 55.0, 30.0)),
)
VERTICAL_SCALE = 1.0  # the terrain's exaggeration (the mesh and the solids keep their z)
# metres: the water drawn this far up. QGIS's terrain tiles approximate the DEM (within
# TERRAIN_SCREEN_ERROR px), and the water is within the demo's 1 m of it: without the lift the
# terrain shows through the water in specks, farther off.
WATER_LIFT = 1.5
TERRAIN_SCREEN_ERROR = 0.5


def depth_classes(style: Path) -> list[tuple[float, float, str]]:
    """The triangle style's depth classes and colours: (lowest, highest, colour), as in the 2D
    picture's legend."""
    layer = render.QgsVectorLayer("Polygon?crs=EPSG:32733&field=depth:integer", "style", "memory")
    _message, ok = layer.loadNamedStyle(str(style))
    if not ok:
        raise RuntimeError(f"cannot read {style}")
    return [
        (item.lowerValue(), item.upperValue(), item.symbol().color().name())
        for item in layer.renderer().ranges()
    ]


def water_layer(path: Path) -> render.QgsVectorLayer:
    """The triangulate run's triangles of the river and the lake (on the DEM, with the points
    added), coloured by BSP depth as in the 2D picture, with white edges."""
    layer = render.vector_layer(f"{path}|layername=triangles")
    layer.setSubsetString("\"kind\" <> 'roof'")  # the roofs are the solids
    root = QgsRuleBased3DRenderer.Rule(None)
    for low, high, colour in depth_classes(TRIANGLE_STYLE):
        symbol = surface_symbol(colour)
        symbol.setHeight(WATER_LIFT)
        if hasattr(symbol, "setEdgesEnabled"):
            symbol.setEdgesEnabled(True)
            symbol.setEdgeColor(QColor("white"))
            symbol.setEdgeWidth(1.0)
        root.appendChild(
            QgsRuleBased3DRenderer.Rule(symbol, f'"depth" >= {low} AND "depth" <= {high}')
        )
    layer.setRenderer3D(QgsRuleBased3DRenderer(root))
    layer.setRenderer(QgsNullSymbolRenderer())  # not in the terrain's texture
    return layer


def surface_symbol(colour: str) -> QgsPolygon3DSymbol:
    material = QgsPhongMaterialSettings()
    material.setDiffuse(QColor(colour))
    material.setAmbient(QColor(colour).darker(250))
    material.setSpecular(QColor(40, 40, 40))
    symbol = QgsPolygon3DSymbol()
    symbol.setMaterial(material)
    symbol.setAltitudeClamping(Qgs3DTypes.AltClampAbsolute)  # the triangles' own z
    symbol.setExtrusionHeight(0.0)
    symbol.setAddBackFaces(True)
    return symbol


def solids_layer(path: Path) -> render.QgsVectorLayer:
    """The buildings run's triangles, coloured by surface (roof, wall, floor)."""
    layer = render.vector_layer(str(path))
    root = QgsRuleBased3DRenderer.Rule(None)
    for surface, colour in SURFACES:
        root.appendChild(
            QgsRuleBased3DRenderer.Rule(surface_symbol(colour), f"\"surface\" = '{surface}'")
        )
    layer.setRenderer3D(QgsRuleBased3DRenderer(root))
    layer.setRenderer(QgsNullSymbolRenderer())  # not in the terrain's texture
    return layer


def dem_terrain(settings: Qgs3DMapSettings, dem_id: str, project: QgsProject) -> None:
    """QGIS's DEM terrain generator on the DEM layer, set through the settings' XML (the
    generator classes have no Python bindings in QGIS 3.22). Call it first: reading the XML
    resets the other settings."""
    document = QDomDocument()
    element = document.createElement("qgis3d")
    document.appendChild(element)
    terrain = document.createElement("terrain")
    for name, value in (
        ("exaggeration", VERTICAL_SCALE),
        ("texture-size", 1024),
        ("max-terrain-error", TERRAIN_SCREEN_ERROR),
        ("max-ground-error", 0.5),
        ("shading-enabled", 0),
    ):
        terrain.setAttribute(name, str(value))
    generator = document.createElement("generator")
    generator.setAttribute("type", "dem")
    generator.setAttribute("layer", dem_id)
    generator.setAttribute("resolution", "64")
    generator.setAttribute("skirt-height", "20")
    terrain.appendChild(generator)
    element.appendChild(terrain)
    settings.readXml(element, QgsReadWriteContext())
    settings.resolveReferences(project)


def height_at(dem: render.QgsRasterLayer, x: float, y: float) -> float:
    value, ok = dem.dataProvider().sample(QgsPointXY(x, y), 1)
    return float(value) if ok else 0.0


def map_settings(
    project: QgsProject, extent: QgsRectangle, dem: QgsMapLayer, layers: list[QgsMapLayer]
) -> Qgs3DMapSettings:
    """The 3D scene: the DEM terrain, its texture and the layers (a new object for each layout
    item, which takes it over)."""
    settings = Qgs3DMapSettings()
    dem_terrain(settings, dem.id(), project)
    settings.setCrs(project.crs())
    settings.setTransformContext(project.transformContext())
    settings.setPathResolver(project.pathResolver())
    settings.setOrigin(QgsVector3D(extent.center().x(), extent.center().y(), 0))
    settings.setLayers([*layers, dem])
    settings.setBackgroundColor(QColor(SKY))
    settings.setFieldOfView(40)
    return settings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("demo_dir", nargs="?", type=Path, default=ROOT / "build" / "demo")
    parser.add_argument("output", nargs="?", type=Path)
    arguments = parser.parse_args()
    demo = arguments.demo_dir.resolve()
    output = (arguments.output or demo / "demo-3d.png").resolve()
    render.start_qgis()
    Qgs3D.initialize()
    project = QgsProject.instance()
    crs = QgsCoordinateReferenceSystem(f"EPSG:{EPSG}")
    project.setCrs(crs)
    colours, hillshade = render.terrain_layers(demo / "terrain.tif")
    water = water_layer(demo / "triangles.gpkg")
    solids = solids_layer(demo / "buildings.gpkg")
    for layer in (colours, hillshade, water, solids):
        project.addMapLayer(layer)

    extent: QgsRectangle = colours.extent()

    layout = QgsPrintLayout(project)
    layout.initializeDefaults()
    page = layout.pageCollection().page(0)
    page.setPageSize(QgsLayoutSize(WIDTH_PX / 4, HEIGHT_PX / 4, QgsUnitTypes.LayoutMillimeters))
    left = 0.0
    for width, (x, y, distance, pitch, heading) in VIEWS:
        item = QgsLayoutItem3DMap(layout)
        item.attemptMove(QgsLayoutPoint(left / 4, 0, QgsUnitTypes.LayoutMillimeters))
        item.attemptResize(QgsLayoutSize(width / 4, HEIGHT_PX / 4, QgsUnitTypes.LayoutMillimeters))
        item.setMapSettings(map_settings(project, extent, colours, [solids, water, hillshade]))
        pose = QgsCameraPose()
        # world coordinates: x east and -z north of the origin (the DEM's centre), y up
        local = extent.center()
        ground = height_at(colours, x, y)
        pose.setCenterPoint(QgsVector3D(x - local.x(), ground, -(y - local.y())))
        pose.setDistanceFromCenterPoint(distance)
        pose.setPitchAngle(pitch)
        pose.setHeadingAngle(heading)
        item.setCameraPose(pose)
        layout.addLayoutItem(item)
        left += width + GAP_PX

    exporter = QgsLayoutExporter(layout)
    image_settings = QgsLayoutExporter.ImageExportSettings()
    image_settings.dpi = 25.4 * 4  # 4 px per millimetre
    image_settings.imageSize = QSize(WIDTH_PX, HEIGHT_PX)
    result = exporter.exportToImage(str(output), image_settings)
    if result != QgsLayoutExporter.Success:
        sys.exit(f"the 3D picture could not be written ({result})")
    render.to_palette(output)
    print(output, f"{output.stat().st_size / 1000:.0f} kB")


if __name__ == "__main__":
    main()
