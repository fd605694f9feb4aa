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
from test_suites.fertilizer.traces import delivered_and_target_g
from test_suites.loaded_bus import run_on_loaded_bus

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("busload")]

SCENARIO = "bench-busload-1700"


def test_accuracy_on_a_loaded_bus(hil_session, hil_run, hil_measure, hil_rig) -> None:
    result, load = run_on_loaded_bus(hil_session, hil_run, hil_rig, SCENARIO)
    delivered, target = delivered_and_target_g(result)
    hil_measure("flow.busload.accuracy", accuracy_theta(target, delivered), run=result,
                conditions={"bus_load_pct": round(100 * result.record["bus_load"]["fraction"])},
                note=f"weighed {delivered:.1f} g of {target:.1f} g; {100 * load:.1f} % of the "
                     f"bit rate on the wire over the run")
