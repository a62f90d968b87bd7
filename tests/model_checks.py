"""Checks of written 3D models shared by the core and QGIS tests: the Khronos glTF Validator
(npm package ``gltf-validator``, installed on first use into build/node), trimesh read-back,
and the closed-solid edge check.

Import the fixture into a test module with ``from tests.model_checks import gltf_validator``.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import ROOT

NODE_PREFIX = ROOT / "build" / "node"
VALIDATOR_PACKAGE = "gltf-validator@2.0.0-dev.3.10"
VALIDATE_SCRIPT = Path(__file__).resolve().parent / "tools" / "validate_gltf.js"
NPM_TIMEOUT_S = 300


def _install_validator() -> str | None:
    """Install the validator into build/node once (idempotent); the reason when it cannot."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        return "node and npm are needed for the Khronos glTF Validator (npm gltf-validator)"
    if (NODE_PREFIX / "node_modules" / "gltf-validator" / "package.json").is_file():
        return None
    NODE_PREFIX.mkdir(parents=True, exist_ok=True)
    try:
        proc = subprocess.run(
            [npm, "install", "--no-save", "--prefix", str(NODE_PREFIX), VALIDATOR_PACKAGE],
            capture_output=True,
            text=True,
            timeout=NPM_TIMEOUT_S,
            stdin=subprocess.DEVNULL,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return f"npm install {VALIDATOR_PACKAGE} failed: {error}"
    if proc.returncode != 0:
        return f"npm install {VALIDATOR_PACKAGE} failed: {proc.stderr[-500:]}"
    return None


Validate = Callable[[Sequence[Path]], list[dict]]


@pytest.fixture(scope="session")
def gltf_validator() -> Validate:
    """``validate(paths)``: one report (``errors``, ``warnings``, ``messages``) per file."""
    reason = _install_validator()
    if reason is not None:
        pytest.skip(reason)

    def validate(paths: Sequence[Path]) -> list[dict]:
        proc = subprocess.run(
            ["node", str(VALIDATE_SCRIPT), str(NODE_PREFIX / "node_modules"), *map(str, paths)],
            capture_output=True,
            text=True,
            timeout=NPM_TIMEOUT_S,
            stdin=subprocess.DEVNULL,
        )
        assert proc.returncode == 0, proc.stderr
        reports = [json.loads(line) for line in proc.stdout.splitlines() if line.strip()]
        assert len(reports) == len(paths), proc.stdout
        return reports

    return validate


def assert_valid_gltf(validate: Validate, *paths: Path) -> None:
    for report in validate(paths):
        assert report["errors"] == 0, report


def trimesh_read(path: Path):
    """The model as one trimesh mesh (node transforms applied), vertices as written."""
    import trimesh

    loaded = trimesh.load(str(path), process=False)
    if isinstance(loaded, trimesh.Scene):
        return loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded.dump(True)
    return loaded


def directed_edges(triangles: np.ndarray) -> np.ndarray:
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    return np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])


def closed_and_oriented(triangles: np.ndarray) -> bool:
    """Every edge used exactly twice, once in each direction (by vertex index)."""
    edges = directed_edges(triangles)
    if not len(edges):
        return False
    # each directed edge once, and its reverse present
    keys = np.unique(edges, axis=0, return_counts=True)
    if (keys[1] != 1).any():
        return False
    forward = {tuple(edge) for edge in keys[0].tolist()}
    return all((b, a) in forward for a, b in forward)


