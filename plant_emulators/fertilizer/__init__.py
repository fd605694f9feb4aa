"""Fertilizer-flow rig of paper [F]: physics, sensor models and CAN database files.

Modules, one idea each:

``config``        rig configuration (frozen dataclasses from ``rig.toml``)
``flow_map``      fluted-roller flow map (shaft speed -> grams per second per row)
``physics``       :class:`FertilizerPlant`: servo motor, reducer, meters, tubes, truth
``flow_sensor``   :class:`FlowSensor`: capacitive flow detection module (block / sliding)
``ground_speed``  :class:`GroundSpeedModel`: tractor speed, ground-wheel Hall pulses, ISOBUS
``analog_output`` :class:`AnalogOutputChannel`: C-3402 output stage (raw mV -> volts)
``frames``        :class:`FertilizerDatabase`: typed codecs over ``db/fertilizer.dbc``
``noise``         seeded child generators and pre-drawn noise for the hot loops
``paper_data``    the paper's published figures the models are checked against

``frames`` is not imported here (it pulls in cantools and python-can).
"""

from plant_emulators.fertilizer.analog_output import AnalogOutputChannel
from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config
from plant_emulators.fertilizer.flow_sensor import FlowReport, FlowSensor, SensorStatus
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel
from plant_emulators.fertilizer.physics import FertilizerPlant

__all__ = [
    "AnalogOutputChannel",
    "FertilizerPlant",
    "FertilizerRigConfig",
    "FlowReport",
    "FlowSensor",
    "GroundSpeedModel",
    "SensorStatus",
    "load_rig_config",
]
