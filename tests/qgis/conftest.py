"""Fixtures of the QGIS tests."""

from __future__ import annotations

import pytest
from qgis.core import QgsApplication

from tests.conftest import load_plugin_package


@pytest.fixture(scope="module")
def provider(qgis_processing):
    """The plugin's provider, registered for one test module (other modules test unload)."""
    load_plugin_package()
    from bsptriangulate.processing_provider.provider import BspTriangulateProvider

    registry = QgsApplication.processingRegistry()
    instance = BspTriangulateProvider()
    assert registry.addProvider(instance)
    yield instance
    registry.removeProvider(instance)
