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

# Before 3.30: QgsWkbTypes.Type, with the same member names.
WkbType = Qgis.WkbType if hasattr(Qgis, "WkbType") else QgsWkbTypes.Type

if hasattr(Qgis, "GeometryType"):
    GeometryType = Qgis.GeometryType
else:

    class GeometryType:
        Polygon = QgsWkbTypes.GeometryType.PolygonGeometry
        Unknown = QgsWkbTypes.GeometryType.UnknownGeometry


if hasattr(Qgis, "DistanceUnit"):
    DistanceUnit = Qgis.DistanceUnit
else:

    class DistanceUnit:
        Meters = QgsUnitTypes.DistanceUnit.DistanceMeters


# Before 3.36: QgsFeatureRequest.Flag, with the same member names.
FeatureRequestFlag = (
    Qgis.FeatureRequestFlag if hasattr(Qgis, "FeatureRequestFlag") else QgsFeatureRequest.Flag
)

if hasattr(Qgis, "CrsWktVariant"):
    CrsWktVariant = Qgis.CrsWktVariant
else:

    class CrsWktVariant:
        Preferred = QgsCoordinateReferenceSystem.WktVariant.WKT_PREFERRED


if hasattr(Qgis, "ProcessingSourceType"):
    ProcessingSourceType = Qgis.ProcessingSourceType
else:

    class ProcessingSourceType:
        VectorPolygon = QgsProcessing.SourceType.TypeVectorPolygon
        VectorLine = QgsProcessing.SourceType.TypeVectorLine
        VectorPoint = QgsProcessing.SourceType.TypeVectorPoint


if hasattr(Qgis, "ProcessingNumberParameterType"):
    ProcessingNumberParameterType = Qgis.ProcessingNumberParameterType
else:

    class ProcessingNumberParameterType:
        Integer = QgsProcessingParameterNumber.Type.Integer
        Double = QgsProcessingParameterNumber.Type.Double


if hasattr(Qgis, "ProcessingFieldParameterDataType"):
    ProcessingFieldParameterDataType = Qgis.ProcessingFieldParameterDataType
else:

    class ProcessingFieldParameterDataType:
        Numeric = QgsProcessingParameterField.DataType.Numeric


if hasattr(Qgis, "ProcessingParameterFlag"):
    ProcessingParameterFlag = Qgis.ProcessingParameterFlag
else:

    class ProcessingParameterFlag:
        Advanced = QgsProcessingParameterDefinition.Flag.FlagAdvanced


if hasattr(Qgis, "ProcessingFeatureSourceFlag"):
    ProcessingFeatureSourceFlag = Qgis.ProcessingFeatureSourceFlag
else:

    class ProcessingFeatureSourceFlag:
        SkipGeometryValidityChecks = QgsProcessingFeatureSource.Flag.FlagSkipGeometryValidityChecks
