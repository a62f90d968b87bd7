"""Helpers shared by the benchmarks: result rows, Markdown tables, timing, machine info."""

from __future__ import annotations

import multiprocessing
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = ROOT.parent / "shared" / "data"
BUILD = ROOT / "build" / "bench"
LONG_RUN = 5.0  # seconds

if str(ROOT) not in sys.path:  # run as a script: make the core package importable
    sys.path.insert(0, str(ROOT))


@dataclass
class Row:
    """One figure of a benchmark: what was measured, its value and unit, and a remark."""

    case: str
    measure: str
    value: float | str
    unit: str = ""
    note: str = ""


def format_value(value: float | str) -> str:
    if isinstance(value, str):
        return value
    if value != value:  # NaN
        return "n/a"
    magnitude = abs(value)
    if magnitude >= 1000:
        return f"{value:,.0f}"
    if magnitude >= 100:
        return f"{value:.0f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    if magnitude >= 0.1:
        return f"{value:.2f}"
    return f"{value:.3g}"


def markdown_table(headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """A GitHub Markdown table; floats are rounded to a readable precision."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    for row in rows:
        cells = (format_value(cell).replace("|", "\\|") for cell in row)
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def rows_table(rows: Iterable[Row]) -> str:
    return markdown_table(
        ["case", "measure", "value", "unit", "note"],
        [(r.case, r.measure, r.value, r.unit, r.note) for r in rows],
    )


def timed(function: Callable[[], Any], repeat: int = 1) -> tuple[float, Any]:
    """Best wall time (seconds) of up to ``repeat`` calls, and the last call's result.

    A call longer than ``LONG_RUN`` seconds is not repeated: its time is stable enough.
    """
    best = float("inf")
    result = None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
        if best > LONG_RUN:
            break
    return best, result


def best_rounds(
    runs: dict[str, Callable[[], Any]], rounds: int, seconds: Callable[[Any], float]
) -> dict[str, Any]:
    """Per name, the best (by ``seconds``) of ``rounds`` alternated rounds of its run: each
    round calls every run once, in turn, so that every library gets the same chances on a
    machine whose speed drifts. A run that returns a string (over budget, failed) keeps it and
    is not called again."""
    best: dict[str, Any] = {}
    for _ in range(rounds):
        for name, run in runs.items():
            if isinstance(best.get(name), str):
                continue
            timing = run()
            previous = best.get(name)
            if isinstance(timing, str) or previous is None or seconds(timing) < seconds(previous):
                best[name] = timing
    return best


class BudgetExceededError(Exception):
    """A measurement did not finish within its time budget."""


def _exit_with_parent(parent: int) -> None:
    """Stop this forked child when the benchmark process that started it is gone."""
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(1)


def _child(function: Callable[[], Any], connection: Any, parent: int) -> None:
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    try:
        connection.send((True, function()))
    except BaseException as error:  # report any failure to the parent, then exit
        connection.send((False, repr(error)))
    finally:
        connection.close()


def within(function: Callable[[], Any], timeout: float | None) -> Any:
    """``function()`` run in a forked child that is killed after ``timeout`` seconds.

    The child inherits the parent's data (no copying of the inputs), so this only costs the
    fork. Raises BudgetExceededError when the budget runs out, RuntimeError when the child fails.
    """
    if timeout is None:
        return function()
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(function, sender, os.getpid()), daemon=True)
    child.start()
    sender.close()
    try:
        if not receiver.poll(timeout):
            raise BudgetExceededError(f"no result within {timeout:.0f} s")
        ok, result = receiver.recv()
    except EOFError:
        ok, result = False, f"child exited with code {child.exitcode}"
    finally:
        if child.is_alive():
            child.kill()
        child.join()
    if not ok:
        raise RuntimeError(result)
    return result


def qgis_process_binary() -> str:
    """``/usr/bin/qgis_process.bin`` where it exists (the wrapper script is broken here)."""
    if Path("/usr/bin/qgis_process.bin").exists():
        return "/usr/bin/qgis_process.bin"
    found = shutil.which("qgis_process")
    if found is None:
        raise RuntimeError("qgis_process not found")
    return found


def qgis_environment(plugin_dir: Path | None = None) -> dict[str, str]:
    """Headless environment with a throwaway profile; the plugin on QGIS_PLUGINPATH if given."""
    environment = dict(os.environ)
    environment["QT_QPA_PLATFORM"] = "offscreen"
    environment["QGIS_CUSTOM_CONFIG_PATH"] = tempfile.mkdtemp(prefix="bsptri-bench-profile-")
    if plugin_dir is not None:
        environment["QGIS_PLUGINPATH"] = str(plugin_dir)
    return environment


def plugin_dir() -> Path:
    """A temporary directory holding ``bsptriangulate`` -> the repository root."""
    directory = Path(tempfile.mkdtemp(prefix="bsptri-plugins-"))
    (directory / "bsptriangulate").symlink_to(ROOT, target_is_directory=True)
    return directory


def enable_plugin(environment: dict[str, str]) -> None:
    """``qgis_process plugins enable bsptriangulate`` in the given environment."""
    subprocess.run(
        [qgis_process_binary(), "plugins", "enable", "bsptriangulate"],
        env=environment,
        check=True,
        capture_output=True,
        text=True,
    )


def qgis_version() -> str:
    """QGIS's version, asked of another Python process: QGIS loaded into this one would be
    in every forked measurement too (its objects and libraries slow the core's calls)."""
    command = [sys.executable, "-c", "from qgis.core import Qgis; print(Qgis.QGIS_VERSION)"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired):
        return "not importable"
    return done.stdout.strip() if done.returncode == 0 else "not importable"


def machine_info() -> dict[str, str]:
    """CPU model, cores, Python, numpy and QGIS versions of this machine."""
    import numpy

    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "CPU": cpu,
        "cores": str(os.cpu_count()),
        "Python": platform.python_version(),
        "numpy": numpy.__version__,
        "QGIS": qgis_version(),
        "OS": platform.platform(),
    }
