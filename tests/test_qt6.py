"""Ready for QGIS 4 (Qt 6), shown without QGIS 4, on the plugin's own code (read with ast).

- Every Qt module, class, enum and member the plugin names through ``qgis.PyQt`` exists in
  PyQt6; no file imports PyQt5 or PyQt6 directly; no ``exec_()``.
- Every QGIS or Qt enum member the plugin names is reached through its own scoped enum in the
  running QGIS (``Qgis.WkbType.PolygonZ``, not ``QgsWkbTypes.PolygonZ``): QGIS 4 drops the
  unscoped names and the aliases that QGIS 3 keeps for them.
- Names that QGIS 3.22 lacks come from processing_provider/qgis_compat.py, the one module with
  version-dependent branches (``QGIS_VERSION_INT`` tests, ``except ImportError``), whose Qt 5
  branches are left out of the PyQt6 check; it gives the running QGIS's own enum where it has it.

The PyQt6 look-ups run in a separate interpreter that imports neither QGIS nor PyQt5.
"""

from __future__ import annotations

import ast
import enum
import importlib
import json
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from tests.conftest import PLUGIN_PACKAGE, ROOT, load_plugin_package

PROVIDER = ROOT / "processing_provider"
COMPAT = PROVIDER / "qgis_compat.py"
PLUGIN_FILES = [ROOT / "__init__.py", ROOT / "plugin.py", *sorted(PROVIDER.rglob("*.py"))]
QT_PACKAGE = "qgis.PyQt"
QGIS_MODULES = {"qgis.core", "qgis.gui", "qgis.analysis", "qgis.processing"}
# Methods that PyQt6 renamed (exec_ -> exec, print_ -> print).
PYQT5_METHODS = {"exec_", "print_"}
# A fresh interpreter: each (module, chain) looked up in PyQt6, the missing ones printed.
PYQT6_LOOKUP = """
import importlib, json, sys
missing = []
for where, module, chain in json.load(sys.stdin):
    target = importlib.import_module("PyQt6." + module)
    for depth, name in enumerate(chain):
        if not hasattr(target, name):
            missing.append(f"{where}: {'.'.join([module, *chain[: depth + 1]])}")
            break
        target = getattr(target, name)
print(json.dumps(missing))
"""


def rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


@dataclass(frozen=True)
class Name:
    """A name bound by an import: from ``module`` (``compat`` for qgis_compat) its ``member``."""

    module: str
    member: str | None


class PluginModule:
    """One plugin file: its imports, attribute chains, and its Qt-5-only (legacy) branches."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        self.legacy = {id(node) for _, branch in legacy_branches(self.tree) for node in branch}
        self.names: dict[str, Name] = {}
        for node in ast.walk(self.tree):
            if isinstance(node, ast.ImportFrom) and id(node) not in self.legacy:
                module = imported_module(node)
                for alias in node.names:
                    self.names[alias.asname or alias.name] = Name(module, alias.name)
            elif isinstance(node, ast.Import) and id(node) not in self.legacy:
                for alias in node.names:
                    if alias.asname:
                        self.names[alias.asname] = Name(alias.name, None)

    def where(self, node: ast.AST) -> str:
        return f"{rel(self.path)}:{node.lineno}"

    def chains(self) -> Iterator[tuple[ast.AST, Name, list[str]]]:
        """(node, root name, [root, attr, ...]) for each longest attribute chain on an import."""
        skipped = self.legacy | {
            id(node.value) for node in ast.walk(self.tree) if isinstance(node, ast.Attribute)
        }
        for node in ast.walk(self.tree):
            if not isinstance(node, ast.Attribute) or id(node) in skipped:
                continue
            chain: list[str] = []
            part: ast.AST = node
            while isinstance(part, ast.Attribute):
                chain.insert(0, part.attr)
                part = part.value
            if isinstance(part, ast.Name) and part.id in self.names:
                yield node, self.names[part.id], [part.id, *chain]


def imported_module(node: ast.ImportFrom) -> str:
    """The absolute module name, with the plugin's own qgis_compat as ``compat``."""
    module = node.module or ""
    if node.level and module.split(".")[-1] == "qgis_compat":
        return "compat"
    return "." * node.level + module


