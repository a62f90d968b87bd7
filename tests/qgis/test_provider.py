"""The plugin as QGIS loads it: package ``bsptriangulate``, provider registration, algorithm
contract (parameter and output names the README and models rely on), icons and help."""

from __future__ import annotations

import pytest
from qgis.core import QgsApplication, QgsProcessingAlgorithm
from qgis.PyQt.QtWidgets import QWidget

from tests.conftest import (
    TRIANGULATE_ID,
    TRIANGULATE_OUTPUTS,
    TRIANGULATE_PARAMETERS,
    load_plugin_package,
)

PROVIDER_ID = "bsptriangulate"


class FakeIface:
    """The few QgisInterface calls the plugin makes, recorded."""

    def __init__(self, window: QWidget) -> None:
        self.window = window
        self.menu: dict[str, list] = {}

    def mainWindow(self) -> QWidget:
        return self.window

    def addPluginToMenu(self, name: str, action) -> None:
        self.menu.setdefault(name, []).append(action)

    def removePluginMenu(self, name: str, action) -> None:
        self.menu[name].remove(action)


@pytest.fixture()
def plugin(qgis_parent: QWidget):
    """The plugin made by classFactory and started as QGIS does; unloaded afterwards."""
    package = load_plugin_package()
    instance = package.classFactory(FakeIface(qgis_parent))
    instance.initProcessing()
    instance.initGui()
    yield instance
    instance.unload()


def triangulate() -> QgsProcessingAlgorithm:
    algorithm = QgsApplication.processingRegistry().algorithmById(TRIANGULATE_ID)
    assert algorithm is not None, f"{TRIANGULATE_ID} is not registered"
    return algorithm


def test_plugin_package_exposes_the_core_as_a_subpackage() -> None:
    package = load_plugin_package()
    import bsptriangulate.bsp_triangulate as core

    assert package.__name__ == "bsptriangulate"
    assert core.Triangulation.__module__ == "bsptriangulate.bsp_triangulate.triangulation"


def test_init_processing_then_init_gui_registers_the_provider_once(plugin) -> None:
    registry = QgsApplication.processingRegistry()
    providers = [p for p in registry.providers() if p.id() == PROVIDER_ID]
    assert providers == [plugin.provider]
    assert sorted(a.id() for a in plugin.provider.algorithms()) == [
        "bsptriangulate:buildings",
        TRIANGULATE_ID,
    ]


def test_init_gui_adds_one_menu_entry_and_unload_removes_it_and_the_provider(
    qgis_parent: QWidget,
) -> None:
    iface = FakeIface(qgis_parent)
    instance = load_plugin_package().classFactory(iface)
    instance.initGui()
    assert [len(actions) for actions in iface.menu.values()] == [1]
    instance.unload()
    assert QgsApplication.processingRegistry().providerById(PROVIDER_ID) is None
    assert [len(actions) for actions in iface.menu.values()] == [0]


def test_triangulate_declares_the_documented_parameters_and_outputs(plugin) -> None:
    algorithm = triangulate()
    assert {p.name() for p in algorithm.parameterDefinitions()} >= TRIANGULATE_PARAMETERS
    assert {o.name() for o in algorithm.outputDefinitions()} >= TRIANGULATE_OUTPUTS


def test_every_algorithm_has_an_icon_help_and_lower_case_ids(plugin) -> None:
    assert not plugin.provider.icon().isNull()
    assert plugin.provider.algorithms(), "the provider has no algorithm"
    for algorithm in plugin.provider.algorithms():
        assert algorithm.name() == algorithm.name().lower()
        assert algorithm.groupId() == algorithm.groupId().lower()
        assert not algorithm.icon().isNull(), algorithm.id()
        assert algorithm.displayName().strip(), algorithm.id()
        assert len(algorithm.shortHelpString()) > 40, algorithm.id()
