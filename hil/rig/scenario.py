"""Scenarios as data: TOML files (or the same dataclasses built in Python).

A scenario names its rig, lasts ``duration_s``, starts from ``initial`` inputs, may follow a
piecewise-linear ``speed_profile`` ((time s, ground speed m/s) breakpoints), and applies
timed ``events``: set inputs, inject or clear a fault. Keys and fault names are checked
against what the rig declares, so a typo is an error naming the file and the key::

    name = "bench-step"
    description = "target flow steps 23 -> 34 -> 44 g/s"
    rig = "fertilizer"
    duration_s = 60.0
    [initial]
    target_flow_gps = 0.0
    [[events]]
    at_s = 1.0
    set = { target_flow_gps = 23.0 }
    [[events]]
    at_s = 30.0
    fault = "flow_sensor_silent"
    target = 2
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from hil.config import key_text, load_toml
from hil.errors import ConfigError
from hil.isobus.vt.steps import OperatorStep

DUT_ACTIONS = ("restart",)
#: the longest scenario accepted (a day of simulated time): beyond it is a typo, not a run
MAX_DURATION_S = 86_400.0


@dataclass(frozen=True)
class Event:
    """One timed event of a scenario: set inputs, inject or clear a fault, or restart the DUT.

    Exactly one of ``set``, ``fault``, ``clear`` and ``dut`` is given.

    Parameters
    ----------
    at_s : float
        When the event happens, in seconds of run time (finite, >= 0).
    set : dict of str to float, optional
        Inputs to set (names the rig declares in :attr:`Rig.inputs`).
    fault : str, optional
        A fault to inject (a name of :attr:`Rig.faults`).
    clear : str, optional
        A fault to clear.
    target : int, optional
        What the fault applies to, where the rig has several (a row, a sensor), >= 0.
    dut : str, optional
        ``"restart"``: the DUT is stopped and started again (a power cycle of the controller).

    Raises
    ------
    ConfigError
        Not exactly one action, an unknown DUT action, a time or value that is not finite, or a
        negative target (naming the key).
    """

    at_s: float
    set: dict[str, float] | None = None
    fault: str | None = None
    clear: str | None = None
    target: int | None = None
    dut: str | None = None

    def __post_init__(self) -> None:
        actions = sum(x is not None for x in (self.set, self.fault, self.clear, self.dut))
        if actions != 1:
            raise ConfigError("an event needs exactly one of set, fault, clear, dut")
        if self.dut is not None and self.dut not in DUT_ACTIONS:
            raise ConfigError(f"unknown DUT action {self.dut!r} (known: "
                              f"{', '.join(DUT_ACTIONS)})", key="dut")
        if not 0 <= self.at_s < math.inf:
            raise ConfigError(f"event time must be a finite number >= 0, got {self.at_s}",
                              key="at_s")
        if self.target is not None and self.target < 0:
            raise ConfigError(f"target must be >= 0, got {self.target}", key="target")
        for name, value in (self.set or {}).items():
            if not math.isfinite(value):
                raise ConfigError(f"{name} must be a finite number, got {value}",
                                  key=f"set.{key_text(name)}")


@dataclass(frozen=True)
class TractorRun:
    """The scenario's ``[tractor]`` table: the rig plays an ISOBUS tractor (ISO 11783).

    Its tractor ECU and Task Controller (:class:`hil.isobus.tractor.Tractor`) drive a field
    path over a prescription map; the DUT, an ISOBUS implement, claims an address, connects
    to the TC and takes its rate and section states from it, its speed from the TECU::

        [tractor]
        field = "../fields/field-rect.geojson"        # relative to the scenario file
        prescription = "../fields/rates-3zones.geojson"
        drive_after_s = 8.0

    Parameters
    ----------
    field : str
        The field GeoJSON (boundary, work area, path legs: ``docs/guide/prescription-maps.md``),
        relative to the scenario file.
    prescription : str, optional
        The prescription map GeoJSON, relative to the scenario file; empty: the TC sends no
        rate (TC-BAS and TC-SC only).
    drive_after_s : float, optional
        When the tractor starts down the path; it stands at the start, key on, before.
    wheel_slip : float, optional
        Slip of the tractor's driven wheels, [0, 0.5]: the wheel-based speed (PGN 65096)
        over-reads by it, the ground-based one (65097) does not.
    overlap_tolerance_pct : float, optional
        Share of a section's ground that may be covered already before TC-SC switches it off.
    tc_memory_bytes : int, optional
        The largest pool the TC accepts; a smaller one makes it refuse the DUT's DDOP.
    vt : bool, optional
        The tractor has a Virtual Terminal (ISO 11783-6) beside its TC: the implement can
        upload its pool and show its masks there, and the scenario's ``[[operator]]`` steps
        are played on it (:mod:`hil.isobus.vt`).
    operator : tuple of OperatorStep, optional
        The scenario's ``[[operator]]`` list (filled from it at load; sorted by time).
    """

    field: str
    prescription: str = ""
    drive_after_s: float = 5.0
    wheel_slip: float = 0.0
    overlap_tolerance_pct: float = 50.0
    tc_memory_bytes: int = 1 << 20
    vt: bool = False
    operator: tuple[OperatorStep, ...] = ()

    def __post_init__(self) -> None:
        if not self.field:
            raise ConfigError("the field file is required", key="field")
        if not 0 <= self.drive_after_s <= MAX_DURATION_S:
            raise ConfigError(f"drive_after_s must be in [0, {MAX_DURATION_S:g}] s, got "
                              f"{self.drive_after_s}", key="drive_after_s")
        if not 0.0 <= self.wheel_slip <= 0.5:
            raise ConfigError(f"wheel_slip must be in [0, 0.5], got {self.wheel_slip}",
                              key="wheel_slip")
        if not 0.0 <= self.overlap_tolerance_pct <= 100.0:
            raise ConfigError(f"overlap_tolerance_pct must be in [0, 100], got "
                              f"{self.overlap_tolerance_pct}",
                              key="overlap_tolerance_pct")
        if not 0 < self.tc_memory_bytes <= 1 << 32:
            raise ConfigError(f"tc_memory_bytes must be in [1, 2^32], got "
                              f"{self.tc_memory_bytes}", key="tc_memory_bytes")

    def resolved(self, base: Path) -> TractorRun:
        """The same table with its file names made absolute against ``base``."""
        def full(name: str) -> str:
            return str((base / name).resolve()) if name else ""
        return replace(self, field=full(self.field), prescription=full(self.prescription))


@dataclass(frozen=True)
class Scenario:
    """A scenario: what happens to the rig during one run.

    Parameters
    ----------
    name : str
        The scenario's name.
    description : str
        One line saying what it tests.
    rig : str
        The rig it is for.
    duration_s : float
        How long the run lasts, in seconds (at most a day).
    seed : int, optional
        The seed of the rig's random generator (noise, field variation), >= 0.
    initial : dict of str to float, optional
        Inputs at t = 0.
    speed_profile : tuple of (float, float), optional
        (time s, ground speed m/s) breakpoints, increasing in time; linear in between.
    events : tuple of Event, optional
        Timed events (kept sorted by time).
    tags : tuple of str, optional
        Free-form labels.
    bus_load : float, optional
        Other ECUs' traffic added to the bus, as a fraction of the rig's bit rate in [0, 1)
        (:mod:`hil.rig.busload`); needs real time and a bus with a bit rate. 0: none.
    tractor : TractorRun, optional
        The rig plays an ISOBUS tractor driving a field (rigs that support it).
    operator : tuple of OperatorStep, optional
        The ``[[operator]]`` list: what the operator does on the tractor's Virtual Terminal,
        at run times (press a soft key or button by id or label, enter a value, acknowledge
        an alarm); needs ``[tractor] vt = true``. Whether the objects it names are in the
        implement's pool is checked when the pool becomes active, before any step is played::

            [[operator]]
            at_s = 4.0
            press = "Master"

    Raises
    ------
    ConfigError
        A value out of range or not finite, speed breakpoints out of order, or operator steps
        without the tractor's VT (naming the key).
    """

    name: str
    description: str
    rig: str
    duration_s: float
    seed: int = 0
    initial: dict[str, float] = field(default_factory=dict)
    speed_profile: tuple[tuple[float, float], ...] = ()
    events: tuple[Event, ...] = ()
    tags: tuple[str, ...] = ()
    bus_load: float = 0.0
    tractor: TractorRun | None = None
    operator: tuple[OperatorStep, ...] = ()

    def __post_init__(self) -> None:
        if not 0 < self.duration_s <= MAX_DURATION_S:
            raise ConfigError(f"duration must be positive and at most {MAX_DURATION_S:g} s, "
                              f"got {self.duration_s}", key="duration_s")
        if self.seed < 0:
            raise ConfigError(f"seed must be >= 0, got {self.seed}", key="seed")
        for name, value in self.initial.items():
            if not math.isfinite(value):
                raise ConfigError(f"{name} must be a finite number, got {value}",
                                  key=f"initial.{key_text(name)}")
        for i, (t, v) in enumerate(self.speed_profile):
            if not (math.isfinite(t) and math.isfinite(v)) or t < 0 or v < 0:
                raise ConfigError(f"breakpoint ({t}, {v}): time and speed must be finite "
                                  f"and >= 0", key=f"speed_profile[{i}]")
        if not 0.0 <= self.bus_load < 1.0:
            raise ConfigError(f"bus_load is a fraction of the bit rate in [0, 1), got "
                              f"{self.bus_load}", key="bus_load")
        times = [t for t, _ in self.speed_profile]
        if times != sorted(times):
            raise ConfigError("speed_profile times must increase", key="speed_profile")
        object.__setattr__(self, "events", tuple(sorted(self.events, key=lambda e: e.at_s)))
        self._operator_on_the_vt()

    def _operator_on_the_vt(self) -> None:
        """Give the sorted ``[[operator]]`` steps to the tractor's VT; refuse them without.

        The field run plays them on the VT (``TractorRun.operator``).
        """
        steps = tuple(sorted(self.operator, key=lambda s: s.at_s))
        object.__setattr__(self, "operator", steps)
        if not steps:
            return
        if self.tractor is None or not self.tractor.vt:
            raise ConfigError("operator steps act on the tractor's Virtual Terminal: the "
                              "scenario needs a [tractor] table with vt = true", key="operator")
        if self.tractor.operator not in ((), steps):
            raise ConfigError("give the operator's steps once, as the scenario's [[operator]] "
                              "list", key="tractor.operator")
        object.__setattr__(self, "tractor", replace(self.tractor, operator=steps))

    def speed_at(self, time_s: float) -> float | None:
        """Ground speed from the profile (linear between breakpoints), or None without one."""
        points = self.speed_profile
        if not points:
            return None
        if time_s <= points[0][0]:
            return points[0][1]
        for (t0, v0), (t1, v1) in itertools.pairwise(points):
            if time_s <= t1:
                return v0 + (v1 - v0) * (time_s - t0) / (t1 - t0) if t1 > t0 else v1
        return points[-1][1]

    def check_against(self, inputs: dict[str, str], faults: dict[str, str],
                      path: str | None = None) -> None:
        """Refuse inputs and faults the rig does not know, naming them.

        Parameters
        ----------
        inputs : dict of str to str
            The rig's inputs (name to unit).
        faults : dict of str to str
            The rig's faults (name to what it does).
        path : str, optional
            The scenario file, named in the error.

        Raises
        ------
        ConfigError
            An initial or event input, or an event's fault, is not the rig's (naming the key).
        """
        for key in self.initial:
            if key not in inputs:
                raise ConfigError(f"unknown input; the rig takes: {', '.join(sorted(inputs))}",
                                  path=path, key=f"initial.{key_text(key)}")
        for i, event in enumerate(self.events):
            for key in event.set or {}:
                if key not in inputs:
                    raise ConfigError(f"unknown input; the rig takes: "
                                      f"{', '.join(sorted(inputs))}", path=path,
                                      key=f"events[{i}].set.{key_text(key)}")
            for name in (event.fault, event.clear):
                if name is not None and name not in faults:
                    raise ConfigError(f"unknown fault {name!r}; the rig has: "
                                      f"{', '.join(sorted(faults))}", path=path,
                                      key=f"events[{i}]")


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario file.

    An event after the end of the run (it would never happen) is refused, naming it. A scenario
    shortened in code (with ``dataclasses.replace``, say) may drop its later events on purpose.

    Parameters
    ----------
    path : str or Path
        The TOML file.

    Returns
    -------
    Scenario
        The scenario, its events sorted by time.

    Raises
    ------
    ConfigError
        A missing or unknown key, a bad value, or an event after ``duration_s`` (naming the file
        and the key).
    """
    scenario = load_toml(path, Scenario)
    if scenario.tractor is not None:
        scenario = replace(scenario, tractor=scenario.tractor.resolved(Path(path).parent))
    for i, event in enumerate(scenario.events):
        if event.at_s > scenario.duration_s:
            raise ConfigError(f"event at {event.at_s:g} s is after the end of the run "
                              f"({scenario.duration_s:g} s): it would never happen",
                              path=str(path), key=f"events[{i}].at_s")
    for i, step in enumerate(scenario.operator):
        if step.at_s > scenario.duration_s:
            raise ConfigError(f"operator step at {step.at_s:g} s is after the end of the run "
                              f"({scenario.duration_s:g} s): it would never happen",
                              path=str(path), key=f"operator[{i}].at_s")
    return scenario
