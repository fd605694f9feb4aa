"""The conformance building blocks on their own: the candump reader against python-can's, the
bit count against the software bus's, the interval and latency arithmetic, the contract read
from the shipped databases."""

from __future__ import annotations

import can
import numpy as np
import pytest
from can.io.canutils import CanutilsLogWriter

from hil.conformance import checks
from hil.conformance.declared import build_contract
from hil.conformance.framelog import parse_candump, read_bus_log
from hil.conformance.rigs import rig_bus
from hil.errors import ConfigError
from hil.softbus.timing import frame_bits


def _log_text(tmp_path, frames: list[tuple[float, int, bool, bytes, bool]]) -> bytes:
    path = tmp_path / "bus.log"
    writer = CanutilsLogWriter(path)
    for t, can_id, ext, data, rx in frames:
        writer.on_message_received(can.Message(timestamp=t, arbitration_id=can_id,
                                               is_extended_id=ext, data=data, is_rx=rx,
                                               channel="can0"))
    writer.stop()
    return path.read_bytes()


def _random_frames(n: int, seed: int = 3) -> list[tuple[float, int, bool, bytes, bool]]:
    rng = np.random.default_rng(seed)
    out = []
    t = 0.0
    for _ in range(n):
        t += float(rng.uniform(0, 0.02))
        ext = bool(rng.random() < 0.5)
        can_id = int(rng.integers(0, 1 << 29 if ext else 1 << 11))
        data = bytes(rng.integers(0, 256, int(rng.integers(0, 9)), dtype=np.uint8))
        out.append((round(t, 6) + 1000.0 * (rng.random() < 0.01), can_id, ext, data,
                    bool(rng.random() < 0.5)))
    out.sort()
    return out


def test_the_vectorised_reader_reads_what_python_can_wrote(tmp_path) -> None:
    frames = _random_frames(3000)
    log = parse_candump(_log_text(tmp_path, frames))
    assert len(log) == len(frames)
    assert log.can_id.tolist() == [f[1] for f in frames]
    assert log.extended.tolist() == [f[2] for f in frames]
    assert log.dlc.tolist() == [len(f[3]) for f in frames]
    assert log.rx.tolist() == [f[4] for f in frames]
    assert [bytes(row[:n]) for row, n in zip(log.data, log.dlc, strict=True)] == \
        [f[3] for f in frames]
    np.testing.assert_allclose(log.time_s, [f[0] for f in frames], atol=1e-6)


def test_keeping_rx_and_sync_keeps_exactly_those(tmp_path) -> None:
    frames = [*_random_frames(500), (2000.0, 0x080, False, b"", False)]
    text = _log_text(tmp_path, frames)
    everything, kept = parse_candump(text), parse_candump(text, keep="rx+sync")
    want = everything.rx | ((everything.can_id == 0x080) & ~everything.extended)
    assert kept.can_id.tolist() == everything.can_id[want].tolist()
    assert kept.time_s.tolist() == everything.time_s[want].tolist()


def test_remote_and_odd_lines_take_the_line_path(tmp_path) -> None:
    text = (b"(0.000000) can0 710#00 R\n(0.100000) can0 123#R T\n"
            b"(0.200000) can0 0CFE49F0#0102 R\n")
    log = parse_candump(text)
    assert log.can_id.tolist() == [0x710, 0x0CFE49F0]      # the remote frame is no data frame
    assert log.time_s.tolist() == [0.0, 0.2]


def test_a_broken_log_is_an_error_naming_the_file_and_line(tmp_path) -> None:
    path = tmp_path / "bus.log"
    path.write_bytes(b"(0.000000) can0 710#00 R\nthis is not candump\n")
    with pytest.raises(ConfigError, match=r"bus.log.*line 2"):
        read_bus_log(path)
    with pytest.raises(ConfigError, match="cannot read the bus log"):
        read_bus_log(tmp_path / "missing.log")


