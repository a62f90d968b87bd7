"""The engine against a compiled constrained Delaunay triangulator on the same rings and points.

Given polygons (rings with z) and interior points per polygon, times
``triangulate_many(polygons, points=..., rule="delaunay")`` against Shewchuk's Triangle
through the ``triangle`` package (PyPI, benchmark-only): one call per polygon with the 'p'
switch, the ring edges as segments and a point inside each island marking it as a hole; the
input arrays are built beforehand and not timed. Each side runs in its own forked child, in
alternated rounds, and keeps its best round. The target of the issue "Terrain-true meshes":
ours at most 10 times Triangle's time.

On its own it takes the Swellendam farms, refines them at 5 m (rule "delaunay") and compares
on the final rings and points: ``python bench/bench_cdt.py [--quick] [--tolerance 5]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from collections.abc import Callable, Sequence

import numpy as np
import shapely
from common import BudgetExceededError, Row, markdown_table, within

from bsp_triangulate import triangulate_many

TARGET = 10.0  # ours at most this many times the compiled triangulator's time
Rings = Sequence[np.ndarray]


def triangle_inputs(polygons: Sequence[Rings], points: Sequence[np.ndarray]) -> list[dict]:
    """Triangle's PSLG per polygon: vertices (rings, then points), ring segments, holes."""
    inputs = []
    for rings, inner in zip(polygons, points):
        xy = [np.asarray(ring, np.float64)[:, :2] for ring in rings]
        starts = np.cumsum([0] + [len(ring) for ring in xy])
        segments = np.concatenate(
            [
                np.column_stack([np.arange(a, b), np.roll(np.arange(a, b), -1)])
                for a, b in zip(starts[:-1], starts[1:])
            ]
        )
        vertices = np.vstack([*xy, np.asarray(inner, np.float64).reshape(-1, 3)[:, :2]])
        data = {"vertices": vertices, "segments": segments.astype(np.int32)}
        if len(xy) > 1:
            islands = shapely.polygons([shapely.linearrings(ring) for ring in xy[1:]])
            holes = shapely.get_coordinates(shapely.point_on_surface(islands))
            data["holes"] = holes
        inputs.append(data)
    return inputs


def time_triangle(inputs: list[dict]) -> tuple[float, int]:
    """Seconds for Triangle on every polygon, and the triangles it made."""
    import triangle

    start = time.perf_counter()
    results = [triangle.triangulate(data, "pQ") for data in inputs]
    seconds = time.perf_counter() - start
    return seconds, sum(len(result.get("triangles", ())) for result in results)


def time_ours(polygons: Sequence[Rings], points: Sequence[np.ndarray]) -> tuple[float, int]:
    """Seconds for triangulate_many with the points (rule "delaunay"), and its triangles."""
    start = time.perf_counter()
    results = triangulate_many(
        polygons, points=points, rule="delaunay", plane="xy", on_error="return"
    )
    seconds = time.perf_counter() - start
    return seconds, sum(len(getattr(result, "triangles", ())) for result in results)


def compare(
    polygons: Sequence[Rings],
    points: Sequence[np.ndarray],
    budget: float | None,
    rounds: int = 5,
) -> tuple[str, list[Row]]:
    """A Markdown table and rows: both times (best of ``rounds``), triangles, the ratio."""
    vertices = sum(len(ring) for rings in polygons for ring in rings)
    given = sum(len(inner) for inner in points)
    size = f"{len(polygons):,} polygons, {vertices:,} ring vertices, {given:,} points"
    if importlib.util.find_spec("triangle") is None:
        message = "skipped: the triangle package is not installed (pip install triangle)"
        return message, [Row(size, "ours / triangle time", message)]
    inputs = triangle_inputs(polygons, points)
    sides: dict[str, Callable[[], tuple[float, int]]] = {
        'ours, triangulate_many(points=..., rule="delaunay")': lambda: time_ours(polygons, points),
        "triangle (Shewchuk's Triangle, 'pQ', one call per polygon)": lambda: time_triangle(inputs),
    }
    best: dict[str, tuple[float, int] | str] = {}
    for _ in range(rounds):
        for name, side in sides.items():
            if isinstance(best.get(name), str):
                continue
            try:
                seconds, triangles = within(side, budget)
            except BudgetExceededError:
                best[name] = f"> {budget:.0f} s (stopped)"
                continue
            except RuntimeError as error:
                best[name] = f"failed: {error}"
                continue
            previous = best.get(name)
            if previous is None or seconds < previous[0]:  # type: ignore[index]
                best[name] = (seconds, triangles)
    rows, table = [], []
    for name, value in best.items():
        if isinstance(value, str):
            rows.append(Row(size, f"{name}: time", value))
            table.append((name, value, ""))
        else:
            rows.append(Row(size, f"{name}: time", value[0], "s", f"{value[1]:,} triangles"))
            table.append((name, value[0], f"{value[1]:,}"))
    ours, theirs = (best.get(name) for name in sides)
    if isinstance(ours, tuple) and isinstance(theirs, tuple):
        ratio = ours[0] / theirs[0]
        verdict = "met" if ratio <= TARGET else "missed"
        note = f"target at most {TARGET:g}x: {verdict}; best of {rounds}"
        rows.append(Row(size, "ours / triangle time", ratio, "x", note))
        table.append(("ours / triangle time", f"{ratio:.1f}x ({note})", ""))
    text = f"{size}\n\n" + markdown_table(["triangulation", "time (s)", "triangles"], table)
    return text, rows


def main() -> None:
    from bench_fidelity import DEM_PATH, FARMS, QUICK_FARMS, Dem, polygon_rings, read_polygons

    from bsp_triangulate.terrain.refine import refine_many

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"first {QUICK_FARMS} farms only")
    parser.add_argument("--tolerance", type=float, default=5.0, help="metres (default 5)")
    parser.add_argument("--budget", type=float, default=1_800.0, help="seconds per call at most")
    arguments = parser.parse_args()
    dem = Dem.read(DEM_PATH)
    farms = read_polygons(FARMS, limit=QUICK_FARMS if arguments.quick else None)
    polygons = [polygon_rings(farm, dem, None) for farm in farms]
    grid = dem.grid
    results = refine_many(
        polygons,
        [grid] * len(polygons),
        arguments.tolerance,
        1_000_000,
        engine=triangulate_many,
        rule="delaunay",
        plane="xy",
    )
    points = [result.points for result in results]
    print(compare(polygons, points, arguments.budget, 1 if arguments.quick else 5)[0])


if __name__ == "__main__":
    main()
