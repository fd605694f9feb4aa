"""The network as a device of a real rig run: the runner's loop, lockstep and real time."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import can
import pytest

from hil.dut import InProcessDut
from hil.isobus.can_id import decode_id, encode_id
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.tecu import TECU_NAME, TractorEcu, TractorState, add_tecu
from hil.rig import RigContext, RunOptions, Scenario, run_scenario

_spec = importlib.util.spec_from_file_location(
    "agrihil_toy_rig", Path(__file__).resolve().parents[1] / "rig" / "toy.py")
assert _spec is not None and _spec.loader is not None
toy = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(toy)

SCENARIO = Scenario(name="isobus", description="the toy rig with a tractor ECU", rig="toy",
                    duration_s=2.0, seed=1, initial={"setpoint": 0.5})
LOWER_THAN_TECU = IsobusName(identity_number=1, function=1)


class IsobusToyRig(toy.ToyRig):
    """The toy rig plus an ISOBUS network carrying a TECU that reports the setpoint as speed."""

    last: IsobusToyRig | None = None

    def __init__(self, ctx: RigContext) -> None:
        super().__init__(ctx)
        self.network = IsobusNetwork()
        self.tecu: TractorEcu = add_tecu(self.network,
                                         lambda t: TractorState(ground_speed_mps=self.setpoint))
        self.devices = [*self.devices, self.network]
        IsobusToyRig.last = self


class ContendingController(toy.ToyController):
    """The toy P controller that also claims 0x80 with a lower NAME when it hears a claim."""

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.is_extended_id and decode_id(msg.arbitration_id).pgn == 0xEE00 \
                and msg.arbitration_id & 0xFF == 0x80:
            return [can.Message(arbitration_id=encode_id(6, 0xEE00, 0x80),
                                data=LOWER_THAN_TECU.to_bytes(), is_extended_id=True)]
        return super().on_frame(msg)


def sent(rig: IsobusToyRig) -> list[tuple[float, int]]:
    return [(round(t, 6), m.arbitration_id) for t, d, m in rig.network.log if d == "tx"]


def test_tecu_runs_in_the_lockstep_loop(tmp_path: Path) -> None:
    result = run_scenario(IsobusToyRig, SCENARIO, InProcessDut(toy.ToyController()),
                          RunOptions(out_dir=tmp_path, bus="virtual", clock="lockstep",
                                     step_timeout_s=0.5))
    assert result.record["error"] is None
    rig = IsobusToyRig.last
    assert rig is not None
    frames = sent(rig)
    assert frames[0] == (0.0, 0x18EEFF80)
    wheel = [t for t, i in frames if i == 0x0CFE4880]
    assert wheel == [round(0.25 + 0.1 * k, 6) for k in range(18)]
    assert rig.tecu.sent == 18


def test_a_dut_taking_the_tecus_address_gets_it_through_the_runner(tmp_path: Path) -> None:
    run_scenario(IsobusToyRig, SCENARIO, InProcessDut(ContendingController()),
                 RunOptions(out_dir=tmp_path, bus="virtual", clock="lockstep",
                            step_timeout_s=0.5))
    rig = IsobusToyRig.last
    assert rig is not None
    ids = [i for _, i in sent(rig)]
    assert ids == [0x18EEFF80, 0x18EEFFFE]         # claim, then cannot-claim: nothing else
    assert rig.network.external() == {0x80: LOWER_THAN_TECU.value}
    assert rig.network.functions[0].name == TECU_NAME


@pytest.mark.realtime
def test_tecu_runs_in_real_time_unchanged(tmp_path: Path) -> None:
    result = run_scenario(IsobusToyRig, SCENARIO, InProcessDut(toy.ToyController()),
                          RunOptions(out_dir=tmp_path, bus="virtual", clock="realtime",
                                     step_timeout_s=0.5))
    assert result.record["error"] is None
    rig = IsobusToyRig.last
    assert rig is not None
    wheel = [t for t, i in sent(rig) if i == 0x0CFE4880]
    # the real-time loop runs the device on its physics ticks: same schedule, to a tick
    assert len(wheel) == 18
    assert all(abs(t - (0.25 + 0.1 * k)) < 0.011 for k, t in enumerate(wheel))