def signed_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Volume enclosed by outward-oriented triangles (divergence theorem), about the centroid
    of the vertices for accuracy."""
    vertices = np.asarray(vertices, dtype=np.float64)
    corners = vertices[np.asarray(triangles)] - vertices.mean(axis=0)
    return float(
        np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum() / 6.0
    )


CITYJSON_SCHEMAS = ROOT.parent / "shared" / "data" / "cityjson" / "schemas"


def cityjson_validator():
    """A draft-07 validator of CityJSON 2.0 documents with the official schemas, their
    ``$ref``s resolved from the shared folder (never fetched)."""
    jsonschema = pytest.importorskip("jsonschema")
    if not (CITYJSON_SCHEMAS / "cityjson.schema.json").is_file():
        pytest.skip(f"the CityJSON schemas are not at {CITYJSON_SCHEMAS}")
    store = {}
    for path in CITYJSON_SCHEMAS.glob("*.schema.json"):
        if ".min." in path.name:
            continue
        schema = json.loads(path.read_text(encoding="utf-8"))
        store[schema["$id"]] = schema
    root = json.loads((CITYJSON_SCHEMAS / "cityjson.schema.json").read_text(encoding="utf-8"))
    resolver = jsonschema.RefResolver(root["$id"], root, store=store)
    return jsonschema.Draft7Validator(root, resolver=resolver)


def cityjson_solids(document: dict) -> list[tuple[str, list[list[int]]]]:
    """(city object id, rings of one shell) for every shell of every Solid and MultiSolid."""
    shells = []
    for name, city_object in document["CityObjects"].items():
        for geometry in city_object.get("geometry", []):
            solids = {"Solid": [geometry["boundaries"]], "MultiSolid": geometry["boundaries"]}
            for solid in solids.get(geometry["type"], []):
                for shell in solid:
                    rings = [ring for surface in shell for ring in surface]
                    shells.append((name, rings))
    return shells


def ring_edges_closed(rings: list[list[int]]) -> bool:
    """Every edge of the rings used exactly twice, once each way."""
    edges = [(ring[i], ring[(i + 1) % len(ring)]) for ring in rings for i in range(len(ring))]
    return (
        len(edges) > 0
        and len(set(edges)) == len(edges)
        and all((b, a) in set(edges) for a, b in edges)
    )


def cityjson_errors(document: dict, whole_up_to: int = 200, sample: int = 20) -> list[str]:
    """Schema errors of a CityJSON document. Up to ``whole_up_to`` city objects the whole
    document is validated as it is; a larger one (the schema tries every city object against
    all 40-odd object types: 11 minutes for Swellendam's 4,708 buildings) is validated with
    its first ``sample`` objects, and every object against the schema of its own type, once
    per ``_schema_shape`` (objects of the same shape get the same errors)."""
    validator = cityjson_validator()
    objects = document["CityObjects"]
    if len(objects) <= whole_up_to:
        return [str(error) for error in validator.iter_errors(document)]
    head = dict(document)
    head["CityObjects"] = dict(list(objects.items())[:sample])
    errors = [str(error) for error in validator.iter_errors(head)]
    by_type = {}
    shapes_valid: dict[str, bool] = {}
    assert _shapes_validate_alike(), "the CityJSON schemas now tell objects of one shape apart"
    base = validator.schema["$id"].rsplit("/", 1)[0]
    for name, city_object in objects.items():
        kind = city_object.get("type", "")
        if kind not in by_type:
            by_type[kind] = type(validator)(
                {"$ref": f"{base}/cityobjects.schema.json#/{kind}"}, resolver=validator.resolver
            )
        shape = _schema_shape(city_object)
        key = json.dumps(shape, sort_keys=True)
        if key not in shapes_valid:
            shapes_valid[key] = by_type[kind].is_valid(shape)
        if not shapes_valid[key]:
            errors += [f"{name}: {error}" for error in by_type[kind].iter_errors(city_object)]
    return errors


def _shapes_validate_alike() -> bool:
    """Whether the CityJSON schemas constrain numbers by JSON type only (no bounds, no number
    in an enum or const, no uniqueItems), and a city object's attributes (``"type": "object"``),
    parents and children (strings) by type only: then an object and its ``_schema_shape`` get
    the same verdict."""
    found = []

    def walk(node: object) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if key in _VALUE_KEYWORDS:
                    found.append(key)
                elif key in ("enum", "const"):
                    values = value if key == "enum" and isinstance(value, list) else [value]
                    found.extend(key for v in values if not isinstance(v, str))
                walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)

    for path in CITYJSON_SCHEMAS.glob("*.schema.json"):
        if ".min." not in path.name:
            walk(json.loads(path.read_text(encoding="utf-8")))
    common = json.loads((CITYJSON_SCHEMAS / "cityobjects.schema.json").read_text(encoding="utf-8"))
    common = common["_AbstractCityObject"]["properties"]
    return (
        not found
        and common["attributes"] == {"type": "object"}
        and all(common[k]["items"] == {"type": "string"} for k in ("parents", "children"))
    )


_VALUE_KEYWORDS = ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum", "multipleOf")
_VALUE_KEYWORDS += ("uniqueItems", "patternProperties", "propertyNames", "dependencies")


def _schema_shape(value: object, key: str = "") -> object:
    """``value`` with what the CityJSON schemas cannot tell apart made equal: every integer 0,
    every float 0.0 when integral (an integer to JSON Schema) else 0.5, ``attributes`` an
    empty object when an object, the ids in ``parents`` and ``children`` empty strings.
    Arrays keep their lengths and nesting, other strings (types, LoDs, keys) stay."""
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, int):
        return 0
    if isinstance(value, float):
        return 0.0 if value.is_integer() else 0.5
    if isinstance(value, str):
        return "" if key in ("parents", "children") else value
    if isinstance(value, list):
        return [_schema_shape(item, key) for item in value]
    if isinstance(value, dict):
        if key == "attributes":
            return {}
        return {k: _schema_shape(v, k) for k, v in value.items()}
    return value
