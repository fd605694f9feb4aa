"""The rig file: a plant FMU, its CAN devices as nodes of your DBC, its controlled quantities.

A rig file is TOML, read into frozen dataclasses (every key checked, errors name the file and
the dotted key); :func:`load_rig_file` then checks it against its FMU and its DBC::

    name = "motor_meter"                    # the rig's name (scenarios say rig = "motor_meter")
    dbc = "motor_meter.dbc"                 # relative to the rig file
    dut_node = "Controller"                 # the controller's node in the DBC
    control_period_ms = 100                 # SYNC period (lockstep: the DUT steps on it)

    [fmu]
    path = "build/StateSpace.fmu"
    step_ms = 1                             # the physics (communication) step
    parameters = { A = [...], B = [...] }   # parameters and start values by variable name

    [inputs.speed_target]                   # a scenario input (set-points, disturbances)
    unit = "rpm"

    [devices.meter]                         # a node of the DBC the rig plays
    node = "Meter"
    node_id = 5                             # CANopen: heartbeat 0x705, NMT (or eds = "...")
    heartbeat_ms = 1000
    [[devices.meter.send]]
    message = "MeterStatus"                 # period: period_ms, else the DBC's cycle time
    signals.Flow = { fmu = "y[2]", unit = "g/s", noise_sd = 0.2, quantum = 0.1 }

    [[devices.drive.receive]]
    message = "DriveCommand"
    timeout_ms = 300
    on_timeout = "zero"                     # hold, zero, or safe (each signal's safe value)
    signals.Voltage = { fmu = "u[1]", unit = "V" }

    [controlled.speed]                      # what the standard suites judge
    target = "speed_target"                 # a scenario input
    sensed = "meter_status_speed"           # a quantity the rig sends (see below)
    truth = "y[1]"                          # an FMU output
    unit = "rpm"
    band = 2.0                              # +/- band of the response time, in unit
    steps = [60.0, 90.0]
    limits = { response_time_s = 1.5, overshoot_pct = 10, steady_state_error = 1.0 }

Each signal a device sends or receives is a rig quantity (:mod:`hil.contract.quantity`) named
``quantity`` or, by default, ``<message>_<signal>`` in snake case; the rig's binding of those
quantities to the DBC's frames is made from the devices (:mod:`hil.ownrig.contract`) and goes
through the same codec as the built-in rigs' DBC bindings.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from hil.config import load_toml
from hil.errors import ConfigError

TIMEOUT_BEHAVIOURS = ("hold", "zero", "safe")
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


def snake(text: str) -> str:
    """``MeterStatus_Flow`` → ``meter_status_flow`` (a quantity name)."""
    text = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", text)
    text = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", text)
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def _positive(value: float | None, key: str) -> None:
    if value is not None and not value > 0:
        raise ConfigError(f"must be > 0, got {value}", key=key)


def _non_negative(value: float, key: str) -> None:
    if not value >= 0:
        raise ConfigError(f"must be >= 0, got {value}", key=key)


@dataclass(frozen=True)
class SentSignal:
    """A DBC signal a device sends, and where its value comes from.

    Exactly one source: ``fmu`` (an FMU output or local, through the sensor model), ``input``
    (a scenario input, sent as it is: a terminal's set-point), ``counter`` (a rolling counter,
    +1 per frame) or ``value`` (a constant). The sensor model, applied in this order to an FMU
    value: ``delay_ms`` (the value that long ago), ``rate_window_ms`` (the rate of change over
    that window, per second: a flow from a cumulative mass), ``hold_ms`` (sample-and-hold: a
    new sample every so often), ``gain`` and ``offset``, ``noise_sd`` (Gaussian, from the
    run's seeded generator), ``quantum`` (rounding to a multiple).
    """

    fmu: str = ""
    input: str = ""
    counter: bool = False
    value: float | None = None
    unit: str = ""
    quantity: str = ""
    gain: float = 1.0
    offset: float = 0.0
    noise_sd: float = 0.0
    quantum: float = 0.0
    delay_ms: float = 0.0
    hold_ms: float = 0.0
    rate_window_ms: float = 0.0

    def __post_init__(self) -> None:
        sources = sum((bool(self.fmu), bool(self.input), self.counter, self.value is not None))
        if sources != 1:
            raise ConfigError("give exactly one source: fmu, input, counter or value")
        for name in ("noise_sd", "quantum", "delay_ms", "hold_ms", "rate_window_ms"):
            _non_negative(getattr(self, name), name)
        if self.quantity and not _NAME.match(self.quantity):
            raise ConfigError(f"quantity names are lower_snake_case, got {self.quantity!r}",
                              key="quantity")


@dataclass(frozen=True)
class SentMessage:
    """A message a device sends: on a period, or when one of its values changes."""

    message: str
    signals: dict[str, SentSignal]
    period_ms: float | None = None
    #: also send as soon as a value changes (checked every physics step), at most every
    #: ``min_interval_ms``
    on_change: bool = False
    min_interval_ms: float = 0.0
    offset_ms: float = 0.0

    def __post_init__(self) -> None:
        _positive(self.period_ms, "period_ms")
        _non_negative(self.min_interval_ms, "min_interval_ms")
        _non_negative(self.offset_ms, "offset_ms")
        if not self.signals:
            raise ConfigError("a sent message needs its signals", key="signals")


@dataclass(frozen=True)
class ReceivedSignal:
    """A DBC signal a device receives from the controller, written into an FMU input as
    ``gain * value + offset``; ``safe`` is its value when the commands stop (``on_timeout =
    "safe"``), in the signal's unit."""

    fmu: str
    unit: str = ""
    quantity: str = ""
    gain: float = 1.0
    offset: float = 0.0
    safe: float = 0.0
    initial: float = 0.0

    def __post_init__(self) -> None:
        if self.quantity and not _NAME.match(self.quantity):
            raise ConfigError(f"quantity names are lower_snake_case, got {self.quantity!r}",
                              key="quantity")


@dataclass(frozen=True)
class ReceivedMessage:
    """A message a device takes from the controller, with an actuator's timeout behaviour.

    ``timeout_ms`` after its last frame (0: never) the device applies ``on_timeout``: ``hold``
    (keeps the last value), ``zero`` (0 into the FMU) or ``safe`` (each signal's ``safe``).
    ``command``: the lockstep step waits for this message after each SYNC.
    """

    message: str
    signals: dict[str, ReceivedSignal]
    timeout_ms: float = 0.0
    on_timeout: Literal["hold", "zero", "safe"] = "hold"
    command: bool = True

    def __post_init__(self) -> None:
        _non_negative(self.timeout_ms, "timeout_ms")
        if not self.signals:
            raise ConfigError("a received message needs its signals", key="signals")


@dataclass(frozen=True)
class DeviceSpec:
    """A CAN node the rig plays: a node of the DBC, optionally a CANopen node.

    ``node_id`` makes it a CANopen node: its heartbeat (``heartbeat_ms``, 0x700 + id, 0x05
    operational) and NMT (stop silences its messages, start resumes them, a reset sends a
    boot-up and starts again). ``eds``: the node is played from its EDS instead
    (:class:`hil.rig.canopen_device.CanopenDevice`: heartbeat from 0x1017, NMT, SDO), and its
    messages go out only while it is operational.
    """

    node: str = ""
    node_id: int | None = None
    heartbeat_ms: float = 0.0
    eds: str = ""
    send: tuple[SentMessage, ...] = ()
    receive: tuple[ReceivedMessage, ...] = ()

    def __post_init__(self) -> None:
        if self.node_id is not None and not 1 <= self.node_id <= 127:
            raise ConfigError(f"a CANopen node id is 1..127, got {self.node_id}", key="node_id")
        _non_negative(self.heartbeat_ms, "heartbeat_ms")
        if (self.heartbeat_ms or self.eds) and self.node_id is None:
            raise ConfigError("a heartbeat or an EDS needs the node's node_id", key="node_id")
        if self.heartbeat_ms and self.eds:
            raise ConfigError("the EDS's object 0x1017 sets the heartbeat of a node played from "
                              "its EDS: leave heartbeat_ms out", key="heartbeat_ms")
        if not self.send and not self.receive and not self.node_id:
            raise ConfigError("a device sends, receives, or is a CANopen node", key="send")


@dataclass(frozen=True)
class InputSpec:
    """A scenario input (a set-point, a disturbance); ``fmu``: also written into that FMU
    input whenever the scenario sets it."""

    unit: str
    initial: float = 0.0
    fmu: str = ""
    description: str = ""


@dataclass(frozen=True)
class FmuSpec:
    """The plant FMU, its parameters and start values, its step."""

    path: str
    step_ms: float = 1.0
    parameters: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _positive(self.step_ms, "step_ms")


@dataclass(frozen=True)
class Limits:
    """Limits of a controlled quantity's measurements (a DUT profile's ``[limits]`` entry of
    the same measurement replaces each)."""

    response_time_s: float | None = None
    overshoot_pct: float | None = None
    steady_state_error: float | None = None
    sensed_steady_state_error: float | None = None
    tracking_rms: float | None = None
    tracking_max: float | None = None
    fault_deviation: float | None = None
    recovery_time_s: float | None = None


@dataclass(frozen=True)
class ControlledSpec:
    """A controlled quantity: what the standard suites judge a controller by.

    ``target``: the scenario input that sets it; ``sensed``: the quantity a device sends of it
    (what the controller sees); ``truth``: the FMU output (what it is); ``band``: the +/- band
    (in ``unit``) of the response time and recovery; ``steps``: the set-points of the step
    suite (each from ``start``); ``profile``: (time s, set-point) breakpoints of the tracking
    suite, linear in between; ``settle_s``: time after each change before the steady state
    is judged.
    """

    target: str
    sensed: str
    truth: str
    unit: str
    band: float
    steps: tuple[float, ...]
    start: float = 0.0
    step_at_s: float = 1.0
    step_duration_s: float = 10.0
    steady_window_s: float = 2.0
    profile: tuple[tuple[float, float], ...] = ()
    fault_at_s: float = 5.0
    fault_duration_s: float = 2.0
    #: the smoothing of the truth and the sensed value before they are judged: a running
    #: median or mean over ``filter_s`` (a mean over a ripple's period removes it: a meter's
    #: flute pulsation), or none
    filter: Literal["median", "mean", "none"] = "median"
    filter_s: float = 0.2
    limits: Limits = field(default_factory=Limits)

    def __post_init__(self) -> None:
        _positive(self.band, "band")
        _positive(self.step_duration_s, "step_duration_s")
        _positive(self.steady_window_s, "steady_window_s")
        _positive(self.fault_duration_s, "fault_duration_s")
        _positive(self.filter_s, "filter_s")
        _non_negative(self.step_at_s, "step_at_s")
        _non_negative(self.fault_at_s, "fault_at_s")
        if not self.steps:
            raise ConfigError("give at least one step set-point", key="steps")
        if self.steady_window_s >= self.step_duration_s - self.step_at_s:
            raise ConfigError("the steady window must end after the step", key="steady_window_s")
        times = [t for t, _ in self.profile]
        if times != sorted(times) or any(t < 0 or not math.isfinite(t) for t in times):
            raise ConfigError("profile times must be >= 0 and increase", key="profile")
        if self.fault_at_s + self.fault_duration_s >= self.step_duration_s:
            raise ConfigError("fault_at_s + fault_duration_s must end before step_duration_s",
                              key="fault_duration_s")


@dataclass(frozen=True)
class RigFile:
    """A rig of your own, as its file says (paths still as written)."""

    name: str
    dbc: str
    fmu: FmuSpec
    devices: dict[str, DeviceSpec]
    description: str = ""
    dut_node: str = "Controller"
    dut_node_id: int = 0x10
    control_period_ms: float = 100.0
    trace_period_ms: float = 10.0
    bitrate_bps: int = 250_000
    scenarios: str = ""
    dispersion: str = ""
    #: named real-valued parameters of the rig (a campaign's dispersion draws them): a string
    #: in ``fmu.parameters`` names one (``B = ["motor_gain", 0.0, ...]``)
    parameters: dict[str, float] = field(default_factory=dict)
    inputs: dict[str, InputSpec] = field(default_factory=dict)
    controlled: dict[str, ControlledSpec] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ConfigError(f"a rig name is lower_snake_case, got {self.name!r}", key="name")
        _positive(self.control_period_ms, "control_period_ms")
        _positive(self.trace_period_ms, "trace_period_ms")
        if not 1 <= self.dut_node_id <= 127:
            raise ConfigError(f"the DUT's node id is 1..127, got {self.dut_node_id}",
                              key="dut_node_id")
        for key in ("control_period_ms", "trace_period_ms"):
            ratio = getattr(self, key) / self.fmu.step_ms
            if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
                raise ConfigError(f"must be a whole number of fmu.step_ms "
                                  f"({self.fmu.step_ms:g} ms)", key=key)
        for name in (*self.devices, *self.inputs, *self.controlled):
            if not _NAME.match(name):
                raise ConfigError(f"names are lower_snake_case, got {name!r}", key=name)


@dataclass(frozen=True)
class LoadedRigFile:
    """A rig file read and resolved: its spec, its own path, and absolute paths."""

    spec: RigFile
    path: Path
    source: str
    dbc: Path
    fmu: Path
    scenarios: Path | None
    dispersion: Path | None
    eds: dict[str, Path]
    #: ``fmu.parameters`` with the names of ``parameters`` replaced by their values
    fmu_parameters: dict[str, Any]


def resolve_parameters(spec: RigFile, label: str) -> dict[str, Any]:
    """``fmu.parameters`` with every string (a name of ``parameters``) replaced by its value.

    Raises
    ------
    ConfigError
        A string that names no parameter (naming the key and the element).
    """
    def one(value: Any, key: str) -> Any:
        if not isinstance(value, str):
            return value
        if value not in spec.parameters:
            raise ConfigError(f"{value!r} names no rig parameter (parameters: "
                              f"{', '.join(spec.parameters) or 'none'})", path=label, key=key)
        return spec.parameters[value]

    out: dict[str, Any] = {}
    for name, value in spec.fmu.parameters.items():
        key = f"fmu.parameters.{name}"
        if isinstance(value, list):
            out[name] = [one(v, f"{key}[{i}]") for i, v in enumerate(value)]
        else:
            out[name] = one(value, key)
    return out


def _resolve(base: Path, text: str) -> Path:
    path = Path(text).expanduser()
    return path if path.is_absolute() else (base / path).resolve()


def load_rig_file(path: str | Path, overrides: dict[str, Any] | None = None, *,
                  source: str = "") -> LoadedRigFile:
    """Read a rig file (with a profile's or a campaign's overrides applied), keys checked.

    Cross-checks against the FMU and the DBC are :func:`hil.ownrig.check.check_rig_file`'s.

    Raises
    ------
    ConfigError
        A missing file, bad TOML, unknown key, wrong type or bad value (naming the file and
        the key).
    """
    path = Path(path).resolve()
    spec = load_toml(path, RigFile, overrides=overrides or None, source=source or None)
    label = f"{source} (over {path.name})" if overrides else str(path)
    base = path.parent
    dbc = _resolve(base, spec.dbc)
    if not dbc.is_file():
        raise ConfigError(f"DBC not found: {dbc}", path=label, key="dbc")
    fmu = _resolve(base, spec.fmu.path)
    scenarios = _resolve(base, spec.scenarios) if spec.scenarios else None
    if scenarios is not None and not scenarios.is_dir():
        raise ConfigError(f"not a directory: {scenarios}", path=label, key="scenarios")
    dispersion = _resolve(base, spec.dispersion) if spec.dispersion else None
    if dispersion is not None and not dispersion.is_file():
        raise ConfigError(f"dispersion file not found: {dispersion}", path=label,
                          key="dispersion")
    eds = {}
    for name, device in spec.devices.items():
        if device.eds:
            eds[name] = _resolve(base, device.eds)
            if not eds[name].is_file():
                raise ConfigError(f"EDS not found: {eds[name]}", path=label,
                                  key=f"devices.{name}.eds")
    return LoadedRigFile(spec, path, label, dbc, fmu, scenarios, dispersion, eds,
                         resolve_parameters(spec, label))
