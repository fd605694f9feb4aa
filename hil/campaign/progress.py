"""Live progress of a campaign: a rich bar on a terminal, plain lines elsewhere (CI logs)."""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO


class Progress:
    """Samples done, failures and errors so far, rate and ETA.

    Parameters
    ----------
    total : int
        samples the campaign will run.
    label : str
        what is running (shown first).
    stream : file, optional
        where to write (default ``sys.stderr``); rich draws only when it is a terminal.
    """

    def __init__(self, total: int, label: str, *, stream: TextIO | None = None,
                 enabled: bool = True) -> None:
        self.total = total
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.done = self.failed = self.errors = 0
        self.t0 = time.perf_counter()
        self._last_line = 0.0
        self._rich: Any = None
        self._task: Any = None
        if enabled and self.stream.isatty():
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )
            from rich.progress import Progress as RichProgress

            self._rich = RichProgress(
                TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                TextColumn("{task.fields[status]}"), TextColumn("{task.fields[rate]}"),
                TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                console=Console(file=self.stream), transient=False)
            self._rich.start()
            self._task = self._rich.add_task(label, total=total, status="", rate="")

    def rate(self) -> float:
        elapsed = time.perf_counter() - self.t0
        return self.done / elapsed if elapsed > 0 else 0.0

    def eta_s(self) -> float | None:
        rate = self.rate()
        return (self.total - self.done) / rate if rate > 0 else None

    def update(self, sample: dict[str, Any]) -> None:
        """Count one finished sample."""
        self.done += 1
        if sample["verdict"] == "fail":
            self.failed += 1
        elif sample["verdict"] != "pass":
            self.errors += 1
        if not self.enabled:
            return
        status = f"{self.failed} failed, {self.errors} errors"
        if self._rich is not None:
            self._rich.update(self._task, completed=self.done, status=status,
                              rate=f"{self.rate() * 60:.1f}/min")
            return
        now = time.perf_counter()
        step = max(1, self.total // 20)
        if self.done == self.total or self.done % step == 0 or now - self._last_line > 15:
            self._last_line = now
            eta = self.eta_s()
            print(f"hil: {self.label}: {self.done}/{self.total} samples, {status}, "
                  f"{self.rate() * 60:.1f} samples/min"
                  + (f", ETA {_mmss(eta)}" if eta is not None and self.done < self.total
                     else ""), file=self.stream, flush=True)

    def close(self) -> None:
        if self._rich is not None:
            self._rich.stop()
            self._rich = None


def _mmss(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    return f"{m}m{s:02d}s"
