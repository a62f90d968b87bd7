"""Many polygons through the one-polygon builder, side by side.

Each polygon's tree runs as steps (``one_polygon.triangulate_steps``) up to the sub-polygons
it hands to the lock-step builder; those of a chunk of polygons are then built in shared
lock-step calls (``subtrees.built_if_worth``), whose rounds cost about as much for many
polygons as for one, and each tree finishes with its own. Every result is the one the polygon
gets alone.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence

import numpy as np

from ..triangulation import Triangulation, TriangulationError
from .one_polygon import Steps, triangulate_steps
from .subtrees import REFINE, Refine, SubtreeRequest, Subtrees, built_if_worth, worth_refining

# points per chunk of polygons run side by side (every tree of a chunk is held until its
# subtrees are built), and polygons per chunk
CHUNK_POINTS = 200_000
CHUNK_POLYGONS = 512

Result = Triangulation | TriangulationError


def engine_results(
    numbers: Sequence[int],
    rings_of: Callable[[int], Sequence[object]],
    options: dict[str, object],
    started: Callable[[], None] | None = None,
    alive: Callable[[], None] | None = None,
    tick: Callable[[float], None] | None = None,
) -> Iterator[tuple[int, Result]]:
    """(number, result) of the polygons ``numbers`` (rings ``rings_of(number)``), in that
    order: ``one_polygon._triangulate`` with the keyword ``options``, or the
    TriangulationError it raises. Run in chunks of up to ``CHUNK_POINTS`` points;
    ``started`` is called as each polygon starts, ``alive`` now and then as they go (their
    steps interleave, so no share is told), and ``tick`` with the share of its tree built
    where a chunk holds one polygon (both may raise to stop)."""
    chunk: list[int] = []
    size = 0
    for number in numbers:
        points = _point_count(rings_of(number))
        if chunk and (size + points > CHUNK_POINTS or len(chunk) >= CHUNK_POLYGONS):
            yield from _chunk_results(chunk, rings_of, options, started, alive, tick)
            chunk, size = [], 0
        chunk.append(number)
        size += points
    if chunk:
        yield from _chunk_results(chunk, rings_of, options, started, alive, tick)


def _chunk_results(
    chunk: list[int],
    rings_of: Callable[[int], Sequence[object]],
    options: dict[str, object],
    started: Callable[[], None] | None,
    alive: Callable[[], None] | None,
    tick: Callable[[float], None] | None,
) -> Iterator[tuple[int, Result]]:
    if alive is not None:
        # several polygons' steps interleave: their trees' ticks tell no share
        if len(chunk) > 1 or tick is None:
            tick = lambda _share: alive()  # noqa: E731
        options = {**options, "alive": alive, "tick": tick}
    steps = [triangulate_steps(rings_of(number), **options) for number in chunk]
    # the whole chunk under the engine's floating-point settings (not across the yields)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        results = drive_many(steps, started, alive)
    yield from zip(chunk, results)


def drive_many(
    all_steps: list[Steps],
    started: Callable[[], None] | None = None,
    alive: Callable[[], None] | None = None,
) -> list[Result]:
    """The result of each polygon's ``steps`` (or the TriangulationError it raised), the
    lock-step requests of all of them built together, those of one rule at a time (split
    further first where that pays for all of them, ``subtrees.worth_refining``; ``alive``
    called every round)."""
    results: list[Result | None] = [None] * len(all_steps)
    waiting: list[tuple[int, SubtreeRequest]] = []
    refined: set[int] = set()

    def advance(k: int, sent: Subtrees | Refine | None, first: bool = False) -> None:
        try:
            request = next(all_steps[k]) if first else all_steps[k].send(sent)
        except StopIteration as done:
            results[k] = done.value
        except TriangulationError as error:
            results[k] = error
        else:
            waiting.append((k, request))

    for k in range(len(all_steps)):
        if started is not None:
            started()
        advance(k, None, first=True)
    while waiting:
        asked, waiting = waiting, []
        for rule in dict.fromkeys(request[6] for _, request in asked):
            group = [(k, request) for k, request in asked if request[6] == rule]
            if not refined.intersection(k for k, _ in group) and worth_refining(
                [request for _, request in group]
            ):
                for k, _ in group:
                    refined.add(k)  # once: a tree may keep its plan (invalid input)
                    advance(k, REFINE)  # asked again, in the next pass
                continue
            # the rounds are shared: worth it for all the sub-polygons together
            built = built_if_worth([request for _, request in group], alive)
            for (k, _), subtrees in zip(group, built):
                advance(k, subtrees)
    return results  # type: ignore[return-value]


def runs_alone(rings: Sequence[object]) -> bool:
    """The polygon fills a chunk by itself (its caller may as well run it alone, with its
    progress reported as it goes)."""
    return _point_count(rings) >= CHUNK_POINTS


def _point_count(rings: Sequence[object]) -> int:
    """The rings' points (a polygon whose size is not known counts as a whole chunk)."""
    try:
        return sum(len(ring) for ring in rings)
    except TypeError:
        return CHUNK_POINTS
