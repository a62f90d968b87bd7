"""map_ahead: the algorithm's overlap of triangulation (threads) with QGIS work (caller)."""

from __future__ import annotations

import threading
import time

import pytest

from tests.conftest import load_plugin_package

load_plugin_package()
from bsptriangulate.processing_provider.prefetch import map_ahead, worker_count  # noqa: E402


@pytest.mark.parametrize("workers", [0, 1, 3])
def test_results_come_back_in_input_order_with_their_items(workers: int) -> None:
    def slow_square(value: int) -> int:
        time.sleep(0.002 * (value % 3))  # later items may finish first
        return value * value

    pairs = list(map_ahead(slow_square, range(20), workers))
    assert pairs == [(value, value * value) for value in range(20)]


def test_items_are_read_in_the_calling_thread_and_worked_on_in_another() -> None:
    caller = threading.get_ident()
    read_in: list[int] = []
    worked_in: list[int] = []

    def items():
        for value in range(5):
            read_in.append(threading.get_ident())
            yield value

    def work(value: int) -> int:
        worked_in.append(threading.get_ident())
        return value

    assert [result for _, result in map_ahead(work, items(), 1)] == list(range(5))
    assert set(read_in) == {caller}
    assert caller not in worked_in


def test_without_workers_everything_runs_in_the_calling_thread() -> None:
    caller = threading.get_ident()
    threads = [result for _, result in map_ahead(lambda _: threading.get_ident(), range(3), 0)]
    assert threads == [caller] * 3


def test_work_runs_at_most_workers_items_ahead() -> None:
    started: list[int] = []
    lock = threading.Lock()

    def work(value: int) -> int:
        with lock:
            started.append(value)
        return value

    for value, _ in map_ahead(work, range(10), 2):
        time.sleep(0.005)
        with lock:
            # the item handed back and at most two more have been submitted
            assert max(started) <= value + 2


def test_an_exception_is_raised_at_its_item_after_the_earlier_results() -> None:
    def work(value: int) -> int:
        if value == 3:
            raise ValueError("bad item 3")
        return value

    seen = []
    with pytest.raises(ValueError, match="bad item 3"):
        for value, _ in map_ahead(work, range(6), 2):
            seen.append(value)
    assert seen == [0, 1, 2]


def test_leaving_early_does_not_start_the_remaining_items() -> None:
    started: list[int] = []

    def work(value: int) -> int:
        started.append(value)
        time.sleep(0.01)
        return value

    for value, _ in map_ahead(work, range(100), 1):
        if value == 2:
            break
    time.sleep(0.05)
    assert max(started) <= 4


@pytest.mark.parametrize(
    ("configured", "cores", "expected"),
    [(-1, 8, 7), (0, 8, 7), (4, 8, 3), (16, 8, 7), (-1, 1, 0), (1, 8, 0)],
)
def test_worker_count_leaves_the_calling_thread_its_core(
    monkeypatch: pytest.MonkeyPatch, configured: int, cores: int, expected: int
) -> None:
    monkeypatch.setattr("os.cpu_count", lambda: cores)
    assert worker_count(configured) == expected
