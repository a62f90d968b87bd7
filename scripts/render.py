"""Render vector layers over a shaded terrain to PNG with QgsMapRendererParallelJob.

Usage: python scripts/render.py TERRAIN.tif OUTPUT.png VECTOR[::STYLE.qml] ... [--extent ...]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("QGIS_CUSTOM_CONFIG_PATH", tempfile.mkdtemp(prefix="bsptri-render-"))

from qgis.core import (
    QgsApplication,
    QgsBilinearRasterResampler,
    QgsColorRampShader,
    QgsContrastEnhancement,
    QgsFeature,
    QgsGeometry,
    QgsMapLayer,
    QgsMapRendererParallelJob,
    QgsMapSettings,
    QgsMarkerSymbol,
    QgsPointXY,
    QgsRasterLayer,
    QgsRasterShader,
    QgsRectangle,
    QgsSingleBandGrayRenderer,
    QgsSingleBandPseudoColorRenderer,
    QgsSingleSymbolRenderer,
    QgsVectorLayer,
)
from qgis.PyQt.QtCore import QSize, Qt
from qgis.PyQt.QtGui import QColor, QFont, QImage, QPainter

# hypsometric tints: green valleys to brown and pale hill tops
TERRAIN_COLOURS = ("#3d7a3d", "#8fb55e", "#e3d98f", "#c49a6c", "#f2eee6")
POINT_COLOUR = "#c0392b"  # point_layer's dots

_application: QgsApplication | None = None


def start_qgis() -> QgsApplication:
    """Start a headless QGIS application once per process."""
    global _application
    if _application is None and QgsApplication.instance() is None:
        QgsApplication.setPrefixPath("/usr", True)
        _application = QgsApplication([], False)
        _application.initQgis()
    return _application or QgsApplication.instance()


def hillshade_raster(terrain: Path) -> Path:
    """A multi-directional hillshade of the terrain, computed once next to a temporary copy."""
    from osgeo import gdal

    output = Path(tempfile.mkdtemp(prefix="bsptri-hillshade-")) / f"{terrain.stem}_hillshade.tif"
    options = gdal.DEMProcessingOptions(multiDirectional=True, zFactor=2.0, computeEdges=True)
    gdal.DEMProcessing(str(output), str(terrain), "hillshade", options=options)
    return output


def terrain_layers(path: Path) -> list[QgsRasterLayer]:
    """The terrain twice: hypsometric colours under a multiplied hillshade."""
    colours = QgsRasterLayer(str(path), "terrain colours")
    hillshade = QgsRasterLayer(str(hillshade_raster(path)), "terrain hillshade")
    if not colours.isValid() or not hillshade.isValid():
        raise RuntimeError(f"cannot open raster {path}")
    for layer in (colours, hillshade):  # no visible cell edges when zoomed in
        layer.resampleFilter().setZoomedInResampler(QgsBilinearRasterResampler())
        layer.resampleFilter().setZoomedOutResampler(QgsBilinearRasterResampler())
    statistics = colours.dataProvider().bandStatistics(1)
    low, high = statistics.minimumValue, statistics.maximumValue
    ramp = QgsColorRampShader(low, high)
    ramp.setColorRampType(QgsColorRampShader.Interpolated)
    step = (high - low) / (len(TERRAIN_COLOURS) - 1)
    ramp.setColorRampItemList(
        [
            QgsColorRampShader.ColorRampItem(low + i * step, QColor(colour))
            for i, colour in enumerate(TERRAIN_COLOURS)
        ]
    )
    shader = QgsRasterShader()
    shader.setRasterShaderFunction(ramp)
    colours.setRenderer(QgsSingleBandPseudoColorRenderer(colours.dataProvider(), 1, shader))
    gray = QgsSingleBandGrayRenderer(hillshade.dataProvider(), 1)
    enhancement = QgsContrastEnhancement(hillshade.dataProvider().dataType(1))
    enhancement.setContrastEnhancementAlgorithm(QgsContrastEnhancement.StretchToMinimumMaximum)
    enhancement.setMinimumValue(60)
    enhancement.setMaximumValue(255)
    gray.setContrastEnhancement(enhancement)
    hillshade.setRenderer(gray)
    hillshade.setBlendMode(QPainter.CompositionMode_Multiply)
    hillshade.setOpacity(0.5)
    return [colours, hillshade]


def vector_layer(path: str, style: Path | None = None) -> QgsVectorLayer:
    """A vector layer from a path (or OGR URI), styled from a .qml file when one is given."""
    layer = QgsVectorLayer(path, Path(path.split("|")[0]).stem, "ogr")
    if not layer.isValid():
        raise RuntimeError(f"cannot open vector layer {path}")
    if style is not None:
        message, ok = layer.loadNamedStyle(str(style))
        if not ok:
            raise RuntimeError(f"cannot apply style {style}: {message}")
    return layer


def point_layer(
    points: Sequence[Sequence[float]],
    crs: str,
    name: str,
    colour: str = POINT_COLOUR,
    size: float = 2.0,
) -> QgsVectorLayer:
    """A memory layer of (x, y) points in ``crs`` (an authority id), drawn as dots of ``size``
    millimetres with a white outline."""
    layer = QgsVectorLayer(f"Point?crs={crs}", name, "memory")
    features = []
    for x, y in points:
        feature = QgsFeature()
        feature.setGeometry(QgsGeometry.fromPointXY(QgsPointXY(float(x), float(y))))
        features.append(feature)
    layer.dataProvider().addFeatures(features)
    layer.updateExtents()
    symbol = QgsMarkerSymbol.createSimple(
        {
            "name": "circle",
            "color": colour,
            "outline_color": "white",
            "outline_width": "0.3",
            "size": str(size),
        }
    )
    layer.setRenderer(QgsSingleSymbolRenderer(symbol))
    return layer


def render(
    layers: Sequence[QgsMapLayer],
    output: Path,
    extent: QgsRectangle,
    size: tuple[int, int] = (1200, 900),
    title: str | None = None,
) -> Path:
    """Render the layers (first on top) over the extent to a PNG file."""
    settings = QgsMapSettings()
    settings.setLayers(list(layers))
    settings.setDestinationCrs(layers[-1].crs())
    settings.setExtent(extent)
    settings.setOutputSize(QSize(*size))
    settings.setBackgroundColor(QColor("white"))
    settings.setFlag(QgsMapSettings.Antialiasing, True)
    settings.setFlag(QgsMapSettings.DrawLabeling, True)
    job = QgsMapRendererParallelJob(settings)
    job.start()
    job.waitForFinished()
    image = job.renderedImage()
    if title:
        draw_title(image, title)
    output.parent.mkdir(parents=True, exist_ok=True)
    if not image.save(str(output), "PNG"):
        raise RuntimeError(f"cannot write {output}")
    return output


def draw_title(image: QImage, title: str) -> None:
    """A caption in the upper left corner, on a white box."""
    painter = QPainter(image)
    font = QFont("DejaVu Sans", 11)
    font.setBold(True)
    painter.setFont(font)
    metrics = painter.fontMetrics()
    box = metrics.boundingRect(title).adjusted(-6, -4, 6, 4)
    box.moveTo(8, 8)
    painter.fillRect(box, QColor(255, 255, 255, 215))
    painter.setPen(QColor("black"))
    painter.drawText(box, Qt.AlignCenter, title)
    painter.end()


def side_by_side(
    images: Sequence[Path],
    output: Path,
    gap: int = 6,
    palette: bool = False,
    legend: QImage | None = None,
    keep: Sequence[QColor] = (),
) -> Path:
    """Join PNG images horizontally (top-aligned) into one PNG, with ``legend`` below them;
    ``palette``: 256 colours, ``keep`` among them exactly (the style's class colours)."""
    loaded = [QImage(str(path)) for path in images]
    width = sum(image.width() for image in loaded) + gap * (len(loaded) - 1)
    height = max(image.height() for image in loaded)
    joined = QImage(width, height + (legend.height() if legend else 0), QImage.Format_RGB32)
    joined.fill(QColor("white"))
    painter = QPainter(joined)
    x = 0
    for image in loaded:
        painter.drawImage(x, 0, image)
        x += image.width() + gap
    if legend is not None:
        painter.drawImage(0, height, legend)
    painter.end()
    if not joined.save(str(output), "PNG"):
        raise RuntimeError(f"cannot write {output}")
    if palette:
        to_palette(output, keep)
    return output


def graduated_classes(layer: QgsVectorLayer) -> list[tuple[str, QColor]]:
    """The (label, colour) of each class of a graduated renderer, as its legend shows them."""
    renderer = layer.renderer()
    ranges = renderer.ranges() if hasattr(renderer, "ranges") else []
    return [(item.label(), item.symbol().color()) for item in ranges]


def legend_strip(
    width: int, title: str, classes: Sequence[tuple[str, QColor]], note: str, height: int = 34
) -> QImage:
    """A one-line legend: the title, a swatch per class with its label, then a note."""
    image = QImage(width, height, QImage.Format_RGB32)
    image.fill(QColor("white"))
    painter = QPainter(image)
    painter.setRenderHint(QPainter.Antialiasing)
    font = QFont("DejaVu Sans", 10)
    bold = QFont(font)
    bold.setBold(True)
    middle = height // 2
    x = 10
    painter.setFont(bold)
    painter.setPen(QColor("black"))
    metrics = painter.fontMetrics()
    painter.drawText(x, middle + metrics.ascent() // 2 - 1, title)
    x += metrics.horizontalAdvance(title) + 10
    painter.setFont(font)
    metrics = painter.fontMetrics()
    for label, colour in classes:
        painter.fillRect(x, middle - 8, 26, 16, colour)
        painter.setPen(QColor("#666666"))
        painter.drawRect(x, middle - 8, 26, 16)
        painter.setPen(QColor("black"))
        x += 31
        painter.drawText(x, middle + metrics.ascent() // 2 - 1, label)
        x += metrics.horizontalAdvance(label) + 12
    x += 18
    painter.drawText(x, middle + metrics.ascent() // 2 - 1, note)
    painter.end()
    return image


def to_palette(path: Path, keep: Sequence[QColor] = ()) -> bool:
    """Rewrite a PNG with 256 colours (a third of the size) when Pillow is available.

    Qt's own 8-bit conversion uses a fixed palette that bands the terrain, so Pillow's median cut
    is used instead; without Pillow the picture stays in full colour. ``keep``: colours in the
    palette as they are (median cut alone shifts the few small areas of a class colour, such as
    the depth classes, towards the terrain's colours), the median cut's colours for the rest.
    """
    try:
        from PIL import Image
    except ImportError:
        return False
    with Image.open(path) as image:
        rgb = image.convert("RGB")
    kept = list(dict.fromkeys((colour.red(), colour.green(), colour.blue()) for colour in keep))
    quantized = rgb.quantize(256 - len(kept), method=Image.Quantize.MEDIANCUT)
    if kept:
        median = quantized.getpalette()[: 3 * (256 - len(kept))]
        palette = Image.new("P", (1, 1))
        palette.putpalette([value for colour in kept for value in colour] + median)
        quantized = rgb.quantize(palette=palette, dither=Image.Dither.NONE)
    quantized.save(path, optimize=True)
    return True


def parse_extent(values: Sequence[float] | None, layers: Sequence[QgsMapLayer]) -> QgsRectangle:
    if values:
        return QgsRectangle(*values)
    extent = QgsRectangle(layers[-1].extent())
    extent.scale(1.02)
    return extent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("terrain", type=Path)
    parser.add_argument("output", type=Path)
    parser.add_argument("vectors", nargs="*", help="PATH or PATH::STYLE.qml, drawn first on top")
    parser.add_argument("--extent", nargs=4, type=float, metavar=("XMIN", "YMIN", "XMAX", "YMAX"))
    parser.add_argument("--size", nargs=2, type=int, default=(1200, 900))
    arguments = parser.parse_args()
    start_qgis()
    layers: list[QgsMapLayer] = []
    for item in arguments.vectors:
        path, _, style = item.partition("::")
        layers.append(vector_layer(path, Path(style) if style else None))
    layers += list(reversed(terrain_layers(arguments.terrain)))
    render(layers, arguments.output, parse_extent(arguments.extent, layers), tuple(arguments.size))
    print(arguments.output)


if __name__ == "__main__":
    main()
