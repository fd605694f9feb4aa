"""What both bus-load suites do first: run the scenario in real time on a loaded bus, or skip.

Load needs real time and a wire with a bit rate (:func:`hil.rig.runner.bus_load_refusal`): on a
bus without one (``inline``, ``virtual``, kernel ``vcan``) the suite is skipped with that reason,
never judged. The load actually carried is read back from the run's bus log.
"""

from __future__ import annotations

import pytest

from hil.rig import RunResult
from hil.rig.busload import wire_load
from hil.rig.runner import bus_load_refusal


def run_on_loaded_bus(hil_session, hil_run, hil_rig, scenario: str) -> tuple[RunResult, float]:
    """``(result, fraction of the bit rate on the wire over the run)``; skips the test when
    the session's bus cannot carry a load."""
    why = bus_load_refusal(hil_session.bus, "realtime")
    if why:
        pytest.skip(f"bus load {why}")
    result = hil_run(scenario, clock="realtime")
    return result, wire_load(str(result.out_dir / "bus.log"), hil_rig.bitrate_bps)
