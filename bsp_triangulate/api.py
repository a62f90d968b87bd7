"""The public entry points: one polygon, many polygons, packed polygons.

Many polygons go to the lock-step batch builder (:mod:`.tree.batch`) where it decides them
exactly; the rest, and every single polygon, to the one-polygon builder
(:mod:`.tree.one_polygon`). Both give the same triangles (``docs/architecture.md``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from .geometry.rings import PLANES, normalise_rings
from .packed import PackedPolygons, PackedTriangulations, Piece, assemble
from .rules import get_rule
from .tree.engine_many import engine_results, runs_alone
from .tree.one_polygon import _as_given, _triangulate
from .tree.points_batch import InsertedMesh, insert_points
from .tree.points_trees import trees_of_inserted, trees_of_known
from .tree.rough_rings import rough_ring_meshes
from .triangulation import Triangulation, TriangulationError


def triangulate(
    rings: Sequence[object],
    *,
    points: object = None,
    rule: str = "first",
    planar_tolerance: float = 0.0,
    invalid: str = "fail",
    plane: str = "auto",
    mesh: object = None,
) -> Triangulation:
    """Triangulate one polygon given as ``[outer ring, island, ...]`` (points (x, y[, z])).

    Degenerate input (zero area, fewer than 3 distinct points, or an area that is zero to
    within double rounding) gives an empty result. A polygon that has no correct triangle on
    some base (a self-intersecting ring, crossing rings) raises :class:`TriangulationError`
    naming the ring with ``invalid="fail"``. With ``invalid="as_given"`` it is triangulated
    anyway, as earcut does with such input: where no correct triangle exists the apex is
    chosen so that the triangles' areas still add up to the polygon's (zero-area triangles
    drop pinches and zero-width spikes; triangles may overlap); where crossing rings make that
    impossible, the polygon is repaired (shapely's make_valid) and its valid parts are
    triangulated, the crossing points becoming vertices.

    ``rule``: the apex rule (``rules.RULES``): "first" (the paper's), "elevation" (paper
    §4.1) or "delaunay" (the constrained Delaunay triangulation, docs/algorithm.md section
    5a), each available in both builders.

    ``plane``: "auto" (default) works in XY unless the outer ring is a steep face (a wall:
    its plane is then used), which is right when x, y and z share one unit; "xy" always
    works in XY, for footprints draped on terrain and for z in another unit than x and y
    (degrees). Every result is checked: its triangles' absolute areas in the working plane
    add up to the polygon's area (with ``invalid="fail"``), or the polygon fails.

    ``points``: None or interior points, an (m, 2) or (m, 3) array of (x, y[, z]) in the
    rings' coordinates (z = 0 where absent), classified in the working plane. Each point
    strictly inside the polygon becomes a vertex (one-point island joined by a bridge); the
    result's ``vertices`` are the ring vertices followed by the used points in the given
    order, and ``point_ids`` gives each given point's row there, or -1 for a point outside
    the polygon, on its boundary or repeating an earlier point. Each used point adds two
    triangles.

    ``mesh``: under rule "delaunay" with points, the result's triangles if already known
    (``terrain.refine.Refinement.mesh``: (t, 3) rows of the result's vertices, any order,
    counter-clockwise): checked (orientation, edges, locally Delaunay, the tree and the
    area) and then used instead of inserting the points again; ignored where a check fails.
    The result is the same with or without it.
    """
    _check_plane(plane)
    # overflow in float filters only routes values to the exact path
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        return _triangulate(
            rings,
            rule=rule,
            planar_tolerance=planar_tolerance,
            invalid=invalid,
            plane=plane,
            points=points,
            mesh=mesh,
        )


def triangulate_many(
    polygons: Sequence[Sequence[object]],
    *,
    rule: str = "first",
    planar_tolerance: float = 0.0,
    on_error: str = "raise",
    invalid: str = "fail",
    proven: Sequence[bool] | None = None,
    plane: str = "auto",
    points: Sequence[object] | None = None,
    meshes: Sequence[object] | None = None,
) -> list:
    """Triangulate many polygons; results in input order, equal to :func:`triangulate`'s.

    Small polygons go through the vectorised batch path (``batch.py``), the rest through the
    engine one by one. With ``on_error="return"`` a polygon that fails gets its
    ``TriangulationError`` in its slot instead of stopping the batch. ``proven``: per
    polygon, True where ``validity.proven_valid`` has proven it valid (it spares the batch
    path its own search for touching rings). ``points``: None or, per polygon, its interior
    points (see :func:`triangulate`) or None; ``meshes``: None or, per polygon, its ``mesh``
    (see :func:`triangulate`) or None.
    """
    polygons = list(polygons)
    _check_many_options(rule, invalid, on_error, proven, len(polygons))
    _check_plane(plane)
    if points is not None and len(points) != len(polygons):
        raise ValueError(f"points has {len(points)} entries for {len(polygons)} polygons")
    # polygons with interior points go to the one-polygon builder
    plain = [i for i in range(len(polygons)) if points is None or _point_count(points[i]) == 0]
    results: list = [None] * len(polygons)
    at_once = points is not None and _at_once_wanted(rule, planar_tolerance, invalid)
    taken = set(plain)
    wanted = (
        [
            i
            for i in range(len(polygons))
            if i not in taken and (meshes is None or not _mesh_given(meshes[i]))
        ]
        if at_once
        else []
    )
    from .tree.batch import triangulate_batch

    wanted_rings: list[Triangulation | None] | None = None
    if planar_tolerance <= 0 and (len(plain) > 1 or wanted):
        # many small polygons in lock-step, those with points for their rings alone (one
        # call: its rounds serve both); it leaves (None) what it does not decide exactly
        batch = [polygons[i] for i in plain + wanted]
        flags = None if proven is None else [proven[i] for i in plain] + [False] * len(wanted)
        try:
            decided = list(triangulate_batch(batch, rule, proven=flags, plane=plane))
            wanted_rings = decided[len(plain) :]
        except (ArithmeticError, ValueError, TypeError):
            # malformed or non-finite input broke the lock-step path: batch only the polygons
            # that normalise, the engine names the ring of the others
            decided = (
                _batch_well_formed(batch[: len(plain)], rule, triangulate_batch, plane)
                if len(plain) > 1
                else [None] * len(plain)
            )
        for index, done in zip(plain, decided):
            results[index] = done
    ring_meshes: dict[int, Triangulation | None] = {}
    inserted: dict[int, InsertedMesh | None] = {}
    if at_once:
        trees, ring_meshes, inserted = _points_at_once(
            wanted,
            [polygons[i] for i in wanted],
            [points[i] for i in wanted],
            lambda: (
                wanted_rings
                if wanted_rings is not None
                else triangulate_batch([polygons[i] for i in wanted], rule, plane=plane)
            ),
            plane,
        )
        for index, tree in trees.items():
            results[index] = tree
        if meshes is not None:
            known = [i for i in range(len(polygons)) if i not in taken and _mesh_given(meshes[i])]
            for index, tree in _known_at_once(
                known,
                [polygons[i] for i in known],
                [points[i] for i in known],
                [meshes[i] for i in known],
                plane,
            ).items():
                results[index] = tree
    if planar_tolerance <= 0:
        # the small polygons the batch path left (touching rings, ...): the engine's
        # sequences, their trees in lock-step
        left = [i for i in plain if results[i] is None]
        prepared = _prepared_at_once(left, polygons.__getitem__, rule, invalid, plane)
        for index, done in prepared.items():
            results[index] = done
    left = [
        index
        for index, done in enumerate(results)
        if not (isinstance(done, Triangulation) or (done is not None and invalid == "fail"))
    ]
    # the polygons the one-polygon builder takes alone (points, meshes) and the others,
    # whose trees run side by side
    alone = {
        index
        for index in left
        if (points is not None and _point_count(points[index]))
        or (meshes is not None and _mesh_given(meshes[index]))
        or ring_meshes.get(index) is not None
        or inserted.get(index) is not None
    }
    options = {
        "rule": rule,
        "planar_tolerance": planar_tolerance,
        "invalid": invalid,
        "plane": plane,
    }
    # in the order of ``left``, as the loop below takes them
    side_by_side = engine_results(
        [index for index in left if index not in alone], polygons.__getitem__, options
    )
    for index, rings in enumerate(polygons):
        done = results[index]
        if isinstance(done, Triangulation) or (done is not None and invalid == "fail"):
            if isinstance(done, TriangulationError) and on_error == "raise":
                raise done
            continue
        if index not in alone:
            _, done = next(side_by_side)
            if isinstance(done, TriangulationError) and on_error == "raise":
                raise done
            results[index] = done
            continue
        results[index] = _engine_result(
            rings,
            rule,
            planar_tolerance,
            invalid,
            on_error,
            plane,
            points=None if points is None else points[index],
            mesh=None if meshes is None else meshes[index],
            ring_mesh=ring_meshes.get(index),
            inserted_mesh=inserted.get(index),
        )
    return results


def _points_at_once(
    index: Sequence[int],
    polygons: list[Sequence[object]],
    points: list[object],
    triangulate_rings: Callable[[], list[Triangulation | None]],
    plane: str,
) -> tuple[
    dict[int, Triangulation], dict[int, Triangulation | None], dict[int, InsertedMesh | None]
]:
    """Rule delaunay with points for the polygons numbered ``index`` (their rings and points):
    the trees read off at once (``points_trees.trees_of_inserted``) where every check
    passes; for the others the rings' triangulations from the batch path
    (``triangulate_rings``, None where it leaves a polygon to the engine) and every point
    inserted into them (``points_batch.insert_points``), per polygon number; none where the
    batch path or the insertion cannot take the input (the one-polygon builder then checks
    it)."""
    if not len(index):
        return {}, {}, {}
    try:
        found = triangulate_rings()
    except (ArithmeticError, ValueError, TypeError):
        return {}, {}, {}
    rough = rough_ring_meshes(polygons, found, plane)
    inserted: list[InsertedMesh | None] = [None] * len(index)
    trees: list[Triangulation | None] = [None] * len(index)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        try:
            inserted = insert_points(polygons, found, points)
            trees = trees_of_inserted(polygons, found, points, inserted, plane, rough)
        except (ArithmeticError, ValueError, TypeError, IndexError):
            trees = [None] * len(index)
    done = {number: tree for number, tree in zip(index, trees) if tree is not None}
    return done, dict(zip(index, found)), dict(zip(index, inserted))


def _mesh_given(mesh: object) -> bool:
    """A polygon's ``mesh`` holds triangles (None or an empty one: no mesh, as packed counts
    of 0 are)."""
    if mesh is None:
        return False
    try:
        return len(mesh) > 0  # type: ignore[arg-type]
    except TypeError:
        return True  # not a sequence: the one-polygon builder says what is wrong


def _known_at_once(
    index: Sequence[int],
    polygons: list[Sequence[object]],
    points: list[object],
    meshes: list[object],
    plane: str,
) -> dict[int, Triangulation]:
    """Rule delaunay with points and known meshes for the polygons numbered ``index``: the
    trees read off their meshes at once (``points_trees.trees_of_known``) where every check
    passes, per polygon number (the one-polygon builder takes the others)."""
    if not len(index):
        return {}
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        try:
            trees = trees_of_known(polygons, points, meshes, plane)
        except (ArithmeticError, ValueError, TypeError, IndexError):
            return {}
    return {number: tree for number, tree in zip(index, trees) if tree is not None}


def _at_once_wanted(rule: str, planar_tolerance: float, invalid: str) -> bool:
    """Whether polygons with points take their rings' triangulation from the batch path and
    their points inserted all at once: rule delaunay by insertion (docs/algorithm.md,
    section 5b)."""
    return rule == "delaunay" and planar_tolerance <= 0 and not _as_given(invalid)


def _point_count(points: object) -> int:
    """How many interior points one polygon is given (None: none)."""
    return 0 if points is None else len(points)


def _prepared_at_once(
    index: Sequence[int],
    rings_of: Callable[[int], Sequence[object]],
    rule: str,
    invalid: str,
    plane: str,
    decided: Callable[[int], None] | None = None,
) -> dict[int, Triangulation]:
    """``tree.prepared_batch.triangulate_prepared`` of the polygons numbered ``index`` (their
    rings ``rings_of(number)``), by polygon number (none where the lock-step builder takes
    none of them), in chunks of ``_PREPARED_CHUNK`` polygons; ``decided`` is called after
    each with how many it decided (it may raise to stop)."""
    from .tree.prepared_batch import triangulate_prepared

    found: dict[int, Triangulation] = {}
    for first in range(0, len(index), _PREPARED_CHUNK):
        part = index[first : first + _PREPARED_CHUNK]
        if len(part) < 2:
            break
        with np.errstate(over="ignore", invalid="ignore", under="ignore"):
            try:
                done = triangulate_prepared([rings_of(i) for i in part], rule, invalid, plane)
            except (ArithmeticError, ValueError, TypeError, IndexError):
                done = {}  # the engine takes them and names what is wrong
        found.update((part[k], tree) for k, tree in done.items())
        if decided is not None:
            decided(len(done))
    return found


# polygons per call of the prepared batch: enough for the lock-step rounds, few enough for
# progress reports (and a cancel) between calls
_PREPARED_CHUNK = 512


def _check_many_options(
    rule: str, invalid: str, on_error: str, proven: Sequence[bool] | None, count: int
) -> None:
    """The options of :func:`triangulate_many` and :func:`triangulate_packed`, or ValueError."""
    if on_error not in ("raise", "return"):
        raise ValueError(f"on_error must be 'raise' or 'return', not {on_error!r}")
    get_rule(rule)
    _as_given(invalid)
    if proven is not None and len(proven) != count:
        raise ValueError(f"proven has {len(proven)} flags for {count} polygons")


def _engine_result(
    rings: Sequence[object],
    rule: str,
    planar_tolerance: float,
    invalid: str,
    on_error: str,
    plane: str,
    tick: Callable[[float], None] | None = None,
    points: object = None,
    mesh: object = None,
    ring_mesh: Triangulation | None = None,
    inserted_mesh: InsertedMesh | None = None,
    alive: Callable[[], None] | None = None,
) -> Triangulation | TriangulationError:
    """:func:`triangulate` of one polygon of many: its error is returned (``on_error`` is
    "return") or raised. ``tick``, ``ring_mesh``, ``inserted_mesh``, ``alive``: see
    ``one_polygon.triangulate_steps``."""
    try:
        with np.errstate(over="ignore", invalid="ignore", under="ignore"):
            return _triangulate(
                rings,
                rule=rule,
                planar_tolerance=planar_tolerance,
                invalid=invalid,
                plane=plane,
                tick=tick,
                points=points,
                mesh=mesh,
                ring_mesh=ring_mesh,
                inserted_mesh=inserted_mesh,
                alive=alive,
            )
    except TriangulationError as exc:
        if on_error == "raise":
            raise
        return exc


def triangulate_packed(
    polygons: PackedPolygons,
    *,
    rule: str = "first",
    planar_tolerance: float = 0.0,
    on_error: str = "raise",
    invalid: str = "fail",
    proven: Sequence[bool] | None = None,
    plane: str = "auto",
    progress: Callable[[float], None] | None = None,
    points: tuple[np.ndarray, np.ndarray] | None = None,
    meshes: tuple[np.ndarray, np.ndarray] | None = None,
) -> PackedTriangulations:
    """:func:`triangulate_many` of packed polygons, with packed results: the same vertices,
    triangles and trees, in flat arrays (no object per polygon). A polygon that fails with
    ``on_error="return"`` has no vertices or triangles and its error in ``errors``.
    ``progress``: called now and then with the share of the polygons done (0 to 1); an
    exception it raises (a cancelled run) stops the call. ``points``: None or interior
    points as ``(coordinates (K, 2 or 3), counts (P,))``, polygon i's being the ``counts[i]``
    rows after the previous polygons' (see :func:`triangulate`); their ids come back in
    ``point_ids`` and ``point_count`` of the result. ``meshes``: None or known triangulations
    as ``(triangles (T, 3), counts (P,))``, packed as the points (see :func:`triangulate`)."""
    _check_many_options(rule, invalid, on_error, proven, len(polygons))
    _check_plane(plane)
    coordinates, counts = _packed_points(points, len(polygons))
    # polygons with interior points go to the one-polygon builder
    plain = None if counts is None or not counts.any() else np.flatnonzero(counts == 0)
    pieces: list[Piece] = []
    report = _Reporter(progress, len(polygons), 0)
    if planar_tolerance <= 0 and len(polygons if plain is None else plain) > 1:
        from .tree.batch import triangulate_batch_packed

        batch = polygons if plain is None else polygons.take(plain)
        flags = proven if plain is None or proven is None else [proven[i] for i in plain]
        try:
            pieces = triangulate_batch_packed(
                batch, rule, proven=flags, plane=plane, alive=report.heartbeat
            )
        except (ArithmeticError, ValueError, TypeError):
            if report.stopped:
                raise  # the caller's progress stopped the call: not a failure of the batch
            pieces = []  # the engine takes every polygon and names what is wrong
        if plain is not None:
            for piece in pieces:
                piece.index = plain[piece.index]
    decided = np.zeros(len(polygons), dtype=bool)
    for piece in pieces:
        decided[piece.index] = True
    errors: dict[int, TriangulationError] = {}
    report.passed(int(decided.sum()))
    starts = None if counts is None else np.cumsum(counts) - counts
    mesh_rows, mesh_counts = (None, None) if meshes is None else meshes
    mesh_starts = None if mesh_counts is None else np.cumsum(mesh_counts) - mesh_counts
    ring_meshes: dict[int, Triangulation | None] = {}
    inserted: dict[int, InsertedMesh | None] = {}
    if counts is not None and _at_once_wanted(rule, planar_tolerance, invalid):
        from .tree.batch import triangulate_batch_packed

        wanted = np.flatnonzero(~decided & (counts > 0))
        if mesh_counts is not None:
            given = np.zeros(len(polygons), dtype=bool)
            given[: len(mesh_counts)] = np.asarray(mesh_counts)[: len(polygons)] > 0
            wanted = wanted[~given[wanted]]

        def triangulate_rings() -> list[Triangulation | None]:
            found: list[Triangulation | None] = [None] * len(wanted)
            for piece in triangulate_batch_packed(polygons.take(wanted), rule, plane=plane):
                for index, result in zip(piece.index.tolist(), piece.results.to_list()):
                    found[index] = result
            return found

        trees, ring_meshes, inserted = _points_at_once(
            wanted.tolist(),
            [polygons.rings(i) for i in wanted.tolist()],
            [coordinates[starts[i] : starts[i] + counts[i]] for i in wanted.tolist()],
            triangulate_rings,
            plane,
        )
        known_trees = {}
        if mesh_counts is not None:
            known = np.flatnonzero(~decided & (counts > 0) & given)
            known_trees = _known_at_once(
                known.tolist(),
                [polygons.rings(i) for i in known.tolist()],
                [coordinates[starts[i] : starts[i] + counts[i]] for i in known.tolist()],
                [
                    mesh_rows[mesh_starts[i] : mesh_starts[i] + mesh_counts[i]]
                    for i in known.tolist()
                ],
                plane,
            )
        for index, tree in (trees | known_trees).items():
            decided[index] = True
            report.one_more()
            pieces.append(Piece.of(index, tree))
    if planar_tolerance <= 0:
        left = np.flatnonzero(~decided if counts is None else ~decided & (counts == 0)).tolist()

        def reported(count: int) -> None:
            for _ in range(count):
                report.one_more()

        prepared = _prepared_at_once(left, polygons.rings, rule, invalid, plane, reported)
        for index, tree in prepared.items():
            decided[index] = True
            pieces.append(Piece.of(index, tree))
    left = np.flatnonzero(~decided).tolist()
    # the polygons the one-polygon builder takes alone (points, meshes, or large enough for
    # their progress to be reported as they go) and the others, whose trees run side by side
    alone = {
        index
        for index in left
        if (counts is not None and counts[index])
        or (mesh_starts is not None and index < len(mesh_counts) and mesh_counts[index])
        or ring_meshes.get(index) is not None
        or inserted.get(index) is not None
        or runs_alone(polygons.rings(index))
    }
    options = {
        "rule": rule,
        "planar_tolerance": planar_tolerance,
        "invalid": invalid,
        "plane": plane,
    }
    # in the order of ``left``, as the loop below takes them
    side_by_side = engine_results(
        [index for index in left if index not in alone],
        polygons.rings,
        options,
        report.one_more,
        report.heartbeat,
        report.tick,
    )
    for index in left:
        if index not in alone:
            _, result = next(side_by_side)
            if isinstance(result, TriangulationError):
                if on_error == "raise":
                    raise result
                errors[index] = result
            else:
                pieces.append(Piece.of(index, result))
            continue
        report.one_more()
        rings = polygons.rings(index)
        given = None
        if counts is not None and counts[index]:
            given = coordinates[starts[index] : starts[index] + counts[index]]
        mesh = None
        if mesh_starts is not None and index < len(mesh_counts) and mesh_counts[index]:
            mesh = mesh_rows[mesh_starts[index] : mesh_starts[index] + mesh_counts[index]]
        result = _engine_result(
            rings,
            rule,
            planar_tolerance,
            invalid,
            on_error,
            plane,
            report.tick,
            given,
            mesh,
            ring_meshes.get(index),
            inserted.get(index),
            report.heartbeat,
        )
        if isinstance(result, TriangulationError):
            errors[index] = result
        else:
            pieces.append(Piece.of(index, result))
    return assemble(len(polygons), pieces, errors, counts)


def _packed_points(
    points: tuple[np.ndarray, np.ndarray] | None, count: int
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The coordinates and per-polygon counts of packed interior points, checked."""
    if points is None:
        return None, None
    coordinates, counts = points
    coordinates = np.asarray(coordinates, dtype=np.float64)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    if coordinates.size == 0:
        coordinates = coordinates.reshape(0, 3)
    if coordinates.ndim != 2 or coordinates.shape[1] not in (2, 3):
        raise ValueError("point coordinates must be a (K, 2) or (K, 3) array")
    if len(counts) != count:
        raise ValueError(f"points has {len(counts)} counts for {count} polygons")
    if (counts < 0).any() or int(counts.sum()) != len(coordinates):
        raise ValueError("point counts must be non-negative and add up to the coordinates")
    return coordinates, counts


