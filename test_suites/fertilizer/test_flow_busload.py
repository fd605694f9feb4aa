"""Bench accuracy on a bus loaded near its bit rate (real time).

The DUT runs [F]'s 1,700 g bench run while other ECUs' traffic fills ~75 % of the 250 kbit/s
(``bench-busload-1700``; half of it outranks every rig and DUT frame): its command frames and
the sensors' reports queue in arbitration, as on a busy tractor bus. The run is real time even
in a lockstep qualification: lockstep time has no wire to load. The load actually carried is
read back from the bus log and stated in the measurement's note.
"""

from __future__ import annotations

import pytest

from hil.metrics import accuracy_theta
from hil.rig.busload import wire_load
from hil.rig.runner import bus_load_refusal
from test_suites.fertilizer.traces import delivered_and_target_g

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("busload")]

SCENARIO = "bench-busload-1700"


def test_accuracy_on_a_loaded_bus(hil_session, hil_run, hil_measure, hil_rig) -> None:
    why = bus_load_refusal(hil_session.bus, "realtime")
    if why:
        pytest.skip(f"bus load {why}")
    result = hil_run(SCENARIO, clock="realtime")
    delivered, target = delivered_and_target_g(result)
    load = wire_load(str(result.out_dir / "bus.log"), hil_rig.bitrate_bps)
    hil_measure("flow.busload.accuracy", accuracy_theta(target, delivered), run=result,
                conditions={"bus_load_pct": round(100 * result.record["bus_load"]["fraction"])},
                note=f"weighed {delivered:.1f} g of {target:.1f} g; {100 * load:.1f} % of the "
                     f"bit rate on the wire over the run")
