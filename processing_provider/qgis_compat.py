"""The names of QGIS 4 (Qt 6) that older QGIS versions lack, in one place.

The plugin is written with QGIS 4's names: fully scoped enums and QMetaType field types.
Where the running QGIS predates a name, this module gives the older equivalent under the new
name; nowhere else does the plugin test the QGIS or Qt version to pick a name. Each enum here
is the running QGIS's own where it has it (``Qgis.WkbType``, ``Qgis.GeometryType`` and
``Qgis.DistanceUnit`` from 3.30, ``Qgis.Processing*``, ``Qgis.FeatureRequestFlag`` and
``Qgis.CrsWktVariant`` from 3.36), else the older enum
or a stand-in class with the new member names (only those the plugin uses).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from qgis.core import (
    Qgis,
    QgsCoordinateReferenceSystem,
    QgsFeatureRequest,
    QgsProcessing,
    QgsProcessingFeatureSource,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterField,
    QgsProcessingParameterNumber,
    QgsUnitTypes,
    QgsWkbTypes,
)
from qgis.PyQt.QtCore import QMetaType

try:
    from qgis.PyQt.QtGui import QAction  # Qt 6
except ImportError:
    from qgis.PyQt.QtWidgets import QAction  # Qt 5

__all__ = [
    "FIELD_TYPES",
    "CrsWktVariant",
    "DistanceUnit",
    "FeatureRequestFlag",
    "GeometryType",
    "ProcessingFeatureSourceFlag",
    "ProcessingFieldParameterDataType",
    "ProcessingNumberParameterType",
    "ProcessingParameterFlag",
    "ProcessingSourceType",
    "QAction",
    "WkbType",
]

# QgsField's type by name: a QMetaType.Type from QGIS 3.38 on (Qt 6 has no QVariant.Type).
if Qgis.QGIS_VERSION_INT >= 33800:
    FIELD_TYPES = {
        "Int": QMetaType.Type.Int,
        "LongLong": QMetaType.Type.LongLong,
        "Double": QMetaType.Type.Double,
        "String": QMetaType.Type.QString,
    }
else:
    # Qt 5 only; looked up by name, as Qt 6 checkers flag every QVariant.<Type> they read.
    from qgis.PyQt.QtCore import QVariant

    FIELD_TYPES = {
        kind: getattr(QVariant, kind) for kind in ("Int", "LongLong", "Double", "String")
    }


def _scoped_enum(name: str, older: Callable[[], Any], **renamed: str) -> Any:
    """``Qgis.<name>`` where the running QGIS has it; else the older enum ``older()``, as it is
    (its members have the new names) or, given ``renamed`` (new member name: older one), as a
    stand-in class of that name. ``older`` is called only then: newer QGIS drops older enums."""
    if hasattr(Qgis, name):
        return getattr(Qgis, name)
    enum = older()
    if not renamed:
        return enum
    return type(name, (), {new: getattr(enum, old) for new, old in renamed.items()})


# From 3.30 on: WkbType, GeometryType, DistanceUnit; from 3.36 on, the others.
WkbType = _scoped_enum("WkbType", lambda: QgsWkbTypes.Type)
GeometryType = _scoped_enum(
    "GeometryType",
    lambda: QgsWkbTypes.GeometryType,
    Polygon="PolygonGeometry",
    Unknown="UnknownGeometry",
)
DistanceUnit = _scoped_enum(
    "DistanceUnit", lambda: QgsUnitTypes.DistanceUnit, Meters="DistanceMeters"
)
FeatureRequestFlag = _scoped_enum("FeatureRequestFlag", lambda: QgsFeatureRequest.Flag)
CrsWktVariant = _scoped_enum(
    "CrsWktVariant", lambda: QgsCoordinateReferenceSystem.WktVariant, Preferred="WKT_PREFERRED"
)
ProcessingSourceType = _scoped_enum(
    "ProcessingSourceType",
    lambda: QgsProcessing.SourceType,
    VectorPolygon="TypeVectorPolygon",
    VectorLine="TypeVectorLine",
    VectorPoint="TypeVectorPoint",
)
ProcessingNumberParameterType = _scoped_enum(
    "ProcessingNumberParameterType",
    lambda: QgsProcessingParameterNumber.Type,
    Integer="Integer",
    Double="Double",
)
ProcessingFieldParameterDataType = _scoped_enum(
    "ProcessingFieldParameterDataType",
    lambda: QgsProcessingParameterField.DataType,
    Numeric="Numeric",
)
ProcessingParameterFlag = _scoped_enum(
    "ProcessingParameterFlag",
    lambda: QgsProcessingParameterDefinition.Flag,
    Advanced="FlagAdvanced",
)
ProcessingFeatureSourceFlag = _scoped_enum(
    "ProcessingFeatureSourceFlag",
    lambda: QgsProcessingFeatureSource.Flag,
    SkipGeometryValidityChecks="FlagSkipGeometryValidityChecks",
)
