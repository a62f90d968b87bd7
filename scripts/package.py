"""Build dist/bsptriangulate-<version>.zip for the QGIS plugin manager and plugins.qgis.org.

The zip holds one folder, ``bsptriangulate/``, with the plugin's run-time files only: no tests,
benchmarks, scripts, docs sources, caches or venv. It is then checked as the plugin repository's
uploader checks a package (``upload_problems``); a zip it would refuse is not written.
Standard library only.

Usage: python3 scripts/package.py [--out DIR]
"""

from __future__ import annotations

import argparse
import configparser
import io
import re
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PLUGIN_FOLDER = "bsptriangulate"
# What the plugin needs at run time, relative to the repository root.
RUNTIME_FILES = ("__init__.py", "plugin.py", "metadata.txt", "LICENSE", "README.md")
RUNTIME_DIRS = ("bsp_triangulate", "processing_provider", "icons", "i18n")
SKIPPED_SUFFIXES = {".pyc", ".pyo", ".ts", ".pro", ".orig", ".rej", ".swp"}

# What plugins.qgis.org's uploader requires of a package (its plugin validator): at most 25 MB;
# one top folder named like a Python package, holding __init__.py, metadata.txt and LICENSE; no
# path outside it, no .pyc, no __pycache__, .git or __MACOSX folder; these metadata keys in
# [general]; an author without slashes; tracker, repository and homepage as absolute URLs.
UPLOAD_MAX_BYTES = 25_000_000
UPLOAD_REQUIRED_METADATA = (
    "name",
    "description",
    "version",
    "qgisMinimumVersion",
    "author",
    "email",
    "about",
    "tracker",
    "repository",
)
UPLOAD_FORBIDDEN_FOLDERS = {"__MACOSX", ".git", "__pycache__"}
# Also refused here, stricter than the uploader: compiled or binary code and hidden files.
COMPILED_SUFFIXES = {".pyc", ".pyo", ".so", ".pyd", ".dll", ".dylib", ".exe"}
QGIS_VERSION = re.compile(r"^\d+\.\d+(\.\d+)?$")
PLUGIN_VERSION = re.compile(r"^\d+(\.\d+)*$")
URL = re.compile(r"^https?://[^/\s]+\.[^/\s]+(/\S*)?$")
EMAIL = re.compile(r"^[^@\s]+@[^@\s]+\.[^@\s]+$")


def plugin_version(root: Path = ROOT) -> str:
    """The version in metadata.txt."""
    parser = configparser.ConfigParser(interpolation=None)
    parser.read(root / "metadata.txt", encoding="utf-8")
    return parser["general"]["version"].strip()


def runtime_files(root: Path = ROOT) -> Iterator[Path]:
    """The plugin's run-time files, sorted, as paths relative to ``root``."""
    for name in RUNTIME_FILES:
        if (root / name).is_file():
            yield Path(name)
    for folder in RUNTIME_DIRS:
        for path in sorted((root / folder).rglob("*")):
            if (
                path.is_file()
                and path.suffix not in SKIPPED_SUFFIXES
                and "__pycache__" not in path.parts
                and not path.name.startswith(".")
            ):
                yield path.relative_to(root)


def build_zip(out_dir: Path, root: Path = ROOT) -> Path:
    """Write ``bsptriangulate-<version>.zip`` into ``out_dir`` and return its path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{PLUGIN_FOLDER}-{plugin_version(root)}.zip"
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for relative in runtime_files(root):
            archive.write(root / relative, f"{PLUGIN_FOLDER}/{relative.as_posix()}")
    return target


def upload_problems(package: Path) -> list[str]:
    """Why plugins.qgis.org's uploader would refuse ``package`` (empty when it would take it),
    as far as can be told offline: whether the URLs answer is not checked."""
    if package.stat().st_size > UPLOAD_MAX_BYTES:
        return [f"{package.stat().st_size} bytes, over {UPLOAD_MAX_BYTES}"]
    try:
        archive = zipfile.ZipFile(package)
    except zipfile.BadZipFile:
        return ["not a zip file"]
    with archive:
        names = archive.namelist()
        problems = [f"{name}: path outside the plugin" for name in names if ".." in name]
        problems += [f"{name}: absolute path" for name in names if name.startswith("/")]
        problems += [f"{name}: compiled file" for name in names if ".pyc" in name]
        for name in names:
            parts = name.split("/")
            if UPLOAD_FORBIDDEN_FOLDERS & set(parts):
                problems.append(f"{name}: forbidden folder")
            if any(part.startswith(".") for part in parts):
                problems.append(f"{name}: hidden file")
            if Path(name).suffix in COMPILED_SUFFIXES - {".pyc"}:
                problems.append(f"{name}: compiled file")
        if archive.testzip() is not None:
            problems.append("bad CRC")
        folders = {name.split("/")[0] for name in names if "/" in name}
        if len(folders) != 1 or len(folders) != len({name.split("/")[0] for name in names}):
            return [*problems, f"not one top folder: {sorted(folders)}"]
        folder = folders.pop()
        if not re.match(r"^[a-z_][a-z0-9_]*$", folder):
            problems.append(f"{folder}: top folder not a lowercase Python package name")
        for required in ("__init__.py", "metadata.txt", "LICENSE"):
            if f"{folder}/{required}" not in names:
                problems.append(f"no {required}")
        if f"{folder}/metadata.txt" in names:
            problems += _metadata_problems(archive, folder)
    return problems


def _metadata_problems(archive: zipfile.ZipFile, folder: str) -> list[str]:
    # Read as the uploader reads it: interpolation on, keys case-sensitive.
    parser = configparser.ConfigParser()
    parser.optionxform = str  # type: ignore[assignment]
    try:
        parser.read_file(io.StringIO(archive.read(f"{folder}/metadata.txt").decode("utf-8")))
        general = dict(parser.items("general"))
    except (configparser.Error, UnicodeDecodeError, ValueError) as error:
        return [f"metadata.txt: {error}"]
    problems = [
        f"metadata.txt: no {key}" for key in UPLOAD_REQUIRED_METADATA if not general.get(key)
    ]
    checks = {
        "version": PLUGIN_VERSION,
        "qgisMinimumVersion": QGIS_VERSION,
        "qgisMaximumVersion": QGIS_VERSION,
        "email": EMAIL,
        "tracker": URL,
        "repository": URL,
        "homepage": URL,
    }
    for key, pattern in checks.items():
        if key in general and not pattern.match(general[key].strip()):
            problems.append(f"metadata.txt: {key}={general[key]!r} malformed")
    if "/" in general.get("author", ""):
        problems.append("metadata.txt: author has a slash")
    for key in ("experimental", "deprecated", "server", "supportsQt6"):
        if key in general and general[key].strip() not in {"True", "False"}:
            problems.append(f"metadata.txt: {key}={general[key]!r} not True or False")
    icon = general.get("icon", "").removeprefix("./")
    if not icon or f"{folder}/{icon}" not in archive.namelist():
        problems.append(f"metadata.txt: icon {icon!r} not in the zip")
    return problems


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "dist", help="output folder")
    args = parser.parse_args()
    target = build_zip(args.out)
    problems = upload_problems(target)
    if problems:
        target.unlink()
        sys.exit("the plugin repository would refuse the zip:\n" + "\n".join(problems))
    print(target)


if __name__ == "__main__":
    main()
