"""Build dist/bsptriangulate-<version>.zip for the QGIS plugin manager.

The zip holds one folder, ``bsptriangulate/``, with the plugin's run-time files only: no tests,
benchmarks, scripts, docs sources, caches or venv. Standard library only.

Usage: python3 scripts/package.py [--out DIR]
"""

from __future__ import annotations

import argparse
import configparser
import zipfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PLUGIN_FOLDER = "bsptriangulate"
# What the plugin needs at run time, relative to the repository root.
RUNTIME_FILES = ("__init__.py", "plugin.py", "metadata.txt", "LICENSE", "README.md")
RUNTIME_DIRS = ("bsp_triangulate", "processing_provider", "icons", "i18n")
SKIPPED_SUFFIXES = {".pyc", ".pyo", ".ts", ".pro", ".orig", ".rej", ".swp"}


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "dist", help="output folder")
    args = parser.parse_args()
    print(build_zip(args.out))


if __name__ == "__main__":
    main()