def test_bit_counts_are_the_software_bus_s(tmp_path) -> None:
    frames = _random_frames(400, seed=9)
    frames += frames[:50]                    # repeats are counted once per frame, too
    log = parse_candump(_log_text(tmp_path, sorted(frames)))
    want = sum(frame_bits(f[1], f[2], f[3]) for f in frames)
    assert checks.total_bits(log) == want


def test_intervals_stay_within_a_power_up() -> None:
    t = np.array([0.0, 0.1, 0.2, 5.0, 5.1])
    segment = np.array([1, 1, 1, 2, 2])
    assert checks.intervals(t, segment).round(6).tolist() == [0.1, 0.1, 0.1]


def test_cycle_stats_band_and_resolution() -> None:
    gaps = np.array([0.1, 0.1, 0.112, 0.1, 0.05])
    strict = checks.cycle_stats(gaps, 100.0, -10, 10, 0.0)
    assert (strict.outside, strict.median_ms, strict.min_ms) == (2, 100.0, 50.0)
    loose = checks.cycle_stats(gaps, 100.0, -10, 10, 5.0)
    assert loose.outside == 1                          # 112 ms is within 110 + 5
    assert checks.cycle_stats(np.zeros(0), 100.0, -10, 10, 0.0).count == 0


def test_sync_latency_is_the_first_command_after_each_sync() -> None:
    sync = np.array([0.0, 0.01, 0.02, 0.03])
    commands = np.array([0.004, 0.005, 0.019, 0.031])
    assert (checks.sync_latency(sync, commands) * 1000).round(3).tolist() == [4.0, 9.0, 11.0,
                                                                              1.0]


def test_fertilizer_contract_from_the_shipped_databases() -> None:
    contract = build_contract(rig_bus("fertilizer"), node_id=0x10, heartbeat_period_ms=100,
                              control_period_ms=100, command_ids=frozenset({0x220}))
    frames = contract.frames
    assert contract.node_name == "Controller"
    assert frames[(0x220, False)].cycle_ms == 100 and frames[(0x220, False)].dlc == 4
    assert frames[(0x190, False)].cycle_ms == 1000
    assert frames[(0x710, False)].cycle_ms == 100
    assert (0x620, False) in frames and (0x590, False) in frames      # SDO, CiA 301
    assert (0x210, False) not in frames        # the terminal's setpoint is not the DUT's
    assert [(c.name, c.time_ms) for c in contract.consumers] == [("analog output module",
                                                                  300.0)]
    assert not any(f.note for f in frames.values()), "databases and profile disagree"


def test_depth_contract_takes_the_drive_pdos_from_its_eds() -> None:
    contract = build_contract(rig_bus("sowing_depth"), node_id=1, heartbeat_period_ms=100,
                              control_period_ms=10, command_ids=frozenset({0x202, 0x302}))
    frames = contract.frames
    assert contract.node_name == "DepthController"
    assert (frames[(0x302, False)].dlc, frames[(0x302, False)].cycle_ms) == (6, 10)
    assert (frames[(0x402, False)].dlc, frames[(0x402, False)].cycle_ms) == (1, None)
    assert frames[(0x000, False)].dlc == 2                  # NMT: the drive's master
    assert (0x701, False) in frames                         # heartbeat, CiA 301
    assert frames[(0x18FF3080, True)].cycle_ms == 100
    assert contract.consumers == ()


def test_every_frame_the_fertilizer_rig_sends_is_in_its_dbc() -> None:
    """issue 20.6: cantools decode knows every frame of a fertilizer run (the runs themselves
    are checked in test_discrimination_bus.py)."""
    import cantools

    from plant_emulators.fertilizer.config import load_rig_config

    cfg = load_rig_config()
    ids = {m.frame_id for m in cantools.database.load_file(cfg.wiring.dbc_file).messages}
    for node in (*cfg.wiring.flow_module_node_ids, cfg.wiring.ground_speed_node_id,
                 cfg.wiring.analog_output_node_id, cfg.wiring.dut_node_id):
        assert 0x700 + node in ids, f"heartbeat 0x{0x700 + node:X} not in the DBC"


