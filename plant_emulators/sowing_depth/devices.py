"""The sowing-depth rig's CAN nodes (and its GNSS serial port), as the controller sees them.

Plain frames carry the rig's quantities through the bus contract's codec
(:class:`hil.contract.codec.ContractCodec`: the rig's DBC under its default binding, or the
DUT's database under the profile's binding); the servo cylinder drive
is a CANopen CiA 402 node on its EDS whose object dictionary entries are the drive logic's own
(:class:`~plant_emulators.sowing_depth.cia402.Cia402Drive`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import can
import canopen

from hil.rig.canopen_device import PDO_LENGTH_ERROR, PDO_LENGTH_EXCEEDED, CanopenDevice
from hil.rig.device import PeriodicDevice
from plant_emulators.sowing_depth.cia402 import OBJECTS, DriveObjectError

if TYPE_CHECKING:
    from hil.contract.codec import ContractCodec
    from plant_emulators.sowing_depth.gnss_serial import GnssSerialPort
    from plant_emulators.sowing_depth.physics import SowingDepthPlant
    from plant_emulators.sowing_depth.sensors import DrawWireSensor, Inclinometer

#: ADC values outside this band mean a broken wire or a saturated output (sensor status)
_INCLINOMETER_VALID_MV = (20, 4980)


class ServoDriveDevice(CanopenDevice):
    """The servo electric cylinder's drive: CiA 402 on CANopen, node id from the wiring.

    Boots pre-operational, as a drive does: the controller (the CANopen master) starts it with
    NMT, configures it by SDO and runs it by PDO on SYNC."""

    def __init__(self, plant: SowingDepthPlant, node_id: int, eds: str) -> None:
        self.plant = plant
        self.drive = plant.drive
        super().__init__("servo cylinder drive", node_id, eds, autostart=False)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)

    def _on_read(self, index: int, subindex: int, od: Any) -> int | None:
        # drive.owns() inlined: every TPDO sample passes here
        if (index, subindex) in OBJECTS:
            return int(self.drive.read(index, subindex))
        return None

    def app_reader(self, index: int, subindex: int) -> Callable[[], int] | None:
        """The drive's reader of an object it owns (what :meth:`_on_read` answers), else None."""
        if (index, subindex) in OBJECTS:
            return self.drive.reader(index, subindex)
        return None

    def _on_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        if self.drive.owns(index, subindex):
            try:
                self.drive.write(index, subindex, od.decode_raw(data))
            except DriveObjectError as exc:
                raise canopen.SdoAbortedError(exc.abort_code) from exc

    def error_register(self) -> int:
        """0x1001: the drive's, from its present fault (0 once reset), and the node's own PDO
        length errors (communication, bit 4)."""
        active = self.errors.active
        if not active:
            return self.drive.error_register
        own = active.get(PDO_LENGTH_ERROR, 0) | active.get(PDO_LENGTH_EXCEEDED, 0)
        return self.drive.error_register | own

    def update_errors(self) -> None:
        """The drive's faults since the last call become the node's errors: a fault is raised
        (EMCY with its code, 0x1003 entry), a fault reset clears them (EMCY 0x0000)."""
        for code, register in self.drive.pop_emcy_events():
            if code:
                self.raise_error(code, register)
            else:
                self.clear_errors()


class DrawWireDevice(PeriodicDevice):
    def __init__(self, plant: SowingDepthPlant, sensor: DrawWireSensor, codec: ContractCodec,
                 period_s: float) -> None:
        super().__init__("draw-wire sensor", codec.period_s("roller_position", period_s))
        self.plant, self.sensor, self.codec = plant, sensor, codec
        self.counter = 0

    def frames(self, time_s: float) -> list[can.Message]:
        position = self.sensor.sample(self.plant.roller_position_mm)
        if position is None:       # the wire is lost: the node stops sending
            return []
        self.counter = (self.counter + 1) % 16
        return self.codec.encode({"roller_position": position,
                                  "roller_position_status": STATUS_OK,
                                  "roller_position_counter": self.counter})