class _Reporter:
    """Calls ``progress`` with the share of ``total`` polygons done, at most every
    :data:`_REPORT_SECONDS`."""

    def __init__(self, progress: Callable[[float], None] | None, total: int, done: int) -> None:
        self.progress = progress
        self.total = max(total, 1)
        self.done = done
        self.last = time.monotonic()
        # what the one-polygon builder calls as it goes (None: nothing to tell)
        self.tick = None if progress is None else self.within
        # what long steps call now and then, where no share is known (the last one is told
        # again: a chance to stop the call)
        self.heartbeat = None if progress is None else self.alive
        self.shown = 0.0
        self.stopped = False  # the progress callback raised (a cancelled run)
        if progress is not None:
            self._tell(done / self.total)

    def _due(self) -> bool:
        """A report is wanted and the last one is old enough (then it counts as made)."""
        now = time.monotonic()
        if self.progress is None or now - self.last < _REPORT_SECONDS:
            return False
        self.last = now
        return True

    def _tell(self, share: float) -> None:
        """Report ``share``, never below one told before (a tree built again starts its
        share over) nor above 1; what the callback raises is noted, then raised on."""
        self.shown = max(self.shown, min(share, 1.0))
        try:
            self.progress(self.shown)
        except BaseException:
            self.stopped = True
            raise

    def within(self, share: float) -> None:
        """The polygon under way is ``share`` done."""
        if self._due():
            self._tell((self.done - 1 + share) / self.total)

    def passed(self, count: int) -> None:
        """``count`` polygons are done at once (the batch path)."""
        self.done = count
        if self.progress is not None:
            self.last = time.monotonic()
            self._tell(count / self.total)

    def alive(self) -> None:
        """A long step goes on: the last share told is told again."""
        if self._due():
            self._tell(self.shown)

    def one_more(self) -> None:
        """A polygon is about to start: the ones before it are done."""
        if self.progress is None:
            return
        if self._due():
            self._tell(self.done / self.total)
        self.done += 1


_REPORT_SECONDS = 0.2


def _check_plane(plane: str) -> None:
    if plane not in PLANES:
        raise ValueError(f"plane must be one of {PLANES}, not {plane!r}")


def _batch_well_formed(polygons: list, rule: str, batch, plane: str) -> list:
    """Batch results for the polygons whose rings normalise; None (engine) for the others."""
    good = []
    for index, rings in enumerate(polygons):
        try:
            normalise_rings(rings, plane)
        except TriangulationError:
            continue
        good.append(index)
    results: list = [None] * len(polygons)
    for index, result in zip(good, batch([polygons[i] for i in good], rule, plane=plane)):
        results[index] = result
    return results
