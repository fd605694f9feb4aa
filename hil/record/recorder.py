"""The run recorder: one directory per run holding everything the run produced.

Layout of ``out_dir``::

    record.json   run id, clock, bus spec, seeds, versions, timing health, measurements, verdict
    bus.log       candump log of every frame the rig sent or received
    bus.asc       the same, Vector ASC
    bus-unheard.log  candump log of the DUT's frames a fault kept from the rig (a cut wire):
                  sent, never received, so in neither bus log (only when there were any)
    traces.npz    named signal traces with units (traces.csv on request)

On any exception (Ctrl-C included) leaving the ``with`` block, the recorder writes all of it
with the verdict ``error`` (or ``aborted``) and the error text, then lets the exception go on.
"""

from __future__ import annotations

import datetime as dt
import functools
import platform
import sys
import traceback
import uuid
from enum import StrEnum
from importlib import metadata
from pathlib import Path
from types import TracebackType
from typing import Any

from hil.clock.base import TimingHealth
from hil.measurements import Measurement, Outcome
from hil.record.atomic import write_json_atomic
from hil.record.buslog import DEFAULT_FORMATS, BusLog, UnheardLog
from hil.record.traces import TraceSet


class Verdict(StrEnum):
    """The verdict of a run: pass, fail, or why the run says nothing about the DUT."""

    PASS = "pass"
    FAIL = "fail"
    #: bench timing out of bounds: says nothing about the DUT
    INVALID_BENCH = "invalid-bench"
    #: the run could not complete (setup error, bus error, DUT silent …)
    ERROR = "error"
    #: stopped by the user (Ctrl-C, SIGTERM)
    ABORTED = "aborted"
    #: finished without any measurement to judge
    NO_MEASUREMENTS = "no-measurements"


_PACKAGES = ("agrihil", "python-can", "cantools", "canopen", "control", "numpy", "pyserial")


def versions() -> dict[str, str]:
    """Python, platform and package versions, for the record.

    Looked up once per process: the metadata scan and ``platform.platform()`` cost tens of ms,
    and they do not change under a running process.
    """
    return dict(_versions())


@functools.cache
def _versions() -> dict[str, str]:
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def judge(measurements: list[Measurement], timing: TimingHealth | None) -> Verdict:
    """Verdict of a completed run: invalid bench timing outranks DUT results."""
    if timing is not None and timing.mode == "realtime" and not timing.valid:
        return Verdict.INVALID_BENCH
    if not measurements:
        return Verdict.NO_MEASUREMENTS
    if any(m.outcome in (Outcome.FAIL, Outcome.ERROR) for m in measurements):
        return Verdict.FAIL
    return Verdict.PASS