def test_the_fertilizer_dut_may_not_send_nmt() -> None:
    """The fertilizer rig is the NMT master (the DBC's NmtMaster sends NMT and SYNC)."""
    contract = build_contract(rig_bus("fertilizer"), node_id=0x10, heartbeat_period_ms=100,
                              control_period_ms=100)
    assert (0x000, False) not in contract.frames and (0x080, False) not in contract.frames


def _synthetic(frames: list[tuple[float, int, bool, bytes, bool]]):
    from hil.conformance.framelog import FrameLog

    return FrameLog(np.array([f[0] for f in frames]), np.array([f[1] for f in frames]),
                    np.array([f[2] for f in frames]), np.array([len(f[3]) for f in frames]),
                    np.array([f[4] for f in frames]),
                    np.array([list(f[3].ljust(8, b"\0")) for f in frames], dtype=np.uint8))


def _judge(frames, **kw):
    from hil.conformance.measure import judge
    from hil.dut.profile import load_profile

    profile = load_profile("dut_profiles/fertilizer-piecewise-pid-daemon.toml")
    contract = build_contract(rig_bus("fertilizer"), node_id=0x10, heartbeat_period_ms=100,
                              control_period_ms=100, command_ids=frozenset({0x220}))
    found = judge(_synthetic(frames), contract, profile, physics_period_s=0.001, **kw)
    return {(m.name, m.conditions.get("message")): m for m in found.measurements}


def _good_power_up(t0: float, steps: int) -> list[tuple[float, int, bool, bytes, bool]]:
    out = [(t0, 0x710, False, b"\x00", True)]
    for k in range(steps):
        t = t0 + 0.1 * k
        out += [(t, 0x080, False, b"", False), (t + 0.003, 0x220, False, b"\1\2\3\4", True),
                (t + 0.003, 0x710, False, b"\x05", True)]
    return out


def test_judge_counts_restarts_and_leaves_other_nodes_traffic_out() -> None:
    frames = _good_power_up(0.0, 30) + _good_power_up(5.0, 30)
    frames += [(0.05 * k, 0x0CF00401, True, bytes(8), True) for k in range(100)]  # bus load
    got = _judge(sorted(frames, key=lambda f: f[0]), clock="realtime", restarts=1,
                 duration_s=8.0, foreign=np.array([0x0CF00401 + (1 << 32)]), bus_load=0.5)
    assert all(m.outcome.value in ("pass", "info") for m in got.values()), \
        [(k, m.value, m.note) for k, m in got.items() if m.outcome.value == "fail"]
    assert got[("bus.bootup.unexpected", None)].value == 0
    assert got[("bus.undeclared_frames", None)].value == 0
    assert got[("bus.sync_latency.p99", None)].high is None        # a loaded bus: recorded
    assert abs(got[("bus.sync_latency.p50", None)].value - 3.0) < 1e-6


def test_judge_fails_what_a_defect_breaks() -> None:
    frames = [(0.0, 0x220, False, b"\0\0\0\0", True), *_good_power_up(0.0, 30)]
    frames += [(0.05, 0x7F0, False, b"\1", True), (1.0, 0x710, False, b"\x00", True)]
    frames += [(1.2, 0x220, False, bytes(8), True)]
    got = _judge(sorted(frames, key=lambda f: f[0]), clock="lockstep", restarts=0,
                 duration_s=3.0)
    assert got[("bus.bootup.frames_before", None)].value == 1
    assert got[("bus.bootup.unexpected", None)].value == 1
    assert got[("bus.undeclared_frames", None)].value == 1
    assert "0x7F0 (1)" in got[("bus.undeclared_frames", None)].note
    assert got[("bus.dlc_errors", "AnalogOutputCommand")].value == 1
    for key in (("bus.bootup.frames_before", None), ("bus.bootup.unexpected", None),
                ("bus.undeclared_frames", None), ("bus.dlc_errors", "AnalogOutputCommand")):
        assert got[key].outcome.value == "fail", key


