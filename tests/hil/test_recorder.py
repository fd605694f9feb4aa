from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import can
import numpy as np
import pytest

from hil.clock.base import TimingHealth, TimingLimits
from hil.measurements import Measurement
from hil.record import Recorder, load_traces
from hil.record.traces import TraceError


def _fill(rec: Recorder, n: int = 50) -> None:
    rec.traces.declare("flow_sensed", "g/s")
    rec.traces.declare("flow_true", "g/s")
    for i in range(n):
        rec.traces.append(i * 0.01, [float(i), 2.0 * i])
        rec.log_frame(can.Message(arbitration_id=0x181, is_extended_id=False,
                                  data=bytes([i % 256])), i * 0.01, rx=False)


def test_a_run_writes_every_artifact(tmp_path: Path) -> None:
    with Recorder(tmp_path, run_id="r1", csv=True) as rec:
        _fill(rec)
        rec.seeds["plant"] = 7
        rec.meta["clock"] = "lockstep"
        rec.measure(Measurement("flow.step.overshoot", 2.0, "%", high=5.0))
    record = json.loads((tmp_path / "record.json").read_text())
    assert record["verdict"] == "pass" and record["run_id"] == "r1"
    assert record["seeds"] == {"plant": 7} and record["clock"] == "lockstep"
    assert record["measurements"][0]["outcome"] == "pass"
    assert "python-can" in record["versions"]
    arrays, units = load_traces(tmp_path / "traces.npz")
    assert units == {"time_s": "s", "flow_sensed": "g/s", "flow_true": "g/s"}
    np.testing.assert_array_equal(arrays["flow_true"], 2.0 * np.arange(50))
    header = (tmp_path / "traces.csv").read_text().splitlines()[0]
    assert header == "time_s [s],flow_sensed [g/s],flow_true [g/s]"
    for name in ("bus.log", "bus.asc"):
        frames = list(can.LogReader(tmp_path / name))
        assert len(frames) == 50 and frames[3].arbitration_id == 0x181
        assert frames[3].timestamp == pytest.approx(0.03)


def test_an_exception_keeps_everything_recorded_so_far(tmp_path: Path) -> None:
    with pytest.raises(ZeroDivisionError), Recorder(tmp_path) as rec:
        _fill(rec, 20)
        _ = 1 / 0
    record = json.loads((tmp_path / "record.json").read_text())
    assert record["verdict"] == "error" and "ZeroDivisionError" in record["error"]
    assert load_traces(tmp_path / "traces.npz")[0]["flow_sensed"].size == 20
    assert len(list(can.LogReader(tmp_path / "bus.log"))) == 20


def test_verdicts(tmp_path: Path) -> None:
    with Recorder(tmp_path / "a") as rec:
        rec.measure(Measurement("x", 9.0, "%", high=5.0))
        rec.measure(Measurement("y", 1.0, "%", high=5.0))
    assert rec.record()["verdict"] == "fail"
    with Recorder(tmp_path / "b") as rec:
        rec.measure(Measurement("x", 9.0, "%", high=5.0))
        rec.timing = TimingHealth.from_lateness(
            np.full(100, 0.01), period_s=1e-3, scheduler="x", limits=TimingLimits(),
            miss_threshold_s=5e-4, stall_threshold_s=2e-3)
    assert rec.record()["verdict"] == "invalid-bench"  # bench timing outranks a DUT failure
    with Recorder(tmp_path / "c") as rec:
        pass
    assert rec.record()["verdict"] == "no-measurements"


def test_traces_refuse_bad_use() -> None:
    rec = Recorder.__new__(Recorder)
    from hil.record.traces import TraceSet
    traces = TraceSet()
    traces.declare("a", "V")
    with pytest.raises(TraceError):
        traces.declare("a", "V")
    with pytest.raises(TraceError):
        traces.append(0.0, [1.0, 2.0])
    traces.append(0.0, [1.0])
    with pytest.raises(TraceError):
        traces.declare("b", "V")
    del rec


def test_sigterm_through_the_cli_flushes(tmp_path: Path) -> None:
    script = textwrap.dedent(f"""
        import signal, sys, time, can
        from hil.cli.main import _on_sigterm
        from hil.record import Recorder
        signal.signal(signal.SIGTERM, _on_sigterm)
        with Recorder({str(tmp_path)!r}) as rec:
            rec.traces.declare("x", "1")
            for i in range(10):
                rec.traces.append(i, [i])
            print("recording", flush=True)
            time.sleep(30)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "recording"
    proc.send_signal(signal.SIGTERM)
    proc.wait(10)
    record = json.loads((tmp_path / "record.json").read_text())
    assert record["verdict"] == "aborted"
    assert load_traces(tmp_path / "traces.npz")[0]["x"].size == 10
