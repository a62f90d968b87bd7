"""The working tree's engine against a git revision's, on one benchmark case, in alternated rounds.

The revision's ``bsp_triangulate`` is extracted (``git archive``) into a temporary folder
under another package name, so both import side by side. Each round times every side once,
in turn (the order alternates), in its own forked process, best of 2 calls there (one where
it takes over 5 s, as ``common.timed`` does for every benchmark); the report gives each
side's best round and the median of the same-round ratios (working tree over revision), the
figures that carry over on a shared machine whose speed drifts. Before timing, the two
sides' results are compared field by field.

Usage: python bench/ab_revision.py [--base HEAD] [--case stars] [--rule first] [--rounds 6]
Cases: stars, footprints (the core set), mid, radial, wavy, river, water-huge3 (the large set).
"""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable
from io import BytesIO
from pathlib import Path

import numpy as np
from common import ROOT, timed, within

import bsp_triangulate

FIELDS = ("vertices", "triangles", "parent", "depth", "side")


def revision_package(revision: str, folder: Path, name: str) -> object:
    """``bsp_triangulate`` of ``revision``, imported as the package ``name`` from ``folder``."""
    archive = subprocess.run(
        ["git", "archive", "--format=tar", revision, "bsp_triangulate"],
        cwd=ROOT,
        check=True,
        capture_output=True,
    ).stdout
    # the "data" filter where this Python has it (3.12, 3.11.4 on); the files are our own
    safe = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(folder, **safe)
    (folder / "bsp_triangulate").rename(folder / name)
    sys.path.insert(0, str(folder))
    return importlib.import_module(name)


def case_polygons(case: str, count: int | None) -> tuple[list, dict]:
    """The polygons of ``case`` and the keyword arguments the benchmarks call with."""
    if case in ("stars", "footprints"):
        from bench_core import FOOTPRINTS_PER_STAR
        from generate import DEFAULT_COUNT, ensure_stars, footprint_polygons, read_rings

        stars = count or DEFAULT_COUNT
        if case == "stars":
            return read_rings(ensure_stars(stars)[0]), {}
        return footprint_polygons(FOOTPRINTS_PER_STAR * stars), {}
    from bench_large import fixture, with_z
    from generate import mid_size_polygons, radial_polygons, river_polygon, wavy_polygon

    made: dict[str, Callable[[], list]] = {
        "mid": lambda: mid_size_polygons(count or 1_000),
        "radial": lambda: radial_polygons(count or 300),
        "wavy": lambda: [wavy_polygon(count or 100_000, (count or 100_000) // 100)],
        "river": lambda: [river_polygon(8 * (count or 3_000), count or 3_000)],
        "water-huge3": lambda: [fixture("water-huge3")],
    }
    return with_z(made[case]()), {"invalid": "as_given", "plane": "xy"}


def same_results(first: list, second: list) -> bool:
    for a, b in zip(first, second):
        if type(a).__name__ != type(b).__name__:
            return False
        if type(a).__name__ == "Triangulation":
            if not all(np.array_equal(getattr(a, f), getattr(b, f)) for f in FIELDS):
                return False
        elif str(a) != str(b):
            return False
    return len(first) == len(second)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="HEAD", help="git revision to compare with (HEAD)")
    parser.add_argument("--case", default="stars")
    parser.add_argument("--rule", default="first", choices=("first", "elevation", "delaunay"))
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--count", type=int, help="polygons (stars, mid, radial) or size")
    arguments = parser.parse_args()
    polygons, options = case_polygons(arguments.case, arguments.count)
    with tempfile.TemporaryDirectory() as folder:
        base = revision_package(arguments.base, Path(folder), "bsp_triangulate_base")
        sides = {"revision": base, "working tree": bsp_triangulate}
        calls = {
            name: (lambda module=module: module.triangulate_many(
                polygons, rule=arguments.rule, on_error="return", **options
            ))
            for name, module in sides.items()
        }  # fmt: skip
        same = same_results(calls["revision"](), calls["working tree"]())
        seconds: dict[str, list[float]] = {name: [] for name in sides}
        order = list(sides)
        for round_ in range(arguments.rounds):
            for name in order if round_ % 2 == 0 else order[::-1]:
                seconds[name].append(within(lambda n=name: timed(calls[n], 2)[0], 3_600.0))
    base_s, new_s = np.array(seconds["revision"]), np.array(seconds["working tree"])
    print(f"{arguments.case}, rule {arguments.rule}, {arguments.rounds} alternated rounds")
    print(f"same results field by field: {'yes' if same else 'NO'}")
    print(f"revision {arguments.base}: best {base_s.min():.3f} s")
    print(f"working tree: best {new_s.min():.3f} s")
    print(
        f"working tree / revision: best {new_s.min() / base_s.min():.3f}, "
        f"median of same-round ratios {float(np.median(new_s / base_s)):.3f}"
    )


if __name__ == "__main__":
    main()