class Recorder:
    """Collects one run's frames, traces, measurements and facts and writes them to its directory.

    A context manager: on entry the bus log opens; on exit, whatever happened, everything is
    written (:meth:`close`), with the verdict ``error`` (``aborted`` for Ctrl-C) and the error
    text if an exception is leaving the block.

    Parameters
    ----------
    out_dir : str or Path
        The run's directory (created).
    run_id : str, optional
        The run's id (default: 12 random hex digits).
    bus_log_formats : tuple of str, optional
        The bus log files to write (see :class:`~hil.record.buslog.BusLog`).
    csv : bool, optional
        Also write ``traces.csv``.
    save_traces : bool, optional
        Write ``traces.npz`` (and ``traces.csv``); False keeps them in :attr:`traces` only.
    """

    def __init__(self, out_dir: str | Path, *, run_id: str | None = None,
                 bus_log_formats: tuple[str, ...] = DEFAULT_FORMATS, csv: bool = False,
                 save_traces: bool = True) -> None:
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.run_id = run_id or uuid.uuid4().hex[:12]
        self.traces = TraceSet()
        self.measurements: list[Measurement] = []
        self.timing: TimingHealth | None = None
        self.meta: dict[str, Any] = {}
        self.seeds: dict[str, int] = {}
        self.csv = csv
        self.save_traces = save_traces
        self.verdict: Verdict | None = None
        self.error: str | None = None
        self.started_at = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        self._bus_log_formats = bus_log_formats
        self.bus_log: BusLog | None = None
        #: the DUT's frames nobody heard (:meth:`log_unheard`), opened at the first one
        self.unheard_log: UnheardLog | None = None
        self._closed = False
        #: the record as written to record.json (set by :meth:`close`)
        self.final_record: dict[str, Any] = {}

    def __enter__(self) -> Recorder:
        self.bus_log = BusLog(self.out_dir, formats=self._bus_log_formats)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc is not None:
            aborted = isinstance(exc, KeyboardInterrupt)
            self.verdict = Verdict.ABORTED if aborted else Verdict.ERROR
            self.error = f"{type(exc).__name__}: {exc}"
            self.meta["traceback"] = "".join(traceback.format_exception(exc_type, exc, tb))[-4000:]
        self.close()

    def log_frame(self, msg: Any, time_s: float, *, rx: bool) -> None:
        """Log one frame the rig sent (``rx=False``) or received at run time ``time_s``."""
        if self.bus_log is not None:
            self.bus_log.write(msg, time_s, rx=rx)

    def log_unheard(self, msg: Any, time_s: float) -> None:
        """Log a frame of the DUT that a fault kept from the rig, at run time ``time_s``.

        A cut wire: the rig's :meth:`~hil.rig.Rig.admits` refused it.

        The bus logs are what the rig received: such a frame is in neither. It goes to
        ``bus-unheard.log`` (candump, opened at the first one), so what the DUT said while
        nobody heard it can still be read, and the record counts them (``unheard``).
        """
        if self.bus_log is None:
            return
        if self.unheard_log is None:
            self.unheard_log = UnheardLog(self.out_dir, channel=self.bus_log.channel)
        self.unheard_log.write(msg, time_s)

    def measure(self, measurement: Measurement) -> Measurement:
        """Keep a judged measurement for the record; returns it."""
        self.measurements.append(measurement)
        return measurement

    def record(self) -> dict[str, Any]:
        """The record as it stands: run id, verdict, error, seeds, timing, measurements, meta.

        The verdict is the one set (error, aborted) or else :func:`judge`'s.
        """
        verdict = self.verdict or judge(self.measurements, self.timing)
        return {
            "run_id": self.run_id,
            "started_at": self.started_at,
            "verdict": verdict.value,
            "error": self.error,
            "seeds": self.seeds,
            "timing": self.timing.to_dict() if self.timing else None,
            "measurements": [m.to_dict() for m in self.measurements],
            "versions": versions(),
            "command": sys.argv,
            "artifacts": self._artifacts(),
            **({"unheard": self.unheard_log.summary()} if self.unheard_log else {}),
            **self.meta,
        }

    def _artifacts(self) -> list[str]:
        names = ["record.json"]
        if self.bus_log is not None:
            names += [p.name for p in self.bus_log.paths]
        if self.unheard_log is not None:
            names.append(self.unheard_log.path.name)
        if self.save_traces:
            names.append("traces.npz")
            if self.csv:
                names.append("traces.csv")
        return names

    def close(self) -> dict[str, Any]:
        """Write everything; safe to call more than once."""
        if self._closed:
            return self.final_record
        self._closed = True
        problems = []
        for name, log in (("bus log", self.bus_log), ("unheard frames", self.unheard_log)):
            if log is None:
                continue
            try:
                log.close()
            except Exception as exc:
                problems.append(f"{name}: {exc}")
        try:
            if self.save_traces:
                self.traces.save_npz(self.out_dir / "traces.npz")
                if self.csv:
                    self.traces.save_csv(self.out_dir / "traces.csv")
        except Exception as exc:
            problems.append(f"traces: {exc}")
        record = self.record()
        if problems:
            record["recorder_problems"] = problems
        write_json_atomic(self.out_dir / "record.json", record)
        self.final_record = record
        return record
