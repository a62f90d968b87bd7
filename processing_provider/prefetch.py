"""Work on the next batches in background threads while the caller handles the current one.

The triangulation of a batch is numpy work that releases the GIL for most of its time, while
reading features, sampling the DEM and writing outputs go through QGIS's bindings and stay in
the calling thread. Overlapping the two uses a second core without sharing any QGIS object
across threads: worker threads only ever see plain Python and numpy data.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")


def worker_count(configured: int = -1) -> int:
    """Background workers to use: ``configured`` threads in all (QGIS's "max threads"
    setting, -1 or 0 for every core) less the calling thread; 0 on a single core."""
    cores = os.cpu_count() or 1
    threads = cores if configured is None or configured <= 0 else min(configured, cores)
    return max(threads - 1, 0)


def map_ahead(
    function: Callable[[Item], Result], items: Iterable[Item], workers: int
) -> Iterator[tuple[Item, Result]]:
    """``(item, function(item))`` for every item, in order.

    ``items`` is consumed in the calling thread; ``function`` runs in up to ``workers``
    threads, at most ``workers`` items ahead of the one handed back. With ``workers`` 0 it
    runs in the calling thread. An exception of ``function`` is raised when its item is
    reached. Leaving the loop early waits only for the items already started.
    """
    if workers <= 0:
        for item in items:
            yield item, function(item)
        return
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="bsptriangulate")
    pending: deque[tuple[Item, Future]] = deque()
    try:
        for item in items:
            pending.append((item, pool.submit(function, item)))
            if len(pending) > workers:
                done, future = pending.popleft()
                yield done, future.result()
        while pending:
            done, future = pending.popleft()
            yield done, future.result()
    finally:
        for _, future in pending:
            future.cancel()
        pool.shutdown(wait=True)
