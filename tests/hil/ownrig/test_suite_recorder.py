"""The own-rig suites record a limit taken from the rig file with that source, and leave a
profile's limit as the profile's."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

from hil.limits import MEASUREMENTS
from hil.ownrig.rig import rig_class
from test_suites.own_rig.judge import Recorder


class Session:
    def __init__(self) -> None:
        self.measurements: list[dict[str, Any]] = []


def test_limit_sources(motor_rig_file: Path) -> None:
    plan = rig_class(motor_rig_file).plan()
    session = Session()
    sources = iter(["catalogue", "profile"])

    def measure(name: str, value: float, **kw: Any) -> Any:
        source = next(sources)
        session.measurements.append({"name": name, "limit_source": source})
        return SimpleNamespace(limit_source=source)

    record = Recorder(plan, session, measure)
    c = plan.controlled["speed"]
    record(c, "step.response_time", 0.6, run=None, scenario="speed-step-1")
    record(c, "step.response_time", 0.6, run=None, scenario="speed-step-2")
    assert [m["limit_source"] for m in session.measurements] == [
        "rig file motor-meter.rig.toml [controlled.speed.limits.response_time_s]", "profile"]
    spec = MEASUREMENTS["motor_meter.speed.step.response_time"]
    assert spec.high == 1.2 and spec.rig == "motor_meter" and spec.unit == "s"
