"""The tractor ECU (TECU) as an internal control function: ISO 11783-7 speed and distance.

Every 100 ms at priority 3, from the moment its address claim settles, the TECU sends

- PGN 65096 (0xFE48) wheel-based speed and distance, with the key switch, the implement
  start/stop state, the direction and the maximum time of tractor power;
- PGN 65097 (0xFE49) ground-based speed and distance;
- PGN 61474 (0xF022) machine selected speed and distance, with the source of that speed.

The values come from a callable returning the scenario's truth (:class:`TractorState`). The
wheel-based speed over-reads the ground speed by the drive-wheel slip, ``v / (1 - slip)``, as
the fertilizer rig's ground-speed model has it; the ground-based speed is the ground speed.
Distances are integrated from the speeds between two messages unless the truth gives them.
Every frame is encoded by cantools from ``hil/isobus/db/iso11783_7.dbc``.

Its NAME: industry group 2 (agriculture), function 134 "tractor ECU" (ISO 11783-1's function
table as AgIsoStack++ carries it, under device class 0, non-specific system). Where sources
disagree: docs/isobus.md puts the TECU at preferred address 128 (0x80); J1939's table of
preferred addresses for industry group 2 (as AgIsoStack++ carries it) and the fertilizer rig's
DBC put it at 240 (0xF0). 0x80 is the default here, as the issue asks; ``address`` changes it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import cantools
from cantools.database.can import Database

from hil.errors import FrameError
from hil.isobus.name import IsobusName
from hil.isobus.network import TIME_TOLERANCE_S, InternalControlFunction, IsobusNetwork

DBC_PATH = Path(__file__).with_name("db") / "iso11783_7.dbc"
PGN_WHEEL_BASED_SPEED = 0xFE48
PGN_GROUND_BASED_SPEED = 0xFE49
PGN_MACHINE_SELECTED_SPEED = 0xF022
PERIOD_S = 0.1
PRIORITY = 3
TECU_FUNCTION = 134
TECU_ADDRESS = 0x80
DISTANCE_WRAP_M = 4_211_081.215
SPEED_MAX_MPS = 64.255

TECU_NAME = IsobusName(identity_number=0x1EC, manufacturer_code=0, function=TECU_FUNCTION,
                       device_class=0, industry_group=2)
"""The rig's TECU NAME (identity number arbitrary, manufacturer code 0: no manufacturer)."""


class Direction(enum.IntEnum):
    """Machine direction of travel (2 bits)."""

    REVERSE = 0
    FORWARD = 1
    ERROR = 2
    NOT_AVAILABLE = 3


class SpeedSource(enum.IntEnum):
    """Source of the machine selected speed (3 bits)."""

    WHEEL_BASED = 0
    GROUND_BASED = 1
    NAVIGATION_BASED = 2
    BLENDED = 3
    SIMULATED = 4
    NOT_AVAILABLE = 7


@dataclass(frozen=True)
class TractorState:
    """What the TECU reports, from the scenario's truth.

    Parameters
    ----------
    ground_speed_mps : float
        True speed over the ground (>= 0; the direction is separate).
    wheel_slip : float
        Slip of the tractor's driven wheels, 0 <= slip < 1.
    direction : Direction
        Direction of travel.
    key_switch_on : bool
        Key switch state (False: off).
    implement_start : bool or None
        Implement start/stop operations: True start, False stop, None not available.
    speed_source : SpeedSource
        Which speed the machine selected speed carries (wheel, ground, navigation (as the
        ground speed), blended (as the ground speed), simulated (as the ground speed)).
    wheel_distance_m, ground_distance_m : float or None
        Distances, if the truth keeps them; else the TECU integrates the speeds.
    max_time_of_tractor_power_min : int
        Minutes of power after key-off (255: not available).
    """

    ground_speed_mps: float
    wheel_slip: float = 0.0
    direction: Direction = Direction.FORWARD
    key_switch_on: bool = True
    implement_start: bool | None = None
    speed_source: SpeedSource = SpeedSource.GROUND_BASED
    wheel_distance_m: float | None = None
    ground_distance_m: float | None = None
    max_time_of_tractor_power_min: int = 255

    @property
    def wheel_based_speed_mps(self) -> float:
        """The wheel-based speed: the ground speed over-read by the slip."""
        return self.ground_speed_mps / (1.0 - self.wheel_slip)


@cache
def iso11783_7_database() -> Database:
    """The ISO 11783-7 messages of :data:`DBC_PATH`, loaded once."""
    db = cantools.database.load_file(DBC_PATH)
    assert isinstance(db, Database)
    return db