def legacy_branches(tree: ast.AST) -> Iterator[tuple[ast.AST, list[ast.AST]]]:
    """(where, its nodes) for each branch taken on older QGIS or Qt only: the ``except
    ImportError`` of a ``try`` that imports from qgis.PyQt, and the ``else`` of an ``if`` on
    ``QGIS_VERSION_INT``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Try) and imports_qt(node.body):
            for handler in node.handlers:
                caught = {getattr(n, "id", None) for n in ast.walk(handler.type or ast.Pass())}
                if caught & {"ImportError", "ModuleNotFoundError"}:
                    yield handler, [n for statement in handler.body for n in ast.walk(statement)]
        elif isinstance(node, ast.If) and version_test(node.test):
            yield node, [n for statement in node.orelse for n in ast.walk(statement)]


def imports_qt(statements: list[ast.stmt]) -> bool:
    return any(
        isinstance(n, ast.ImportFrom) and (n.module or "").startswith(QT_PACKAGE)
        for statement in statements
        for n in ast.walk(statement)
    )


def version_test(test: ast.AST) -> bool:
    return any(
        (isinstance(n, ast.Attribute) and n.attr == "QGIS_VERSION_INT")
        or (isinstance(n, ast.Name) and n.id == "QGIS_VERSION_INT")
        for n in ast.walk(test)
    )


def plugin_modules(*, compat: bool = True) -> list[PluginModule]:
    return [PluginModule(path) for path in PLUGIN_FILES if compat or path != COMPAT]


def project_python_files() -> list[Path]:
    """Every Python file of the work tree but the venv, caches and build output."""
    return sorted(
        path
        for path in ROOT.rglob("*.py")
        if not any(
            part.startswith(".") or part in {"build", "dist", "__pycache__"}
            for part in path.relative_to(ROOT).parts
        )
    )


def test_no_python_file_imports_pyqt_directly() -> None:
    offending = []
    for path in project_python_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                modules = [node.module or ""]
            else:
                continue
            for module in modules:
                if module.split(".")[0] in {"PyQt5", "PyQt6", "PySide2", "PySide6", "sip"}:
                    offending.append(f"{rel(path)}:{node.lineno}: import {module}")
    assert not offending, "import Qt through qgis.PyQt:\n" + "\n".join(offending)


def qt_lookups() -> list[tuple[str, str, list[str]]]:
    """(where, Qt module, chain) for each Qt name the plugin uses outside Qt 5 branches."""
    lookups = []
    for module in plugin_modules():
        for node in ast.walk(module.tree):
            if isinstance(node, ast.ImportFrom) and id(node) not in module.legacy:
                if node.module == QT_PACKAGE:
                    lookups += [(module.where(node), a.name, []) for a in node.names]
                elif (node.module or "").startswith(QT_PACKAGE + "."):
                    qt_module = node.module.removeprefix(QT_PACKAGE + ".")
                    lookups += [(module.where(node), qt_module, [a.name]) for a in node.names]
        for node, name, chain in module.chains():
            if name.module.startswith(QT_PACKAGE + "."):
                qt_module = name.module.removeprefix(QT_PACKAGE + ".")
                lookups.append((module.where(node), qt_module, [name.member, *chain[1:]]))
            elif name.module == QT_PACKAGE:
                lookups.append((module.where(node), name.member, chain[1:]))
    return lookups


def test_every_qt_class_enum_and_member_the_plugin_names_exists_in_pyqt6() -> None:
    lookups = qt_lookups()
    assert any(chain == ["QIcon"] for _, _, chain in lookups)  # the parser sees the imports
    proc = subprocess.run(
        [sys.executable, "-c", PYQT6_LOOKUP],
        input=json.dumps(lookups),
        capture_output=True,
        text=True,
        timeout=120,
        cwd="/",
    )
    assert proc.returncode == 0, f"PyQt6 (requirements-dev.txt) not usable:\n{proc.stderr}"
    missing = json.loads(proc.stdout)
    assert not missing, "not in PyQt6:\n" + "\n".join(missing)


def test_no_pyqt5_only_method_names() -> None:
    offending = [
        f"{module.where(node)}: .{node.attr}()"
        for module in plugin_modules()
        for node in ast.walk(module.tree)
        if isinstance(node, ast.Attribute) and node.attr in PYQT5_METHODS
    ]
    assert not offending, "PyQt6 has exec() and print() only:\n" + "\n".join(offending)


def test_version_dependent_names_are_picked_in_qgis_compat_alone() -> None:
    offending = []
    for module in plugin_modules(compat=False):
        for node in ast.walk(module.tree):
            if isinstance(node, (ast.Attribute, ast.Name)) and "QGIS_VERSION_INT" in {
                getattr(node, "attr", None),
                getattr(node, "id", None),
            }:
                offending.append(f"{module.where(node)}: tests QGIS_VERSION_INT")
            elif isinstance(node, ast.alias) and node.name == "QVariant":
                offending.append(f"{rel(module.path)}: imports QVariant")
        offending += [
            f"{module.where(node)}: a branch for older QGIS or Qt"
            for node, _ in legacy_branches(module.tree)
        ]
    assert not offending, "use processing_provider/qgis_compat.py:\n" + "\n".join(offending)


def compat_module():
    load_plugin_package()
    return importlib.import_module(f"{PLUGIN_PACKAGE}.processing_provider.qgis_compat")


def is_enum_member(value: object) -> bool:
    # Python enums (scoped C++ enums; every enum on PyQt6), or sip's own enum type (PyQt5).
    return isinstance(value, enum.Enum) or type(type(value)).__name__ == "enumtype"


def test_every_enum_member_the_plugin_names_is_scoped_by_its_own_enum() -> None:
    from qgis.core import Qgis

    compat = compat_module()
    offending = []
    for module in plugin_modules(compat=False):
        for node, name, chain in module.chains():
            if name.module == "compat":
                target = compat
            elif name.module in QGIS_MODULES or name.module.startswith(QT_PACKAGE + "."):
                target = importlib.import_module(name.module)
            else:
                continue
            path, parent = [], None
            for part in [name.member, *chain[1:]]:
                if not hasattr(target, part):
                    offending.append(f"{module.where(node)}: {'.'.join(chain)} does not exist")
                    break
                parent, target = target, getattr(target, part)
                path.append(part)
                if not is_enum_member(target):
                    continue
                kind = type(target)
                expected = f"{kind.__qualname__}.{getattr(target, 'name', None) or part}"
                if kind.__qualname__.startswith("QVariant"):
                    scoped, expected = False, f"qgis_compat.FIELD_TYPES[{part!r}]"
                elif name.module == "compat":
                    scoped = True  # qgis_compat's own test checks these
                elif "." in kind.__qualname__:
                    scoped = parent is kind and ".".join(path[:-1]) == kind.__qualname__
                else:
                    scoped = parent is kind and path[-2:] == [kind.__name__, part]
                if not scoped:
                    offending.append(f"{module.where(node)}: {'.'.join(path)} -> {expected}")
                break
    assert not offending, f"unscoped enums on QGIS {Qgis.QGIS_VERSION}:\n" + "\n".join(offending)


def test_qgis_compat_gives_the_running_qgis_own_enums_or_stand_ins_with_their_names() -> None:
    from qgis.core import Qgis

    compat = compat_module()
    for name in compat.__all__:
        if name in {"FIELD_TYPES", "QAction"}:
            continue
        alias = getattr(compat, name)
        if hasattr(Qgis, name):
            assert alias is getattr(Qgis, name), name
        elif type(alias).__name__ not in {"enumtype", "EnumType"}:
            # A stand-in: the new member names, each an enum member of the older QGIS.
            members = {k: v for k, v in vars(alias).items() if not k.startswith("_")}
            assert members, name
            assert all(is_enum_member(value) for value in members.values()), name


def test_qgis_compat_field_types_make_fields_of_those_types() -> None:
    from qgis.core import QgsField

    compat = compat_module()
    # QVariant.Type and QMetaType.Type share these numbers.
    expected = {"Int": 2, "LongLong": 4, "Double": 6, "String": 10}
    assert set(compat.FIELD_TYPES) == set(expected)
    for kind, number in expected.items():
        assert int(QgsField("value", compat.FIELD_TYPES[kind]).type()) == number, kind


def test_qgis_compat_action_is_qt_qaction() -> None:
    compat = compat_module()
    assert compat.QAction.__name__ == "QAction"
    assert compat.QAction.__module__.split(".")[0].startswith("PyQt")
