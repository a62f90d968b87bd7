"""The validity proof against QGIS's own GEOS check (``QgsGeometry.isGeosValid``), which the
repair and fail policies would otherwise ask: a proven geometry is always GEOS-valid."""

from __future__ import annotations

import numpy as np
import pytest
from qgis.core import QgsGeometry, QgsVectorLayer

from tests.conftest import SHARED_DATA, load_plugin_package
from tests.core.validity_cases import all_cases


@pytest.fixture(scope="module")
def proof():
    load_plugin_package()
    from bsptriangulate.bsp_triangulate.formats.wkb import polygon_table
    from bsptriangulate.bsp_triangulate.geometry.validity import proven_valid

    def proven(wkbs: list[bytes]) -> np.ndarray:
        return proven_valid(polygon_table(wkbs), np.ones(len(wkbs), dtype=bool))

    return proven


def _geos_valid(wkbs: list[bytes]) -> np.ndarray:
    valid = []
    for wkb in wkbs:
        geometry = QgsGeometry()
        geometry.fromWkb(wkb)
        valid.append(geometry.isGeosValid())
    return np.array(valid)


def test_generated_polygons_proven_valid_are_geos_valid(proof):
    wkbs = all_cases()
    proven = proof(wkbs)
    valid = _geos_valid(wkbs)
    assert not (proven & ~valid).any(), np.flatnonzero(proven & ~valid)
    assert proven.sum() > 0.5 * valid.sum()


@pytest.mark.parametrize(
    "name", ["farms_33S", "water_33S", "protected_areas", "urban_33S", "training_data"]
)
def test_swellendam_polygons_proven_valid_are_geos_valid(proof, name):
    suffix = ".gpkg" if name == "training_data" else ".shp"
    layer = QgsVectorLayer(str(SHARED_DATA / "swellendam" / f"{name}{suffix}"), name, "ogr")
    assert layer.isValid()
    geometries = [feature.geometry() for feature in layer.getFeatures()]
    wkbs = [bytes(geometry.asWkb()) for geometry in geometries]
    proven = proof(wkbs)
    valid = np.array([geometry.isGeosValid() for geometry in geometries])
    assert not (proven & ~valid).any()
    if name == "farms_33S":
        assert proven.sum() > 1000 and (~valid).sum() >= 16


@pytest.mark.parametrize("policy", [0, 1, 2])
def test_features_read_carry_the_proof_to_the_engine(proof, policy):
    from bsptriangulate.processing_provider.geometry_io import INVALID_AS_GIVEN, read_features

    layer = QgsVectorLayer(str(SHARED_DATA / "swellendam" / "farms_33S.shp"), "farms", "ogr")
    features = list(layer.getFeatures())
    items = list(read_features(features, policy))
    flags = np.array([item.proven for item in items])
    if policy == INVALID_AS_GIVEN:
        # nothing is proven where nothing is checked: the batch path proves for itself
        assert not flags.any()
    else:
        wkbs = [bytes(feature.geometry().asWkb()) for feature in features]
        assert np.array_equal(flags, proof(wkbs))
        assert flags.sum() > 1000
