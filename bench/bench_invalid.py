"""Islands outside the outer ring or across it (invalid input): how long each rule takes to
report the polygon (``invalid="fail"``) or to triangulate it as given (with the repair).

Such an island has no valid bridge, so every vertex of the sequence is tested before it is
reported or joined to its nearest vertex; rule delaunay tries it again in each of its rounds.
Cases: the river of 1,000 islands (29,746 vertices) as it is, with 1 and with 4 squares outside
it, with 5 of its islands moved onto the shell, and with 50 small triangles just outside its
shell. One call each (the slow ones take
seconds), in one process.

Usage: python bench/bench_invalid.py [--rules first,elevation,delaunay]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import shapely
from generate import river_polygon

from bsp_triangulate import triangulate_many

RULES = ("first", "elevation", "delaunay")
MODES = ("fail", "as_given")

Rings = list[np.ndarray]


def squares_outside(rings: Rings, count: int, seed: int) -> list[np.ndarray]:
    """``count`` clockwise 1 m squares at random in the shell's bounding box, each at least
    2 m outside the shell."""
    shell = shapely.Polygon(rings[0]).buffer(2.0)
    (x0, y0), (x1, y1) = rings[0].min(axis=0), rings[0].max(axis=0)
    rng = np.random.default_rng(seed)
    found: list[np.ndarray] = []
    while len(found) < count:
        cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
        square = np.array([(cx, cy), (cx, cy + 1), (cx + 1, cy + 1), (cx + 1, cy)])
        if not shell.intersects(shapely.Polygon(square)):
            found.append(square)
    return found


def moved_onto_shell(rings: Rings, count: int, seed: int) -> Rings:
    """``rings`` with ``count`` islands moved so that each is centred on a shell vertex."""
    rng = np.random.default_rng(seed)
    moved = list(rings)
    for i in rng.choice(np.arange(1, len(rings)), count, replace=False):
        ring = moved[i]
        moved[i] = ring - ring.mean(axis=0) + rings[0][rng.integers(len(rings[0]))]
    return moved


def triangles_just_outside(rings: Rings, count: int) -> list[np.ndarray]:
    """``count`` small clockwise triangles just outside the shell, at evenly spaced vertices
    (along the outward bisector, a fifth of the shorter edge there away, as long), each
    clear of the shell."""
    shell = rings[0]
    outline = shapely.Polygon(shell)
    found: list[np.ndarray] = []
    for i in np.linspace(1, len(shell) - 2, 2 * count).astype(int).tolist():
        before, after = shell[i] - shell[i - 1], shell[i + 1] - shell[i]
        scale = 0.2 * min(np.hypot(*before), np.hypot(*after))
        normal = np.array([before[1], -before[0]]) / np.hypot(*before)
        normal += np.array([after[1], -after[0]]) / np.hypot(*after)
        out = normal / np.hypot(*normal)  # right of a counter-clockwise shell: outside
        side = np.array([-out[1], out[0]])
        tip = shell[i] + out * scale
        far = tip + out * scale
        triangle = np.array([tip, far + side * scale / 2, far - side * scale / 2])
        if not outline.intersects(shapely.Polygon(triangle)):
            found.append(triangle)
    return found[::2][:count]


def cases() -> dict[str, Rings]:
    river = river_polygon(8_000, 1_000)
    return {
        "river, 1,000 islands (valid)": river,
        "the same, 1 square outside": river + squares_outside(river, 1, 1),
        "the same, 4 squares outside": river + squares_outside(river, 4, 2),
        "the same, 5 islands across the shell": moved_onto_shell(river, 5, 3),
        "the same, 50 triangles just outside the shell": river + triangles_just_outside(river, 50),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rules", default=",".join(RULES))
    rules = parser.parse_args().rules.split(",")
    print("| case | " + " | ".join(f"{rule}, {mode}" for rule in rules for mode in MODES) + " |")
    print("| --- |" + " --- |" * (len(rules) * len(MODES)))
    for name, rings in cases().items():
        cells = []
        for rule in rules:
            for mode in MODES:
                start = time.perf_counter()
                result = triangulate_many([rings], rule=rule, invalid=mode, on_error="return")
                seconds = time.perf_counter() - start
                failed = isinstance(result[0], Exception)
                cells.append(f"{seconds:.2f} s" + (" (reported)" if failed else ""))
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
