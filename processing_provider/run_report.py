"""What a run tells its user: progress over its stages, and per-feature failures summarised."""

from __future__ import annotations

import csv
import re
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TypeVar

from qgis.core import QgsProcessingFeedback

T = TypeVar("T")

# Share of the progress bar of each stage a feature goes through; "finish" is the end of the
# run (closing the outputs, writing the mesh file).
STAGES = {"read": 0.15, "elevation": 0.10, "engine": 0.30, "write": 0.40, "finish": 0.05}
# the same with interior points added from a DEM ("refine"), which then takes most of a run
REFINE_STAGES = {
    "read": 0.05,
    "elevation": 0.05,
    "refine": 0.60,
    "engine": 0.10,
    "write": 0.15,
    "finish": 0.05,
}
# failures listed with their ids per kind of reason; the rest are counted
LISTED_PER_REASON = 10


class Progress:
    """Progress of a run of ``total`` features: each stage reports the features it has
    passed; the bar is the weighted sum of the stages, so it only moves forward."""

    def __init__(
        self, feedback: QgsProcessingFeedback, total: int, stages: dict[str, float] | None = None
    ) -> None:
        self.feedback = feedback
        self.total = max(total, 1)
        self.stages = STAGES if stages is None else stages
        self.done = dict.fromkeys(self.stages, 0.0)
        self.shown = -1.0

    def advance(self, stage: str, features: float) -> None:
        """``features`` more features have passed ``stage``."""
        self.done[stage] = min(self.done[stage] + features, self.total)
        self._show()

    def finish_stage(self, stage: str) -> None:
        """Every feature has passed ``stage``."""
        self.done[stage] = self.total
        self._show()

    def _show(self) -> None:
        value = 100.0 * sum(self.stages[s] * d for s, d in self.done.items()) / self.total
        value = min(value, 99.9)
        if value > self.shown:
            self.shown = value
            self.feedback.setProgress(value)

    def counted(
        self, stage: str, items: Iterable[T], size: Callable[[T], float], every: float = 500
    ) -> Iterator[T]:
        """``items`` as they come; each adds ``size(item)`` features to ``stage``, shown every
        ``every`` features. Stops early when the run is cancelled."""
        pending = 0.0
        for item in items:
            if self.feedback.isCanceled():
                return
            yield item
            pending += size(item)
            if pending >= every:
                self.advance(stage, pending)
                pending = 0.0
        if pending:
            self.advance(stage, pending)


def reason_kind(reason: str) -> str:
    """The reason with its numbers left out: failures of one kind share it."""
    return re.sub(r"-?\d+(\.\d+)?(e-?\d+)?", "#", reason)


class FailureLog:
    """Per-feature failures: the first few of each kind of reason are reported with their ids
    at once, the others counted and summarised at the end; all of them go to an optional
    CSV report (fid, reason)."""

    def __init__(
        self,
        feedback: QgsProcessingFeedback,
        tr: Callable[[str], str],
        report_path: str | None = None,
    ) -> None:
        self.feedback = feedback
        self.tr = tr
        self.kinds: Counter[str] = Counter()
        self.warning_kinds: Counter[str] = Counter()
        self.examples: dict[str, str] = {}
        self.count = 0
        self.report_path = report_path
        self._file = None
        self._writer = None
        if report_path:
            Path(report_path).parent.mkdir(parents=True, exist_ok=True)
            self._file = open(report_path, "w", newline="", encoding="utf-8")  # noqa: SIM115
            self._writer = csv.writer(self._file)
            self._writer.writerow(["fid", "reason"])

    def add(self, fid: int, reason: str) -> None:
        self.count += 1
        kind = reason_kind(reason)
        self.kinds[kind] += 1
        self.examples.setdefault(kind, reason)
        if self._writer is not None:
            self._writer.writerow([fid, reason])
        if self.kinds[kind] <= LISTED_PER_REASON:
            self.feedback.reportError(self.tr("Feature {}: {}").format(fid, reason), False)

    def warn(self, fid: int, reason: str) -> None:
        """A feature that is written but falls short (not a failure): listed as ``add``
        lists failures, and in the report."""
        kind = reason_kind(reason)
        self.warning_kinds[kind] += 1
        self.examples.setdefault(kind, reason)
        if self._writer is not None:
            self._writer.writerow([fid, reason])
        if self.warning_kinds[kind] <= LISTED_PER_REASON:
            self.feedback.pushWarning(self.tr("Feature {}: {}").format(fid, reason))

    def close(self) -> None:
        """Summarise the kinds with more failures than were listed; close the report."""
        for kind, count in self.kinds.most_common():
            if count > LISTED_PER_REASON:
                self.feedback.reportError(
                    self.tr("{} more feature(s) failed the same way as: {}").format(
                        count - LISTED_PER_REASON, self.examples[kind]
                    ),
                    False,
                )
        for kind, count in self.warning_kinds.most_common():
            if count > LISTED_PER_REASON:
                self.feedback.pushWarning(
                    self.tr("{} more feature(s) the same way as: {}").format(
                        count - LISTED_PER_REASON, self.examples[kind]
                    )
                )
        if self._file is not None:
            self._file.close()
            self._file = None
            if self.count:
                self.feedback.pushInfo(
                    self.tr("Failures of {} feature(s) listed in {}").format(
                        self.count, self.report_path
                    )
                )
            if self.warning_kinds:
                self.feedback.pushInfo(
                    self.tr("Warnings of {} feature(s) listed in {}").format(
                        sum(self.warning_kinds.values()), self.report_path
                    )
                )
