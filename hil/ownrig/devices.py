"""The CAN nodes of a rig of your own: senders, actuators and plain CANopen nodes.

:class:`SenderDevice` sends one DBC message on its period (and, with ``on_change``, as soon as
a value changes), each signal from an FMU output through its sensor model, a scenario input,
a counter or a constant. :class:`ActuatorDevice` takes one message from the controller into
FMU inputs and, when its commands stop for ``timeout_ms``, holds, zeroes or goes to its safe
values. :class:`NmtNode` plays a CANopen node's heartbeat and NMT state for a device without
an EDS. All encode and decode through the rig's :class:`~hil.contract.codec.ContractCodec`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import can

from hil.contract.codec import ContractCodec
from hil.ownrig.config import ReceivedMessage, SentMessage
from hil.ownrig.fmu import FmuPlant
from hil.ownrig.plan import MessagePlan
from hil.ownrig.sensor import SensorModel
from hil.rig.device import Device

NMT_ID = 0x000
OPERATIONAL, STOPPED, PRE_OPERATIONAL = 0x05, 0x04, 0x7F


class NmtNode(Device):
    """A CANopen node's heartbeat and NMT state (boot-up, start, stop, pre-op, resets).

    Parameters
    ----------
    name : str
        The device's name.
    node_id : int
        Its node id (heartbeat COB-ID 0x700 + id).
    heartbeat_s : float
        Heartbeat period; 0: none (NMT only).
    note : callable
        The run's note function (a state change is noted).
    """

    def __init__(self, name: str, node_id: int, heartbeat_s: float,
                 note: Callable[[float, str, str], None]) -> None:
        self.name = f"{name} (CANopen node {node_id})"
        self.node_id = node_id
        self.heartbeat_s = heartbeat_s
        self.state = OPERATIONAL
        self._note = note
        self._bootup = True
        self._due = 0.0

    @property
    def operational(self) -> bool:
        return self.state == OPERATIONAL

    def next_due(self, time_s: float) -> float:
        if self._bootup:
            return max(self._due, time_s)
        if self.heartbeat_s <= 0:
            return math.inf
        return self._due if self._due > time_s else time_s + self.heartbeat_s

    def emit(self, time_s: float) -> list[can.Message]:
        if self.silent:
            self._due = time_s + (self.heartbeat_s or 1.0)
            return []
        state = 0x00 if self._bootup else self.state
        self._bootup = False
        self._due = time_s + self.heartbeat_s if self.heartbeat_s > 0 else math.inf
        return [can.Message(arbitration_id=0x700 + self.node_id, data=bytes([state]),
                            is_extended_id=False)]

    def accepts(self, msg: can.Message) -> bool:
        return (msg.arbitration_id == NMT_ID and not msg.is_extended_id and len(msg.data) >= 2
                and msg.data[1] in (0, self.node_id))

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        command = msg.data[0]
        state = {0x01: OPERATIONAL, 0x02: STOPPED, 0x80: PRE_OPERATIONAL}.get(command)
        if command in (0x81, 0x82):          # reset node / communication: boot-up, autostart
            self._bootup, self._due, state = True, time_s, OPERATIONAL
        if state is not None and (state != self.state or command in (0x81, 0x82)):
            self._note(time_s, "nmt", f"{self.name}: command 0x{command:02X}")
            self.state = state
        return []


class SenderDevice(Device):
    """One message a device sends.

    Parameters
    ----------
    plan : MessagePlan
        The message, its period and its signals.
    codec : ContractCodec
        The rig's codec (quantities to frames).
    plant : FmuPlant
        The FMU (the sources of ``fmu`` signals).
    sensors : dict
        Quantity name → its sensor model (``fmu`` signals only).
    inputs : callable
        The scenario input's value now, by name.
    step_s : float
        The physics step (``on_change`` messages are checked every step).
    gate : callable, optional
        False while the node may not send (a CANopen node not operational).
    """

    def __init__(self, plan: MessagePlan, codec: ContractCodec, plant: FmuPlant,
                 sensors: dict[str, SensorModel], inputs: Callable[[str], float],
                 step_s: float, gate: Callable[[], bool] | None = None) -> None:
        spec = plan.spec
        assert isinstance(spec, SentMessage)
        self.name = f"{plan.device}: {plan.message}"
        self.device = plan.device
        self.plan = plan
        self.codec = codec
        self.plant = plant
        self.period_s = plan.period_s
        self.offset_s = spec.offset_ms / 1000.0
        self.on_change = spec.on_change
        self.min_interval_s = max(spec.min_interval_ms / 1000.0, step_s)
        self.step_s = step_s
        self.gate = gate
        self.frozen = False
        self.sensors = sensors
        self._inputs = inputs
        self._counters = {s.quantity: -1 for s in plan.sent if s.spec.counter}
        self._last_frames: list[can.Message] = []
        self._last_values: dict[str, float] = {}
        self._sent_at = -math.inf
        self._period_due = self.offset_s if self.period_s is not None else math.inf
        self._bounds = {q.name: (q.minimum, q.maximum) for q in codec.contract.quantities}
        #: the values last sent, by quantity (what the controller saw): traced
        self.sensed: dict[str, float] = {s.quantity: math.nan for s in plan.sent}
        self._slots = {s.quantity: plant.slot(s.source.text) for s in plan.sent
                       if s.source is not None}

    def _next_period(self, time_s: float) -> float:
        """The first period time strictly after ``time_s``."""
        if self.period_s is None:
            return math.inf
        if time_s < self.offset_s:
            return self.offset_s
        k = math.floor((time_s - self.offset_s) / self.period_s + 1e-9) + 1
        return self.offset_s + k * self.period_s

    def next_due(self, time_s: float) -> float:
        due = self._period_due if self._period_due > time_s else self._next_period(time_s)
        if self.on_change:
            due = min(due, time_s + self.step_s)
        return due

    def _values(self, time_s: float) -> dict[str, float]:
        values = self.plant.values()
        out: dict[str, float] = {}
        for s in self.plan.sent:
            spec = s.spec
            if s.source is not None:
                value = self.sensors[s.quantity].sample(time_s, values[self._slots[s.quantity]])
            elif spec.input:
                value = self._inputs(spec.input)
            elif spec.counter:
                value = float(self._counters[s.quantity] + 1)
            else:
                value = float(spec.value or 0.0)
            low, high = self._bounds[s.quantity]
            out[s.quantity] = min(max(value, low), high)
        return out

    def emit(self, time_s: float) -> list[can.Message]:
        if self.silent or (self.gate is not None and not self.gate()):
            return []
        periodic = time_s >= self._period_due - 1e-9
        if periodic:
            self._period_due = self._next_period(time_s)
        if self.frozen and self._last_frames:
            return list(self._last_frames) if periodic else []
        values = self._values(time_s)
        if not periodic:   # an on_change check between periods
            changed = any(values[k] != self._last_values.get(k) for k in values
                          if k not in self._counters)
            if not changed or time_s - self._sent_at < self.min_interval_s - 1e-9:
                return []
        for name in self._counters:
            wrap = int(self._bounds[name][1]) + 1
            self._counters[name] = (self._counters[name] + 1) % wrap
            values[name] = float(self._counters[name])
        frames = self.codec.encode(values)
        self._last_frames, self._last_values, self._sent_at = frames, values, time_s
        self.sensed.update(values)
        return frames


class ActuatorDevice(Device):
    """One message a device takes from the controller into FMU inputs.

    Parameters
    ----------
    plan : MessagePlan
        The message and its signals.
    codec : ContractCodec
        The rig's codec.
    plant : FmuPlant
        The FMU (its inputs are written).
    note : callable
        The run's note function (commands lost and back are noted).
    gate : callable, optional
        False while the node ignores frames (a CANopen node not operational).
    """

    def __init__(self, plan: MessagePlan, codec: ContractCodec, plant: FmuPlant,
                 note: Callable[[float, str, str], None],
                 gate: Callable[[], bool] | None = None) -> None:
        spec = plan.spec
        assert isinstance(spec, ReceivedMessage)
        self.name = f"{plan.device}: {plan.message}"
        self.device = plan.device
        self.plan = plan
        self.codec = codec
        self.plant = plant
        self.frame_id = plan.frame_id
        self.timeout_s = spec.timeout_ms / 1000.0
        self.on_timeout = spec.on_timeout
        self.gate = gate
        self._note = note
        self._last_rx = -math.inf
        self.timed_out = False
        #: the value each FMU input has now, by quantity (in the signal's unit): traced
        self.commanded: dict[str, float] = {}
        for r in plan.received:
            self._write(r.quantity, r.spec.initial)

    def _write(self, quantity: str, value: float) -> None:
        r = next(x for x in self.plan.received if x.quantity == quantity)
        self.commanded[quantity] = value
        self.plant.set(r.target, r.spec.gain * value + r.spec.offset)

    def next_due(self, time_s: float) -> float:
        if self.timeout_s <= 0 or self.timed_out or self._last_rx == -math.inf:
            return math.inf
        due = self._last_rx + self.timeout_s
        return due if due > time_s else time_s

    def emit(self, time_s: float) -> list[can.Message]:
        if (self.timeout_s > 0 and not self.timed_out and self._last_rx > -math.inf
                and time_s - self._last_rx >= self.timeout_s - 1e-9):
            self.timed_out = True
            self._note(time_s, "actuator-timeout",
                       f"{self.name}: no command for {self.timeout_s * 1000:g} ms: "
                       f"{self.on_timeout}")
            if self.on_timeout != "hold":
                for r in self.plan.received:
                    self._write(r.quantity, r.spec.safe if self.on_timeout == "safe" else 0.0)
        return []

    def accepts(self, msg: can.Message) -> bool:
        return msg.arbitration_id == self.frame_id

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        if self.gate is not None and not self.gate():
            return []
        values = self.codec.decode(msg)
        if not values:
            return []
        if self.timed_out:
            self._note(time_s, "actuator-timeout", f"{self.name}: commands back")
        self.timed_out = False
        self._last_rx = time_s
        for r in self.plan.received:
            if r.quantity in values:
                self._write(r.quantity, float(values[r.quantity]))
        return []
