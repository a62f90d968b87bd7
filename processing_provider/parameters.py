"""Parameter and output declarations that the Processing algorithms share.

Each function makes one declaration (or a pair that belongs together) from the parameter's name
and, where the algorithms word it differently, its label. Labels are translated by the calling
algorithm's ``tr``, so each algorithm keeps its own translation context.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TypeVar

from qgis.core import (
    QgsProcessingOutputNumber,
    QgsProcessingParameterBand,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFeatureSink,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
)

from .qgis_compat import (
    ProcessingNumberParameterType,
    ProcessingParameterFlag,
    ProcessingSourceType,
)

Translate = Callable[[str], str]
Parameter = TypeVar("Parameter", bound=QgsProcessingParameterDefinition)


def polygon_source(name: str, label: str) -> QgsProcessingParameterFeatureSource:
    """The input layer: polygons or multipolygons."""
    return QgsProcessingParameterFeatureSource(name, label, [ProcessingSourceType.VectorPolygon])


def dem_and_band(dem: str, band: str, tr: Translate) -> list[QgsProcessingParameterDefinition]:
    """The optional DEM raster and its band (default 1)."""
    return [
        QgsProcessingParameterRasterLayer(dem, tr("DEM"), optional=True),
        QgsProcessingParameterBand(
            band, tr("DEM band"), defaultValue=1, parentLayerParameterName=dem, optional=True
        ),
    ]


def non_negative_double(name: str, label: str) -> QgsProcessingParameterNumber:
    """A distance or tolerance: a double from 0 (the default, "off") up."""
    return QgsProcessingParameterNumber(
        name, label, ProcessingNumberParameterType.Double, defaultValue=0.0, minValue=0.0
    )


def apex_rule(name: str, tr: Translate) -> QgsProcessingParameterEnum:
    """The rule that picks a triangle's apex (the order of ``APEX_RULES``), first by default."""
    return QgsProcessingParameterEnum(
        name,
        tr("Apex rule"),
        [
            tr("First correct apex (planar)"),
            tr("Closest elevation"),
            tr("Constrained Delaunay (largest angle)"),
        ],
        defaultValue=0,
    )


def invalid_polygons(name: str, repair_label: str, tr: Translate) -> QgsProcessingParameterEnum:
    """The invalid-polygon policy: repair (the default; ``repair_label`` says what follows),
    fail the feature, or triangulate the rings as given."""
    return QgsProcessingParameterEnum(
        name,
        tr("Invalid polygons"),
        [repair_label, tr("Fail the feature"), tr("Triangulate the rings as given")],
        defaultValue=0,
    )


def advanced(parameters: Iterable[Parameter]) -> list[Parameter]:
    """The parameters, each flagged Advanced (shown folded in the dialog)."""
    flagged = list(parameters)
    for parameter in flagged:
        parameter.setFlags(parameter.flags() | ProcessingParameterFlag.Advanced)
    return flagged


def polygon_sink(
    name: str, label: str, create_by_default: bool
) -> QgsProcessingParameterFeatureSink:
    """An optional output layer of polygons."""
    return QgsProcessingParameterFeatureSink(
        name,
        label,
        ProcessingSourceType.VectorPolygon,
        optional=True,
        createByDefault=create_by_default,
    )


def file_destination(
    name: str, label: str, file_filter: str, create_by_default: bool
) -> QgsProcessingParameterFileDestination:
    """An optional output file."""
    return QgsProcessingParameterFileDestination(
        name, label, file_filter, optional=True, createByDefault=create_by_default
    )


def count_outputs(labels: Iterable[tuple[str, str]]) -> list[QgsProcessingOutputNumber]:
    """A number output for each (name, label)."""
    return [QgsProcessingOutputNumber(name, label) for name, label in labels]
