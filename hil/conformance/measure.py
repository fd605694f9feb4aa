"""Bus conformance of one run as measurements, with limits from the profile or the defaults.

:func:`run_conformance` reads the run's ``bus.log`` (the frames the rig received are the
DUT's; a bus-load generator's frames are left out) and ``bus-unheard.log`` (the DUT's frames a
fault kept from the rig, a cut wire: never received, so in no bus log), checks them against the
DUT's
:class:`~hil.conformance.declared.BusContract` and returns the measurements and a detail
table (written as ``conformance.json`` beside the run's record, for the report).

Default limits (a profile's ``[limits]`` table overrides any of them by name):

======================================  ===============================================
``bus.undeclared_frames``               high 0
``bus.dlc_errors``                      high 0 (per message)
``bus.cycle_time.median``               -10 % … +10 % of the declared cycle (per message)
``bus.cycle_time.outside_band``         high 5 % of the intervals (per message; lockstep)
``bus.heartbeat.period``                -10 % … +10 % of ``timing.heartbeat_period_ms``
``bus.heartbeat.max_interval``          high: the consumer's heartbeat time (per consumer);
                                        without a consumer on the rig, the rig's own monitor
                                        at 2 x ``timing.heartbeat_period_ms``; the gap from the
                                        last heartbeat to the end of the run counts
``bus.bootup.frames_before``            high 0
``bus.bootup.unexpected``               high 0
``bus.share``                           high 10 % of the bit rate
``bus.sync_latency.p50``                none (recorded)
``bus.sync_latency.p99``                high: the control period + 10 % + one physics step
                                        (none on a bus loaded with other traffic)
``bus.sync_latency.max``                none (recorded)
======================================  ===============================================

Frames a fault kept from the rig (a cut wire) are judged as what they are: not received. They
count for nothing (not in the bus share, no cycle, no heartbeat, no answer to a SYNC), and the
gap they leave is the fault's, not the DUT's: an interval across them (cycle, heartbeat) is not
judged, the heartbeat's last gap ends at the first of them, and a SYNC they answered first has
no latency. The detail table says how many there were and how many intervals were left out.

The cycle-time band of each interval is the median's limits widened by the resolution of the
rig's time stamps: in real time the rig reads the bus once per physics step (1 ms); in
lockstep a frame that is not a command (status, heartbeat) is read once per control period.
In real time the share of intervals outside the band gets no default limit: the intervals the
rig sees carry the bench's own time-stamping jitter (the rig polls the bus, through the
software bus's process), a few ms on a loaded host, as much as a 10 ms cycle's band; the
median, the heartbeat and the latency's 99th percentile are judged.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hil.conformance import checks
from hil.conformance.declared import BusContract, DeclaredFrame, build_contract
from hil.conformance.framelog import FrameLog, read_bus_log
from hil.conformance.isobus import isobus_conformance, isobus_frames
from hil.conformance.rigs import rig_bus
from hil.dut.profile import DutProfile, database_path
from hil.errors import ConfigError
from hil.isobus.vt.conformance import vt_client_conformance
from hil.limits import MEASUREMENTS
from hil.measurements import Measurement
from hil.record.buslog import UNHEARD_NAME

SYNC_ID = 0x080
CYCLE_TOLERANCE_PCT = 10.0
OUTSIDE_BAND_PCT = 5.0
HEARTBEAT_TOLERANCE_PCT = 10.0
#: Without a node of the rig that consumes the DUT's heartbeat (object 0x1016 of an EDS), the rig
#: monitors it as a CiA 301 heartbeat consumer would: CiA 301 only requires a consumer time
#: longer than the producer time; twice the declared period is the usual setting (one lost or
#: late heartbeat tolerated, two not), so a node that falls silent is caught within two periods
#: whatever the rig's devices do with its heartbeat.
RIG_MONITOR_FACTOR = 2.0
BUS_SHARE_PCT = 10.0
#: where the detail table goes, beside the run's record.json
DETAIL_FILE = "conformance.json"


@dataclass
class Conformance:
    """What :func:`run_conformance` found: the measurements and the per-message table."""

    measurements: list[Measurement] = field(default_factory=list)
    detail: dict[str, Any] = field(default_factory=dict)


def contract_of(profile: DutProfile, *, root: Path | None = None) -> BusContract:
    """The bus contract of ``profile``'s DUT on its rig (``wiring.database`` resolved against
    the current directory, then against ``root``, the project's root by default).

    Raises
    ------
    ConfigError
        Unknown rig, or a database that cannot be found or read (named).
    """
    try:
        rig = rig_bus(profile.dut.rig, profile.rig_config, str(profile.path or ""))
    except KeyError as exc:
        raise ConfigError(str(exc.args[0]), path=str(profile.path or ""),
                          key="dut.rig") from exc
    database = None
    if profile.wiring.database:
        database = Path(profile.wiring.database)
        if not database.is_absolute() and not database.exists():
            base = root or Path(__file__).resolve().parents[2]
            database = base / database
        if not database.exists() and profile.path is not None:
            # as hil profile check reads it (hil.dut.profile.database_path): beside the profile
            database = database_path(profile.wiring.database, Path(profile.path))
        if not database.exists():
            raise ConfigError(f"message database {profile.wiring.database} not found",
                              path=str(profile.path or ""), key="wiring.database")
    return build_contract(rig, node_id=profile.wiring.node_id,
                          heartbeat_period_ms=profile.timing.heartbeat_period_ms,
                          control_period_ms=profile.timing.control_period_ms,
                          command_ids=frozenset(profile.wiring.command_ids), database=database)


def _foreign_keys(record: Mapping[str, Any]) -> np.ndarray:
    """Frames of a bus-load generator (other ECUs' traffic): 29-bit ids from the record."""
    load = record.get("bus_load") or {}
    ids = [int(str(f["id"]), 16) for f in load.get("frames", []) if "id" in f]
    return np.array([i + (1 << 32) for i in ids], dtype=np.int64)


def _limits(profile: DutProfile, name: str, low: float | None,
            high: float | None) -> dict[str, Any]:
    limit = profile.limit(name)
    if limit is None:
        return {"low": low, "high": high}
    out: dict[str, Any] = {"low": limit.low, "high": limit.high}
    if limit.marginal is not None:
        out["marginal_band"] = limit.marginal
    return out


def run_conformance(record: Mapping[str, Any], out_dir: Path, profile: DutProfile, *,
                    physics_period_s: float, contract: BusContract | None = None,
                    conditions: Mapping[str, Any] | None = None) -> Conformance:
    """The bus conformance of the run recorded in ``out_dir``.

    Parameters
    ----------
    record : mapping
        The run's record (``record.json``: clock, events, bus load, simulated time).
    out_dir : Path
        The run's directory, with its ``bus.log``.
    profile : DutProfile
        The DUT's profile (wiring, timing, limits).
    physics_period_s : float
        The rig's physics step (how often it reads the bus in real time).
    contract : BusContract, optional
        The DUT's contract (default: :func:`contract_of` the profile).
    conditions : mapping, optional
        Added to every measurement's conditions: what tells this run's measurements from
        another run's in one qualification (the plugin gives ``{"run": <run directory>}``).

    Returns
    -------
    Conformance
        No measurements when the run wrote no candump log.

    Raises
    ------
    ConfigError
        An unreadable database or log (named).
    """
    path = Path(out_dir) / "bus.log"
    if not path.exists():
        return Conformance(detail={"skipped": "the run wrote no bus.log"})
    unheard_path = Path(out_dir) / UNHEARD_NAME
    unheard = read_bus_log(unheard_path) if unheard_path.exists() else None
    contract = contract or contract_of(profile)
    clock = str(record.get("clock", "lockstep"))
    isobus_log: FrameLog | None = None
    if profile.wiring.isobus:
        # an ISOBUS implement's 29-bit frames are judged by the ISOBUS checks (they need the
        # rig's side too: requests, CTS, a contender), its CANopen frames as any DUT's
        full = read_bus_log(path, keep="all")
        isobus_log = full.select(full.extended)
        sync = ~full.rx & ~full.extended & (full.can_id == SYNC_ID)
        log = full.select((full.rx & ~full.extended) | sync)
    else:
        log = read_bus_log(path, keep="rx+sync")
    out = judge(log, contract, profile, clock=clock,
                restarts=sum(1 for e in record.get("events", []) or []
                             if e.get("kind") == "dut-restart"),
                duration_s=float(record.get("sim_s") or 0.0),
                physics_period_s=physics_period_s, foreign=_foreign_keys(record),
                bus_load=float((record.get("bus_load") or {}).get("fraction") or 0.0),
                conditions=conditions, unheard=unheard)
    if isobus_log is not None:
        resolution_s = (physics_period_s if clock == "realtime"
                        else profile.timing.control_period_ms / 1000.0)
        node = {"node": contract.node_name, **(conditions or {})}
        rows = isobus_frames(isobus_log)        # decoded once for both
        found = [_with_profile_limits(profile, m) for m in
                 isobus_conformance(rows, resolution_s=resolution_s, conditions=node)]
        # a run with the tractor's VT on the bus: the DUT's behaviour as a VT client too
        found += [_with_profile_limits(profile, m) for m in vt_client_conformance(
            rows, end_s=float(record.get("sim_s") or 0.0) or None, conditions=node)]
        out.measurements.extend(found)
        out.detail["isobus"] = [{"name": m.name, "value": m.value, "unit": m.unit,
                                 "outcome": m.outcome.value, "note": m.note,
                                 "conditions": {k: v for k, v in m.conditions.items()
                                                if k not in node}} for m in found]
    return out


def _with_profile_limits(profile: DutProfile, m: Measurement) -> Measurement:
    """``m`` with the profile's limits for its name, if the profile sets any."""
    if profile.limit(m.name) is None:
        return m
    return Measurement(m.name, m.value, m.unit, conditions=m.conditions, note=m.note,
                       **_limits(profile, m.name, None, None))


def judge(log: FrameLog, contract: BusContract, profile: DutProfile, *, clock: str,
          restarts: int, duration_s: float, physics_period_s: float,
          foreign: np.ndarray | None = None, bus_load: float = 0.0,
          conditions: Mapping[str, Any] | None = None,
          unheard: FrameLog | None = None) -> Conformance:
    """The checks on a frame log (the rig's received frames are the DUT's; ``foreign``: keys
    of other nodes' frames, left out; ``bus_load``: the fraction of the bit rate they took;
    ``unheard``: the DUT's frames a fault kept from the rig, see the module)."""
    out = Conformance()
    unheard = unheard if unheard is not None else FrameLog.empty()
    unheard_s = np.sort(unheard.time_s)
    node = {"node": contract.node_name, **(conditions or {})}
    keys_all = checks.frame_keys(log)
    sync_mask = ~log.rx & (log.can_id == SYNC_ID) & ~log.extended
    dut_mask = log.rx.copy()
    if foreign is not None and foreign.size:
        dut_mask &= ~np.isin(keys_all, foreign)
    dut = log.select(dut_mask)
    keys = keys_all[dut_mask]
    hb_key = checks.key_of((contract.heartbeat_id, False))
    is_hb = keys == hb_key
    is_bootup = is_hb & (dut.dlc == 1) & (dut.data[:, 0] == 0)
    segment = checks.power_ups(is_bootup)
    # unbroken series: a power-up, cut where the DUT's frames did not reach the rig
    series = checks.series(segment, dut.time_s, unheard_s)
    counts = checks.count_by_key(keys)
    declared = {checks.key_of(k): f for k, f in contract.frames.items()}

    add = _Sink(profile, out.measurements)

    # undeclared frames
    unknown = {k: n for k, n in counts.items() if k not in declared}
    listed = ", ".join(f"{_label(k)} ({n})" for k, n in sorted(unknown.items(),
                                                                key=lambda kv: -kv[1])[:10])
    add("bus.undeclared_frames", sum(unknown.values()), dict(node),
        f"identifiers (frames): {listed}" if unknown else "", high=0)
    rows = []
    resolution_ms = _resolution_ms(clock, physics_period_s, contract.control_period_ms)
    for key, frame in declared.items():
        n = counts.get(key, 0)
        mask = keys == key
        row: dict[str, Any] = {"message": frame.name, "id": frame.label, "source": frame.source,
                               "frames": n, "dlc_declared": frame.dlc,
                               "cycle_declared_ms": frame.cycle_ms,
                               "cycle_source": frame.cycle_source, "note": frame.note}
        if n:
            seen = sorted(set(dut.dlc[mask].tolist()))
            errors = int(np.count_nonzero(dut.dlc[mask] != frame.dlc))
            row.update(dlc_seen=seen, dlc_errors=errors)
            m = add("bus.dlc_errors", errors, {"message": frame.name, **node},
                    f"declared {frame.dlc}, seen {', '.join(map(str, seen))}" if errors else "",
                    high=0)
            row["dlc_outcome"] = m.outcome.value
        if frame.cycle_ms is not None and key != hb_key:
            row.update(_cycle(add, frame, dut.time_s[mask], series[mask],
                              resolution_ms(frame), node, realtime=clock == "realtime",
                              cut=checks.intervals_cut(segment[mask], series[mask])))
        rows.append(row)
    out.detail["messages"] = rows
    out.detail["undeclared"] = [{"id": _label(k), "frames": n} for k, n in
                                sorted(unknown.items())]
    beats = is_hb & ~is_bootup
    out.detail["heartbeat"] = _heartbeat(add, contract, dut.time_s[beats], segment[beats],
                                         resolution_ms(contract.frames[(contract.heartbeat_id,
                                                                        False)]), node,
                                         last_power_up=_last_power_up(dut.time_s, is_bootup),
                                         end_s=_heard_end(duration_s, dut.time_s[is_hb],
                                                          unheard_s),
                                         series=series[beats])
    # boot-up: first, and once per power-up
    before = int(np.count_nonzero(segment == 0))
    bootups = int(np.count_nonzero(is_bootup))
    expected = 1 + restarts
    first_before = ", ".join(sorted({_label(k) for k in keys[segment == 0][:50].tolist()}))
    if profile.dut.kind == "physical":
        # the rig does not power a physical ECU: it may have booted before the rig listened
        # (frames "before" its boot-up are then just its traffic), or once while the rig
        # waited for it; a second boot-up is still a restart nobody asked for
        add("bus.bootup.frames_before", before, dict(node),
            "not judged: the rig does not power up a physical ECU, so its power-up may "
            "precede the run" + (f" (frames before a boot-up: {first_before})" if before
                                 else ""), high=None)
        add("bus.bootup.unexpected", max(0, bootups - 1), {**node, "power_ups": 0},
            f"{bootups} boot-up messages; at most one (the ECU powered while the rig "
            "waited) is expected", high=0)
        expected = min(bootups, 1)
    else:
        add("bus.bootup.frames_before", before, dict(node),
            f"before the first boot-up: {first_before}" if before else "", high=0)
        add("bus.bootup.unexpected", abs(bootups - expected), {**node, "power_ups": expected},
            f"{bootups} boot-up messages for {expected} power-up(s)", high=0)
    # share of the bus
    duration = duration_s if duration_s > 0 else float(log.time_s.max(initial=0.0))
    bits = checks.total_bits(dut)
    bits_per_s = bits / duration if duration > 0 else math.nan
    share = 100.0 * bits_per_s / contract.bitrate_bps
    add("bus.share", share, dict(node),
        f"{bits_per_s:.0f} bit/s of {contract.bitrate_bps} bit/s ({len(dut)} frames, "
        f"{bits} bits in {duration:g} s)", high=BUS_SHARE_PCT)
    out.detail.update(bootup={"frames_before": before, "bootups": bootups,
                              "power_ups": expected},
                      share={"bits": bits, "bits_per_s": bits_per_s, "pct": share,
                             "bitrate_bps": contract.bitrate_bps},
                      node=contract.node_name, node_id=contract.node_id, clock=clock,
                      databases=list(contract.databases))
    if unheard_s.size:
        out.detail["unheard"] = {
            "frames": int(unheard_s.size), "first_s": float(unheard_s[0]),
            "last_s": float(unheard_s[-1]), "file": UNHEARD_NAME,
            "note": "the DUT's frames a fault kept from the rig (a cut wire): not received, so "
                    "not judged; intervals across them are not judged either"}
    if clock == "realtime":
        unheard_commands = unheard.time_s[np.isin(
            checks.frame_keys(unheard),
            np.array(sorted(contract.command_ids), dtype=np.int64)) & ~unheard.extended]
        out.detail["sync_latency"] = _latency(add, contract, log.time_s[sync_mask], dut, keys,
                                              node, physics_period_s * 1000.0, bus_load,
                                              unheard_commands_s=np.sort(unheard_commands))
    return out


def _heard_end(duration_s: float, heartbeats_s: np.ndarray,
               unheard_s: np.ndarray) -> float | None:
    """Where the heartbeat's last gap ends: the end of the run, or the first of the DUT's
    frames a fault kept from the rig after its last heard heartbeat (the silence after it is
    the fault's). None when the run's length is unknown."""
    if duration_s <= 0:
        return None
    if unheard_s.size and heartbeats_s.size:
        later = unheard_s[unheard_s > heartbeats_s.max()]
        if later.size:
            return min(duration_s, float(later[0]))
    return duration_s


def _label(key: int) -> str:
    can_id, extended = key & 0x1FFFFFFF, bool(key >> 32)
    return f"0x{can_id:08X}" if extended else f"0x{can_id:03X}"


def _resolution_ms(clock: str, physics_period_s: float, control_period_ms: float) -> Any:
    def resolution(frame: DeclaredFrame) -> float:
        if clock == "realtime":
            return physics_period_s * 1000.0
        return 0.0 if frame.cycle_source.endswith("(SYNC)") else control_period_ms
    return resolution


class _Sink:
    """Makes each measurement with the profile's limits for its name, else the default."""

    def __init__(self, profile: DutProfile, measurements: list[Measurement]) -> None:
        self.profile = profile
        self.measurements = measurements

    def limits(self, name: str) -> dict[str, Any]:
        """The profile's limits for ``name`` (low/high None where it sets none)."""
        return _limits(self.profile, name, None, None)

    def __call__(self, name: str, value: float, conditions: dict[str, Any], note: str = "",
                 *, low: float | None = None, high: float | None = None) -> Measurement:
        m = Measurement(name, float(value), MEASUREMENTS[name].unit, conditions=conditions,
                        note=note, **_limits(self.profile, name, low, high))
        self.measurements.append(m)
        return m


def _band(profile_limits: dict[str, Any], default: float) -> tuple[float, float]:
    low, high = profile_limits["low"], profile_limits["high"]
    return (-default if low is None else low, default if high is None else high)


def _cycle(add: _Sink, frame: DeclaredFrame, time_s: np.ndarray, segment: np.ndarray,
           resolution_ms: float, node: dict[str, Any], *, realtime: bool,
           cut: int = 0) -> dict[str, Any]:
    """``segment``: the unbroken series of each frame; ``cut``: how many intervals across
    frames a fault kept from the rig that leaves out."""
    gaps = checks.intervals(time_s, segment)
    if gaps.size == 0:
        return {"cycle": "fewer than two frames in one power-up"}
    cond = {"message": frame.name, **node}
    # the profile's median limits (if set) are the band each interval is judged by
    band = _band(add.limits("bus.cycle_time.median"), CYCLE_TOLERANCE_PCT)
    stats = checks.cycle_stats(gaps, frame.cycle_ms or math.nan, band[0], band[1],
                               resolution_ms)
    note = (f"median {stats.median_ms:.4g} ms, min {stats.min_ms:.4g}, max {stats.max_ms:.4g} "
            f"over {stats.count} intervals; declared {frame.cycle_ms:g} ms "
            f"({frame.cycle_source})" + (f"; {frame.note}" if frame.note else "")
            + (f"; {_cut_note(cut)}" if cut else ""))
    m1 = add("bus.cycle_time.median", stats.deviation_pct, cond, note, low=band[0],
             high=band[1])
    realtime_note = ("; real time: the intervals include the bench's own time-stamping "
                     "jitter (the rig reads the bus once per physics step, through the software "
                     "bus), so no default limit" if realtime else "")
    m2 = add("bus.cycle_time.outside_band", stats.outside_pct, cond,
             f"{stats.outside} of {stats.count} intervals outside {band[0]:g} … {band[1]:g} % "
             f"(+/- {resolution_ms:g} ms time-stamp resolution){realtime_note}",
             high=None if realtime else OUTSIDE_BAND_PCT)
    return {"median_ms": stats.median_ms, "min_ms": stats.min_ms, "max_ms": stats.max_ms,
            "intervals": stats.count, "outside": stats.outside, "intervals_cut": cut,
            "resolution_ms": resolution_ms,
            "cycle_outcome": _worst(m1.outcome.value, m2.outcome.value)}


def _cut_note(cut: int) -> str:
    return (f"{cut} interval{'s' if cut != 1 else ''} across frames a fault kept from the rig "
            f"(a cut wire, {UNHEARD_NAME}) not judged")


def _worst(*outcomes: str) -> str:
    for outcome in ("error", "fail", "pass", "info"):
        if outcome in outcomes:
            return outcome
    return "info"


def _last_power_up(time_s: np.ndarray, is_bootup: np.ndarray) -> tuple[int, float] | None:
    """The last power-up's segment number and its boot-up time (``None``: no boot-up seen)."""
    boots = np.flatnonzero(is_bootup)
    if not boots.size:
        return None
    return int(boots.size), float(time_s[boots[-1]])


def _trailing_gap_s(time_s: np.ndarray, segment: np.ndarray,
                    last_power_up: tuple[int, float] | None, end_s: float | None) -> float:
    """Time from the last heartbeat of the last power-up (or its boot-up, if it sent none) to
    the end of the run: the gap a heartbeat consumer sees when a node falls silent for good.
    NaN when the end of the run or the power-up is unknown."""
    if end_s is None or last_power_up is None:
        return math.nan
    seg, boot_s = last_power_up
    mine = time_s[segment == seg]
    last = float(mine.max()) if mine.size else boot_s
    return max(0.0, end_s - last)


def _heartbeat(add: _Sink, contract: BusContract, time_s: np.ndarray, segment: np.ndarray,
               resolution_ms: float, node: dict[str, Any], *,
               last_power_up: tuple[int, float] | None = None,
               end_s: float | None = None,
               series: np.ndarray | None = None) -> dict[str, Any]:
    """``segment``: the power-up of each heartbeat; ``series``: its unbroken series (a
    power-up cut where the DUT's frames did not reach the rig), which the intervals keep to."""
    declared = contract.heartbeat_period_ms
    series = segment if series is None else series
    gaps = checks.intervals(time_s, series)
    cut = checks.intervals_cut(segment, series)
    out: dict[str, Any] = {"id": f"0x{contract.heartbeat_id:03X}", "declared_ms": declared,
                           "frames": int(time_s.size)}
    band = _band(add.limits("bus.heartbeat.period"), HEARTBEAT_TOLERANCE_PCT)
    stats = checks.cycle_stats(gaps, declared, band[0], band[1], resolution_ms)
    m = add("bus.heartbeat.period", stats.deviation_pct, dict(node),
            f"median {stats.median_ms:.4g} ms, min {stats.min_ms:.4g}, max "
            f"{stats.max_ms:.4g} over {stats.count} intervals; declared {declared:g} ms "
            "(timing.heartbeat_period_ms)" + (f"; {_cut_note(cut)}" if cut else "")
            if stats.count else "no heartbeat interval", low=band[0], high=band[1])
    trailing_ms = 1000.0 * _trailing_gap_s(time_s, segment, last_power_up, end_s)
    longest = [v for v in (stats.max_ms if stats.count else math.nan, trailing_ms)
               if not math.isnan(v)]
    silence_ms = max(longest) if longest else math.nan
    out.update(median_ms=stats.median_ms, min_ms=stats.min_ms, max_ms=stats.max_ms,
               trailing_ms=trailing_ms, longest_silence_ms=silence_ms,
               intervals=stats.count, intervals_cut=cut, outcome=m.outcome.value,
               consumers=[])
    consumers = [(c.name, c.time_ms, "(0x1016)") for c in contract.consumers]
    if not consumers:
        consumers = [("rig's heartbeat monitor", RIG_MONITOR_FACTOR * declared + resolution_ms,
                      f"({RIG_MONITOR_FACTOR:g} x timing.heartbeat_period_ms + the rig's "
                      "time-stamp resolution: no node of the rig consumes it)")]
    where = (f"; longest interval {stats.max_ms:.4g} ms" if stats.count else "") + (
        f", last heartbeat {trailing_ms:.4g} ms before the end of the run"
        if not math.isnan(trailing_ms) else "")
    for name, time_ms, why in consumers:
        c = add("bus.heartbeat.max_interval", silence_ms, {**node, "consumer": name},
                f"the {name} expects a heartbeat within {time_ms:g} ms {why}{where}",
                high=time_ms)
        out["consumers"].append({"name": name, "time_ms": time_ms,
                                 "outcome": c.outcome.value})
    return out


def _latency(add: _Sink, contract: BusContract, sync_s: np.ndarray, dut: FrameLog,
             keys: np.ndarray, node: dict[str, Any], resolution_ms: float,
             bus_load: float, *, unheard_commands_s: np.ndarray | None = None
             ) -> dict[str, Any]:
    commands = np.isin(keys, np.array(sorted(contract.command_ids), dtype=np.int64)) \
        & ~dut.extended
    unheard = np.zeros(0) if unheard_commands_s is None else unheard_commands_s
    latency_ms = checks.heard_sync_latency(sync_s, dut.time_s[commands], unheard) * 1000.0
    period = contract.control_period_ms
    if latency_ms.size == 0:
        for name in ("bus.sync_latency.p50", "bus.sync_latency.p99", "bus.sync_latency.max"):
            add(name, math.nan, dict(node), "no SYNC followed by a command frame")
        return {"syncs": int(sync_s.size), "samples": 0}
    p50, p99 = (float(v) for v in np.percentile(latency_ms, [50, 99]))
    worst = float(latency_ms.max())
    note = f"{latency_ms.size} SYNCs; control period {period:g} ms"
    add("bus.sync_latency.p50", p50, dict(node), note)
    if bus_load > 0:
        # other nodes' higher-priority frames win arbitration: the latency then measures the
        # loaded bus as much as the DUT
        add("bus.sync_latency.p99", p99, dict(node),
            note + f"; the bus carried {bus_load:.0%} of other traffic: no default limit")
    else:
        add("bus.sync_latency.p99", p99, dict(node),
            note + f", +{CYCLE_TOLERANCE_PCT:g} %, + {resolution_ms:g} ms time-stamp "
            "resolution", high=period * (1 + CYCLE_TOLERANCE_PCT / 100.0) + resolution_ms)
    add("bus.sync_latency.max", worst, dict(node), note)
    return {"syncs": int(sync_s.size), "samples": int(latency_ms.size), "p50_ms": p50,
            "p99_ms": p99, "max_ms": worst, "period_ms": period}


def write_detail(conformance: Conformance, out_dir: Path) -> Path:
    """The detail table as ``conformance.json`` in the run's directory."""
    path = Path(out_dir) / DETAIL_FILE
    path.write_text(json.dumps(conformance.detail, indent=1, default=_plain))
    return path


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return str(value)
