"""Sowing-depth rig of paper [D]: wheat planter 2BFG-12 with a CiA 402 servo cylinder.

Modules, one idea each (README.md has the equations, parameters, frames and measurements):

``config``          rig configuration (frozen dataclasses from ``rig.toml``)
``cylinder``        :class:`ServoCylinder`: servo motor, belt, 10:1 reducer, lead screw, rod
``motion_profile``  on-line trapezoidal moves and velocity ramps
``cia402_states``   the CiA 402 state machine as tables
``cia402_objects``  the drive's object dictionary: objects, types, units, error codes
``cia402``          :class:`Cia402Drive`: state machine, pp/pv modes, monitoring
``field``           the field's random processes along distance, pre-drawn in blocks
``arm``             :class:`PressArm`: post-sowing press arm geometry (angle <-> cover)
``physics``         :class:`SowingDepthPlant`: everything stepped together, 12 rows, truth
``sensors``         :class:`Inclinometer` (LVT525H + ADC), :class:`DrawWireSensor`
``nmea``            NMEA 0183 builders, checked parser, :class:`GnssReceiver`
``gnss_serial``     :class:`GnssSerialPort`: NMEA on a pseudo-terminal
``frames``          :class:`FrameCodec`: typed codecs over ``db/sowing_depth.dbc``

``frames`` is not imported here (it pulls in cantools and python-can).
"""

from plant_emulators.sowing_depth.arm import PressArm
from plant_emulators.sowing_depth.cia402 import Cia402Drive, DriveObjectError, DriveState
from plant_emulators.sowing_depth.config import SowingDepthRigConfig, load_rig_config
from plant_emulators.sowing_depth.cylinder import ServoCylinder
from plant_emulators.sowing_depth.gnss_serial import GnssSerialPort
from plant_emulators.sowing_depth.nmea import GnssReceiver
from plant_emulators.sowing_depth.physics import SowingDepthPlant, TruthCells
from plant_emulators.sowing_depth.sensors import (
    DrawWireSensor,
    Inclinometer,
    calibration_depth_mm,
)

__all__ = [
    "Cia402Drive",
    "DrawWireSensor",
    "DriveObjectError",
    "DriveState",
    "GnssReceiver",
    "GnssSerialPort",
    "Inclinometer",
    "PressArm",
    "ServoCylinder",
    "SowingDepthPlant",
    "SowingDepthRigConfig",
    "TruthCells",
    "calibration_depth_mm",
    "load_rig_config",
]