class TractorEcu:
    """The TECU application: runs on an internal control function's port.

    Parameters
    ----------
    port : InternalControlFunction
        Its control function on the network.
    truth : callable
        ``truth(now_s) -> TractorState``.
    period_s : float
        Message period (100 ms in ISO 11783-7).

    Raises
    ------
    FrameError
        A state the messages cannot carry (negative speed, slip outside [0, 1)), when it is
        encoded, naming the field and the time.
    """

    def __init__(self, port: InternalControlFunction, truth: Callable[[float], TractorState],
                 period_s: float = PERIOD_S) -> None:
        self.port = port
        self.truth = truth
        self.period_s = period_s
        self._next_s: float | None = None
        self._first_s: float | None = None
        self._last_s: float | None = None
        self.wheel_distance_m = 0.0
        self.ground_distance_m = 0.0
        self.sent = 0
        #: True: the TECU sends nothing (its speed is lost to the implement); the schedule and
        #: the distances go on
        self.silent = False
        db = iso11783_7_database()
        self._wheel = db.get_message_by_name("WheelBasedSpeedDist")
        self._ground = db.get_message_by_name("GroundBasedSpeedDist")
        self._selected = db.get_message_by_name("MachineSelectedSpeed")

    def next_due(self, now_s: float) -> float:
        """When the next messages go (``inf`` until the address has settled)."""
        if self.port.address is None:
            return math.inf
        return now_s if self._next_s is None else self._next_s

    def tick(self, now_s: float) -> None:
        """Send the three messages if they are due."""
        if self.port.address is None:
            return
        if self._next_s is not None and now_s + TIME_TOLERANCE_S < self._next_s:
            return
        state = self.truth(now_s)
        self._integrate(state, now_s)
        for pgn, data in self.encode(state):
            if not self.silent:
                self.port.send(pgn, data, priority=PRIORITY)
        self.sent += 1
        if self._first_s is None:
            self._first_s = now_s
        # the k-th period from the first message, not a running sum: a runner's tick grid
        # (k * dt) meets it without float drift; a late tick does not send a burst
        k = math.floor((now_s - self._first_s) / self.period_s + 1e-6) + 1
        self._next_s = self._first_s + k * self.period_s

    def encode(self, state: TractorState) -> list[tuple[int, bytes]]:
        """The (PGN, 8 data bytes) of the three messages for ``state``."""
        if not (math.isfinite(state.ground_speed_mps) and state.ground_speed_mps >= 0):
            raise FrameError(f"TECU: ground_speed_mps = {state.ground_speed_mps} is not a speed "
                             f">= 0 m/s")
        if not 0.0 <= state.wheel_slip < 1.0:
            raise FrameError(f"TECU: wheel_slip = {state.wheel_slip} is outside [0, 1)")
        wheel_v = min(state.wheel_based_speed_mps, SPEED_MAX_MPS)
        ground_v = min(state.ground_speed_mps, SPEED_MAX_MPS)
        wheel_d = _wrap(state.wheel_distance_m if state.wheel_distance_m is not None
                        else self.wheel_distance_m)
        ground_d = _wrap(state.ground_distance_m if state.ground_distance_m is not None
                         else self.ground_distance_m)
        direction = int(state.direction)
        start = 3 if state.implement_start is None else int(state.implement_start)
        wheel = self._wheel.encode({
            "WheelBasedMachineSpeed": wheel_v, "WheelBasedMachineDistance": wheel_d,
            "MaxTimeOfTractorPower": state.max_time_of_tractor_power_min,
            "MachineDirection": direction, "KeySwitchState": int(state.key_switch_on),
            "ImplementStartStop": start, "OperatorDirectionReversed": 0})
        ground = self._ground.encode({
            "GroundBasedMachineSpeed": ground_v, "GroundBasedMachineDistance": ground_d,
            "ReservedByte7": 0xFF, "MachineDirection": direction, "ReservedByte8": 0x3F})
        by_wheel = state.speed_source == SpeedSource.WHEEL_BASED
        selected = self._selected.encode({
            "MachineSelectedSpeed": wheel_v if by_wheel else ground_v,
            "MachineSelectedSpeedDistance": wheel_d if by_wheel else ground_d,
            "ExitReasonCode": 0x3F, "ReservedByte7": 0x3, "MachineDirection": direction,
            "SpeedSource": int(state.speed_source), "LimitStatus": 0})
        return [(PGN_WHEEL_BASED_SPEED, bytes(wheel)), (PGN_GROUND_BASED_SPEED, bytes(ground)),
                (PGN_MACHINE_SELECTED_SPEED, bytes(selected))]

    def _integrate(self, state: TractorState, now_s: float) -> None:
        if self._last_s is not None:
            dt = now_s - self._last_s
            self.wheel_distance_m = _wrap(self.wheel_distance_m
                                          + state.wheel_based_speed_mps * dt)
            self.ground_distance_m = _wrap(self.ground_distance_m + state.ground_speed_mps * dt)
        self._last_s = now_s


def _wrap(distance_m: float) -> float:
    """Distances restart at 0 beyond the largest the message carries."""
    return math.fmod(distance_m, DISTANCE_WRAP_M)


def add_tecu(network: IsobusNetwork, truth: Callable[[float], TractorState],
             name: IsobusName = TECU_NAME, address: int = TECU_ADDRESS) -> TractorEcu:
    """Host a TECU on ``network`` and run it.

    Parameters
    ----------
    network : IsobusNetwork
        The rig's network.
    truth : callable
        ``truth(now_s) -> TractorState``.
    name : IsobusName
        Its NAME (function 134).
    address : int
        Its preferred address.

    Returns
    -------
    TractorEcu
        The running application.
    """
    cf = network.add(name, address, "TECU")
    tecu = TractorEcu(cf, truth)
    cf.run(tecu)
    return tecu
