"""``triangulate_packed`` (and the rows of large mesh files) in worker processes, so that a
large layer uses every core.

The engine is numpy code driven by Python, so one process uses one core. A
:class:`WorkerPool` runs calls of :func:`~bsp_triangulate.api.triangulate_packed` in other
Python processes of the same version (this interpreter's own executable, found with
:func:`python_interpreter`), each started once and fed one call after another through its
standard input and output. Calls and results cross as pickles of plain arrays, so the results
are the same arrays, bit for bit, as in this process.

The worker side is :func:`serve`: it imports this package by its own name from the folder
that holds it, whatever name the caller imported it under (a QGIS plugin imports it as a
sub-package of the plugin).
"""

from __future__ import annotations

import contextlib
import json
import os
import pickle
import queue
import subprocess
import sys
import tempfile
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from .packed import PackedPolygons, PackedTriangulations
from .triangulation import TriangulationError

if TYPE_CHECKING:
    from .terrain.refine import Refinement

# this package's folder: the worker loads the package from there by its path, so that
# nothing beside it (an ``inspect.py`` next to a checkout) can shadow the standard library
_PACKAGE_PATH = str(Path(__file__).resolve().parent)
_BOOT = (
    "import importlib.util, json, os, sys; sys.path[:] = json.loads(sys.argv[1]); "
    "folder = sys.argv[2]; name = os.path.basename(folder); "
    "spec = importlib.util.spec_from_file_location(name, os.path.join(folder, '__init__.py'), "
    "submodule_search_locations=[folder]); "
    "package = importlib.util.module_from_spec(spec); sys.modules[name] = package; "
    "spec.loader.exec_module(package); "
    "importlib.import_module(name + '.workers').serve()"
)
# seconds a worker may take to exit after its input closes before it is killed
_EXIT_WAIT = 2.0
_RESULT_FIELDS = (
    "vertices", "vertex_count", "triangles", "triangle_count", "parent", "depth", "side",
)  # fmt: skip
# keyword fields of PackedTriangulations that cross too (interior points' ids)
_RESULT_KEYWORDS = ("point_ids", "point_count")


class WorkerError(RuntimeError):
    """A worker process could not start, or stopped before it answered."""


class WorkerCallError(RuntimeError):
    """The call raised in the worker process (the message names the exception); a
    :class:`TriangulationError` is raised as itself."""


def python_interpreter() -> str | None:
    """An executable of the running Python's version, or None.

    Embedded interpreters (QGIS) report their own program or a guess from ``PATH`` as
    ``sys.executable``, so the interpreter beside this Python's installation comes first.
    The worker checks the version when it starts.
    """
    major, minor = sys.version_info[:2]
    prefix = Path(sys.exec_prefix)
    if os.name == "nt":
        # pythonw: no console window per worker
        candidates = [prefix / "pythonw.exe", prefix / "python.exe"]
    else:
        candidates = [prefix / "bin" / f"python{major}.{minor}", prefix / "bin" / "python3"]
    for name in (getattr(sys, "_base_executable", None), sys.executable):
        if name and Path(name).name.lower().startswith("python"):
            candidates.append(Path(name))
    for candidate in candidates:
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    return None