# --- the measurements no bus-defect profile fails, failed on synthetic logs (issue 21's rule:
# tests/test_suites_coverage.py lists these tests in SYNTHETIC) -----------------------------
def test_judge_fails_a_dut_that_takes_too_much_of_the_bus() -> None:
    """A command sent every 1 ms instead of every 100 ms: ~1,000 frames/s of a 250 kbit/s bus."""
    frames = _good_power_up(0.0, 30)
    frames += [(0.001 * k, 0x220, False, b"\1\2\3\4", True) for k in range(1, 3000)]
    got = _judge(sorted(frames, key=lambda f: f[0]), clock="lockstep", restarts=0,
                 duration_s=3.0)
    share = got[("bus.share", None)]
    assert share.value > 10.0 and share.outcome.value == "fail", (share.value, share.note)


def test_judge_fails_a_heartbeat_gap_longer_than_the_consumer_time() -> None:
    """Heartbeats every 100 ms, but none for 0.6 s in the middle: the analog module (consumer
    time 300 ms) would fall back to 0 V."""
    frames = [f for f in _good_power_up(0.0, 30)
              if not (f[1] == 0x710 and 1.0 < f[0] < 1.6)]
    got = _judge(frames, clock="lockstep", restarts=0, duration_s=3.0)
    gaps = [m for (name, _), m in got.items() if name == "bus.heartbeat.max_interval"]
    assert gaps, "no consumer of the DUT's heartbeat was judged"
    assert all(m.value > 300 and m.outcome.value == "fail" for m in gaps), \
        [(m.value, m.high, m.conditions) for m in gaps]


def test_judge_fails_a_dut_that_misses_sync_answers_in_real_time() -> None:
    """In real time a DUT that answers only every third SYNC: the commands of the other two
    come a period late, beyond the control period's p99 limit."""
    frames = [(0.0, 0x710, False, b"\x00", True)]
    for k in range(60):
        t = 0.1 * k
        frames.append((t, 0x080, False, b"", False))
        frames.append((t + 0.003, 0x710, False, b"\x05", True))
        if k % 3 == 0:
            frames.append((t + 0.003, 0x220, False, b"\1\2\3\4", True))
    got = _judge(frames, clock="realtime", restarts=0, duration_s=6.0)
    p99 = got[("bus.sync_latency.p99", None)]
    assert p99.high is not None and p99.value > p99.high and p99.outcome.value == "fail", \
        (p99.value, p99.high)


def test_a_physical_ecu_is_not_blamed_for_a_power_up_the_rig_did_not_see() -> None:
    """The rig does not power a physical ECU: joined after its boot-up, its traffic is not
    'before boot-up'; a second boot-up during the run is still an unexpected restart."""
    from hil.conformance.measure import judge
    from hil.dut.profile import load_profile

    profile = load_profile("dut_profiles/physical/fertilizer-physical-ecu.toml")
    contract = build_contract(rig_bus("fertilizer"), node_id=0x10, heartbeat_period_ms=100,
                              control_period_ms=100, command_ids=frozenset({0x220}))
    already_up = [f for f in _good_power_up(0.0, 30) if f[3] != b"\x00"]   # no boot-up seen

    def judged(frames):
        found = judge(_synthetic(sorted(frames, key=lambda f: f[0])), contract, profile,
                      physics_period_s=0.001, clock="realtime", restarts=0, duration_s=3.0)
        return {m.name: m for m in found.measurements if m.name.startswith("bus.bootup")}

    got = judged(already_up)
    assert got["bus.bootup.frames_before"].high is None
    assert got["bus.bootup.unexpected"].outcome.value == "pass"
    twice = judged([*already_up, (1.0, 0x710, False, b"\x00", True),
                    (2.0, 0x710, False, b"\x00", True)])
    assert twice["bus.bootup.unexpected"].outcome.value == "fail"
