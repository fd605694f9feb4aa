"""Bus load: the schedule's arithmetic, the wire load read back from a log, and a loaded run."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import can
import pytest

from hil.dut import InProcessDut
from hil.errors import ConfigError
from hil.rig import RunOptions, Scenario, run_scenario
from hil.rig.busload import LOAD_MIX, load_schedule, offered_load, wire_load
from hil.rig.runner import bus_load_refusal
from hil.softbus.timing import frame_bits

from .toy import ToyController, ToyRig

LOADED = Scenario(name="loaded", description="", rig="toy", duration_s=1.0,
                  initial={"setpoint": 1.0}, bus_load=0.5)


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.75, 0.95])
def test_schedule_offers_the_fraction_asked(fraction: float) -> None:
    schedule = load_schedule(fraction, 250_000)
    assert offered_load(schedule, 250_000) == pytest.approx(fraction, rel=1e-12)
    assert [f.arbitration_id for f in schedule] == [i for i, _ in LOAD_MIX]
    # 0.75 of 250 kbit/s in ~134-bit frames: one every ~0.7 ms across the four
    total_rate = sum(1 / f.period_s for f in schedule)
    assert total_rate == pytest.approx(fraction * 250_000 / 134.25, rel=0.02)


def test_half_the_load_outranks_the_rigs_11_bit_frames() -> None:
    base_ids = [i >> 18 for i, _ in LOAD_MIX]          # the 11 bits arbitration compares first
    # priority 1 beats the sensors (0x181-0x185), the DUT's command (0x220), the rig's
    # priority-3 J1939 frames (base 0x33C and up), but not SYNC (0x080)
    assert sum(0x080 < b < 0x181 for b in base_ids) == 2
    assert sum(b > 0x33C for b in base_ids) == 2        # priority 6: waits behind them


@pytest.mark.parametrize("fraction", [0.0, 1.0, -0.1, 1.5])
def test_schedule_refuses_impossible_loads(fraction: float) -> None:
    with pytest.raises(ValueError, match="fraction"):
        load_schedule(fraction, 250_000)


def test_wire_load_of_a_known_log(tmp_path: Path) -> None:
    log = tmp_path / "bus.log"
    msg_bits = frame_bits(0x18FF1080, True, bytes(8))
    with can.Logger(str(log)) as writer:
        for k in range(101):                            # one frame per ms for 0.1 s
            writer.on_message_received(can.Message(timestamp=10.0 + k * 1e-3,
                                                   arbitration_id=0x18FF1080,
                                                   is_extended_id=True, data=bytes(8)))
    # 101 frames over 0.1 s at 250 kbit/s
    assert wire_load(str(log), 250_000) == pytest.approx(101 * msg_bits / 250_000 / 0.1,
                                                          rel=1e-6)


def test_scenario_checks_its_bus_load() -> None:
    with pytest.raises(ConfigError, match="bus_load"):
        replace(LOADED, bus_load=1.2)


@pytest.mark.parametrize(("bus", "clock", "why"), [
    ("softbus", "lockstep", "realtime clock"),
    ("inline", "realtime", "bit rate"),
    ("virtual", "realtime", "bit rate"),
    ("socketcan:vcan0", "realtime", "vcan"),
])
def test_runner_refuses_a_bus_that_cannot_carry_load(tmp_path: Path, bus: str, clock: str,
                                                     why: str) -> None:
    assert why in (bus_load_refusal(bus, clock) or "")
    with pytest.raises(ConfigError, match="bus_load") as err:
        run_scenario(ToyRig, LOADED, InProcessDut(ToyController()),
                     RunOptions(out_dir=tmp_path, bus=bus, clock=clock))
    assert why in str(err.value)


def test_paced_buses_carry_load() -> None:
    assert bus_load_refusal("softbus", "realtime") is None
    assert bus_load_refusal("socketcan:can0", "realtime") is None
    assert bus_load_refusal("pcan:PCAN_USBBUS1,bitrate=250000", "realtime") is None


def test_loaded_run_logs_the_load_and_does_not_count_it_as_the_dut(tmp_path: Path) -> None:
    # the DUT may send at most 5 frames per control period: the load's ~90 per period must
    # not count against it
    result = run_scenario(ToyRig, LOADED, InProcessDut(ToyController()),
                          RunOptions(out_dir=tmp_path, bus="softbus", clock="realtime",
                                     max_dut_frames_per_period=5))
    assert result.record["error"] is None
    assert result.record["bus_load"]["fraction"] == 0.5
    assert result.record["softbus"]["bitrate"] == ToyRig.bitrate_bps
    ids = {m.arbitration_id for m in can.LogReader(str(tmp_path / "bus.log"))}
    assert {i for i, _ in LOAD_MIX} <= ids
    assert wire_load(str(tmp_path / "bus.log"), ToyRig.bitrate_bps) > 0.0


def test_stopped_load_sends_nothing_more() -> None:
    from hil.rig.busload import BusLoad

    with can.Bus(interface="virtual", channel="busload-stop") as bus:
        load = BusLoad(bus, 0.5, 250_000).start()
        threads = [t.thread for t in load._tasks]   # python-can's cyclic send threads
        load.stop()
        assert not any(t.is_alive() for t in threads)
