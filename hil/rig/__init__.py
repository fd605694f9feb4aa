"""Rigs: a plant emulator and its CAN devices, run against a DUT under a clock.

A rig package (``plant_emulators.<rig>``) subclasses :class:`Rig` (the physics and the devices)
and ships scenario files; :func:`run_scenario` is the one loop that runs any rig under either
clock. Rigs are found by name through :func:`hil.rig.registry.load_rig` and the
``agrihil.rigs`` entry point group.
"""

from hil.rig.base import Rig, RigContext
from hil.rig.device import Device, PeriodicDevice
from hil.rig.registry import available_rigs, load_rig
from hil.rig.runner import RunOptions, RunResult, run_scenario
from hil.rig.scenario import Event, Scenario, load_scenario

__all__ = ["Device", "Event", "PeriodicDevice", "Rig", "RigContext", "RunOptions", "RunResult",
           "Scenario", "available_rigs", "load_rig", "load_scenario", "run_scenario"]
