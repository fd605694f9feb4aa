"""Synthetic qualification records for the gate's tests, built from real Measurement objects."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hil.measurements import Measurement

DUT = "fertilizer-piecewise-pid-firmware"


def step_time(value: float, target: int = 23) -> Measurement:
    return Measurement("flow.step.response_time", value, "s", high=1.5,
                       conditions={"target_gps": target, "sensor": "sliding"})


def overshoot(value: float, target: int = 23) -> Measurement:
    return Measurement("flow.step.overshoot", value, "%", high=10.0,
                       conditions={"target_gps": target})


def bench_accuracy(value: float) -> Measurement:
    return Measurement("flow.bench.accuracy", value, "%", low=90.0,
                       conditions={"target_g": 1700})


def depth_mean(value: float) -> Measurement:
    return Measurement("depth.field.mean", value, "mm", low=20.0, high=40.0,
                       conditions={"speed_band": "3-5"})


def lateness(value: float) -> Measurement:
    return Measurement("rig.timing.lateness_p99", value, "us")


def good() -> list[Measurement]:
    """A build that passes every limit with room to spare."""
    return [step_time(1.10), step_time(1.00, target=44), overshoot(3.0), bench_accuracy(97.0),
            depth_mean(30.2), lateness(12.0)]


def record(measurements: list[Measurement], *, verdict: str | None = None, dut: str = DUT,
           run_id: str = "3f2a9c1b7d10", **extra: Any) -> dict[str, Any]:
    """A record as ``hil qualify`` documents it; the verdict follows the measurements unless
    given."""
    items = [m.to_dict() for m in measurements]
    if verdict is None:
        verdict = "fail" if any(i["outcome"] in ("fail", "error") for i in items) else "pass"
    data: dict[str, Any] = {
        "schema": "agrihil.qualification/1", "run_id": run_id,
        "started_at": "2026-11-22T10:00:00+00:00", "wall_s": 41.2, "verdict": verdict,
        "dut": {"name": dut, "version": "1.0.0", "build_id": "b-0001", "kind": "firmware",
                "rig": "fertilizer", "controller": "piecewise-pid",
                "profile": f"dut_profiles/{dut}.toml", "profile_sha256": "0" * 64},
        "rig": {"name": "fertilizer", "config_sha256": "1" * 64},
        "bus": "softbus", "clock": "lockstep", "seed": 1, "suites": ["fast"],
        "versions": {"agrihil": "0.1.0", "python": "3.11.9"},
        "limits": {m.name: {"low": m.low, "high": m.high, "unit": m.unit} for m in measurements
                   if m.low is not None or m.high is not None},
        "measurements": items,
        "tests": [], "runs": [], "timing": {"mode": "lockstep"},
    }
    data.update(extra)
    return data


def write(path: Path, data: Any) -> Path:
    path.write_text(json.dumps(data), encoding="utf-8")
    return path