class InclinometerDevice(PeriodicDevice):
    """The analog input node reading the LVT525H's two 0-5 V outputs, in mV.

    Fault hooks: ``lost`` (the node is off the bus: no frames), ``x_open_circuit`` (the X
    output's wire is broken: the module reads 0 mV there, status "below range"). The sensor
    is sampled either way, so its noise stream stays the same as in a run without the fault.
    """

    def __init__(self, plant: SowingDepthPlant, sensor: Inclinometer, codec: ContractCodec,
                 period_s: float) -> None:
        super().__init__("inclinometer", codec.period_s("inclinometer_x", period_s))
        self.plant, self.sensor, self.codec = plant, sensor, codec
        self.counter = 0
        self.last_x_mv = 0
        self.lost = False
        self.x_open_circuit = False

    def frames(self, time_s: float) -> list[can.Message]:
        p = self.plant
        reading = self.sensor.sample(time_s, p.arm.sensor_angle_deg(p.arm_angle_deg),
                                     p.machine_roll_deg, p.ground_speed_mps)
        if self.lost:
            return []
        x_mv = 0 if self.x_open_circuit else reading.x_mv
        self.counter = (self.counter + 1) % 16
        self.last_x_mv = x_mv
        return self.codec.encode({"inclinometer_x": x_mv, "inclinometer_y": reading.y_mv,
                                  "inclinometer_x_status": _status(x_mv),
                                  "inclinometer_y_status": _status(reading.y_mv),
                                  "inclinometer_counter": self.counter})


#: status values of the rig's quantities (the value tables of ``sowing_depth.dbc``)
STATUS_OK, STATUS_BELOW_RANGE, STATUS_ABOVE_RANGE = 0, 1, 2
DIRECTION_FORWARD = 1
ENABLE_OFF, ENABLE_ON = 0, 1
MODE_MANUAL, MODE_AUTOMATIC = 0, 1


def _status(mv: int) -> int:
    lo, hi = _INCLINOMETER_VALID_MV
    return STATUS_BELOW_RANGE if mv < lo else STATUS_ABOVE_RANGE if mv > hi else STATUS_OK


class TractorSpeedDevice(PeriodicDevice):
    """The tractor ECU's ground-based speed (ISO 11783 PGN 65097)."""

    def __init__(self, plant: SowingDepthPlant, codec: ContractCodec, period_s: float) -> None:
        super().__init__("tractor ground speed", codec.period_s("ground_speed", period_s))
        self.plant, self.codec = plant, codec

    def frames(self, time_s: float) -> list[can.Message]:
        return self.codec.encode({"ground_speed": self.plant.ground_speed_mps,
                                  "ground_distance": self.plant.distance_m,
                                  "ground_direction": DIRECTION_FORWARD})


class TerminalDevice(PeriodicDevice):
    """The CODESYS terminal sending the depth setpoint."""

    def __init__(self, codec: ContractCodec, period_s: float) -> None:
        super().__init__("terminal setpoint", codec.period_s("target_depth", period_s))
        self.codec = codec
        self.target_depth_mm = 30.0
        self.enable = True
        self.manual = False
        self.manual_roller_position_mm = 0.0
        self.counter = 0

    def frames(self, time_s: float) -> list[can.Message]:
        self.counter = (self.counter + 1) % 16
        return self.codec.encode({
            "target_depth": self.target_depth_mm,
            "manual_roller_position": self.manual_roller_position_mm,
            "depth_enable": ENABLE_ON if self.enable else ENABLE_OFF,
            "depth_mode": MODE_MANUAL if self.manual else MODE_AUTOMATIC,
            "setpoint_counter": self.counter})


class GnssDevice(PeriodicDevice):
    """The BeiDou receiver: NMEA 0183 (RMC, VTG, GGA) at 10 Hz on a pseudo-terminal the DUT
    opens by path. It sends nothing on the CAN bus."""

    def __init__(self, port: GnssSerialPort, period_s: float = 0.1) -> None:
        super().__init__("GNSS receiver", period_s)
        self.port = port

    def frames(self, time_s: float) -> list[can.Message]:
        self.port.emit(time_s)
        return []