class _Worker:
    """One worker process and its pipes."""

    def __init__(self, python: str) -> None:
        # the worker's messages, read when it fails (a pipe nobody reads could fill up)
        self._errors = tempfile.TemporaryFile()  # noqa: SIM115 - closed in kill()
        # the parent's own path, less the empty entry (the worker's current folder)
        paths = [path for path in sys.path if path]
        flags = getattr(subprocess, "CREATE_NO_WINDOW", 0)
        try:
            self.process = subprocess.Popen(
                [python, "-c", _BOOT, json.dumps(paths), _PACKAGE_PATH],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self._errors,
                creationflags=flags,
            )
        except OSError as error:
            self._errors.close()
            raise WorkerError(f"cannot start {python}: {error}") from error
        hello = self._receive()
        if hello != ("ready", tuple(sys.version_info[:2])):
            self.kill()
            raise WorkerError(f"{python} is not Python {sys.version_info[0]}.{sys.version_info[1]}")

    def call(self, request: tuple) -> Any:
        try:
            _send(self.process.stdin, request)
        except OSError as error:
            raise self._stopped(error) from error
        return self._receive()

    def _receive(self) -> Any:
        try:
            return pickle.load(self.process.stdout)
        except (EOFError, OSError, pickle.UnpicklingError) as error:
            raise self._stopped(error) from error

    def _stopped(self, error: BaseException) -> WorkerError:
        """The worker ended (killed if it had not): the error naming what it printed last."""
        self._end()
        try:
            self._errors.seek(0)
            printed = self._errors.read().decode(errors="replace").strip()[-2000:]
        except (OSError, ValueError):
            printed = ""
        self.kill()
        return WorkerError(f"the worker stopped: {printed or repr(error)}")

    def close(self) -> None:
        """Close the worker's input (it exits), kill it if it does not."""
        try:
            self.process.stdin.close()
            self.process.wait(_EXIT_WAIT)
        except (OSError, subprocess.TimeoutExpired):
            pass
        self.kill()

    def _end(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()

    def kill(self) -> None:
        self._end()
        for stream in (self.process.stdin, self.process.stdout, self._errors):
            with contextlib.suppress(OSError):
                stream.close()


class WorkerPool:
    """Up to ``count`` worker processes running ``triangulate_packed`` calls.

    ``submit`` returns a future of the call's :class:`PackedTriangulations`. A worker starts
    with the first call that needs it and serves calls until :meth:`close`. A call fails
    with :class:`WorkerError` when its worker cannot start or stops (it is replaced for the
    next call), with :class:`WorkerCallError` when ``triangulate_packed`` raises.
    """

    def __init__(self, count: int, python: str | None = None) -> None:
        if count < 1:
            raise ValueError("a pool needs at least one worker")
        self.count = count
        self.python = python or python_interpreter()
        self._threads = ThreadPoolExecutor(count, thread_name_prefix="bsp-triangulate-worker")
        self._idle: queue.SimpleQueue[_Worker] = queue.SimpleQueue()
        self._workers: list[_Worker] = []
        self._lock = threading.Lock()
        self._closed = False
        # workers started so far (a stopped one is replaced by a new one)
        self.started = 0

    def submit(self, polygons: PackedPolygons, **options: Any) -> Future:
        """``triangulate_packed(polygons, **options)`` in a worker."""
        request = (
            "triangulate",
            (polygons.points, polygons.ring_len, polygons.ring_count, options),
        )
        return self._threads.submit(self._run, request)

    def refine(
        self,
        polygons: list,
        grids: list,
        tolerance: float,
        max_points: int,
        *,
        fixed: list | None = None,
        groups: list[int] | None = None,
        **options: Any,
    ) -> Future:
        """``refine_many(polygons, grids, tolerance, max_points, engine=triangulate_many,
        fixed=fixed, groups=groups, **options)`` in a worker: a future of its list of
        :class:`~bsp_triangulate.terrain.refine.Refinement` (an error is rebuilt from its
        type's name and message)."""
        # the grids as plain values: the worker imports this package under another name
        cells = [(grid.x0, grid.y0, grid.dx, grid.dy, grid.values) for grid in grids]
        request = ("refine", (polygons, cells, tolerance, max_points, fixed, groups, options))
        return self._threads.submit(self._run, request)

    def write_rows(self, path: str, kind: str, first: int, rows: np.ndarray) -> Future:
        """``mesh.write_rows(path, kind, first, rows)`` in a worker (a future of None)."""
        return self._threads.submit(self._run, ("write_rows", (str(path), kind, first, rows)))

    def _run(self, request: tuple) -> PackedTriangulations | list[Refinement] | None:
        worker = self._take()
        try:
            status, payload = worker.call(request)
        except BaseException:
            self._drop(worker)
            raise
        self._idle.put(worker)
        if status != "ok":
            kind, message = payload
            if kind == TriangulationError.__name__:
                raise TriangulationError(message)
            raise WorkerCallError(f"{kind}: {message}")
        if request[0] == "refine":
            return [_refinement(*values) for values in payload]
        if request[0] != "triangulate":
            return None
        arrays, errors = payload
        positional = arrays[: len(_RESULT_FIELDS)]
        keywords = dict(zip(_RESULT_KEYWORDS, arrays[len(_RESULT_FIELDS) :]))
        return PackedTriangulations(
            *positional,
            errors={index: TriangulationError(text) for index, text in errors.items()},
            **keywords,
        )

    def _take(self) -> _Worker:
        try:
            return self._idle.get_nowait()
        except queue.Empty:
            pass
        if self.python is None:
            raise WorkerError("no Python executable of this version was found")
        with self._lock:
            if self._closed:
                raise WorkerError("the pool is closed")
        worker = _Worker(self.python)
        with self._lock:
            if self._closed:
                worker.kill()
                raise WorkerError("the pool is closed")
            self._workers.append(worker)
            self.started += 1
        return worker

    def _drop(self, worker: _Worker) -> None:
        worker.kill()
        with self._lock:
            if worker in self._workers:
                self._workers.remove(worker)

    def processes(self) -> list[subprocess.Popen]:
        """The worker processes running now."""
        with self._lock:
            return [w.process for w in self._workers if w.process.poll() is None]

    def close(self, cancel: bool = False) -> None:
        """Stop the workers: after their calls (``cancel``: at once, calls not started are
        dropped and running ones fail)."""
        with self._lock:
            self._closed = True
            workers, self._workers = self._workers, []
        if cancel:
            for worker in workers:
                worker.kill()
        self._threads.shutdown(wait=True, cancel_futures=cancel)
        for worker in workers:
            worker.close()

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close(cancel=exc_info[0] is not None)


def _send(channel: IO[bytes], message: object) -> None:
    pickle.dump(message, channel, protocol=pickle.HIGHEST_PROTOCOL)
    channel.flush()


def serve() -> None:
    """The worker's loop: one task (its name and arguments, see ``_TASKS``) from standard
    input, its reply to standard output, until the input closes. Anything else printed goes
    to standard error."""
    requests = sys.stdin.buffer
    replies = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    _send(replies, ("ready", tuple(sys.version_info[:2])))
    while True:
        try:
            task, arguments = pickle.load(requests)
        except EOFError:
            return
        try:
            reply: tuple = ("ok", _TASKS[task](*arguments))
        except Exception as error:  # the caller decides what a failed call means
            reply = ("error", (type(error).__name__, str(error)))
        _send(replies, reply)


def _triangulate(
    points: np.ndarray, ring_len: np.ndarray, ring_count: np.ndarray, options: dict
) -> tuple[tuple[np.ndarray, ...], dict[int, str]]:
    """Task "triangulate": the result's arrays and error messages, as plain values."""
    from .api import triangulate_packed

    result = triangulate_packed(PackedPolygons(points, ring_len, ring_count), **options)
    names = _RESULT_FIELDS + _RESULT_KEYWORDS
    arrays = tuple(np.asarray(getattr(result, name)) for name in names)
    return arrays, {index: str(error) for index, error in result.errors.items()}


def _refine(
    polygons: list,
    grids: list,
    tolerance: float,
    max_points: int,
    fixed: list | None,
    groups: list[int] | None,
    options: dict,
) -> list[tuple]:
    """Task "refine": ``refine_many`` over the polygons (``grids`` as the plain values of
    ``CellGrid``), each outcome as plain values (the fields of ``Refinement``, its error as
    its type's name and message, then its mesh)."""
    from .api import triangulate_many
    from .terrain.refine import CellGrid, refine_many

    results = refine_many(
        polygons,
        [CellGrid(*grid) for grid in grids],
        tolerance,
        max_points,
        engine=triangulate_many,
        fixed=fixed,
        groups=groups,
        **options,
    )
    return [
        (
            r.points,
            r.added,
            r.max_error,
            r.cells,
            r.rounds,
            r.within,
            r.capped,
            None if r.error is None else (type(r.error).__name__, str(r.error)),
            r.mesh,
        )
        for r in results
    ]


def _refinement(*values: Any) -> Refinement:
    """A ``Refinement`` from the plain values of the task "refine"."""
    from .terrain.refine import Refinement

    *fields, error, mesh = values
    if error is not None:
        kind, message = error
        if kind == TriangulationError.__name__:
            error = TriangulationError(message)
        else:
            error = WorkerCallError(f"{kind}: {message}")
    return Refinement(*fields, error=error, mesh=mesh)


def _write_rows(path: str, kind: str, first: int, rows: np.ndarray) -> None:
    """Task "write_rows": a part of a 2DM file (``mesh.write_rows``)."""
    from .formats.mesh import write_rows

    write_rows(path, kind, first, rows)


_TASKS = {"triangulate": _triangulate, "refine": _refine, "write_rows": _write_rows}
