"""The measurement triggers the TC sets on a client's process data after activation."""

from __future__ import annotations

from dataclasses import dataclass

from hil.isobus.ddi import REQUEST_DEFAULT_PROCESS_DATA
from hil.isobus.ddop import (
    ElementType,
    ObjectPool,
    ProcessData,
    ProcessDataProperty,
    TriggerMethod,
)
from hil.isobus.process_data import Command, ElementCommand


@dataclass(frozen=True)
class TriggerPlan:
    """Which measurement commands to send to every DPD that declares the trigger method.

    A field of ``None`` sends no command of that kind. Settable entities (set-points) get no
    triggers: the TC sets them rather than logs them.

    Attributes
    ----------
    time_interval_ms : int or None
        Measurement time interval (command 4) for DPDs with the time interval method.
    distance_interval_mm : int or None
        Measurement distance interval (command 5).
    change_threshold : int or None
        Change threshold (command 8) for DPDs with the on change method.
    minimum_threshold, maximum_threshold : int or None
        Threshold commands 6 and 7 for DPDs with the threshold limits method.
    request_default_process_data : bool
        Also send a request value of DDI 0xDFFF to the device element, which asks the client
        to start sending its default set (the DPDs with the default set property) as it
        chooses.
    """

    time_interval_ms: int | None = 1000
    distance_interval_mm: int | None = None
    change_threshold: int | None = 1
    minimum_threshold: int | None = None
    maximum_threshold: int | None = None
    request_default_process_data: bool = False

    def commands(self, pool: ObjectPool) -> list[ElementCommand]:
        """The measurement commands for ``pool``, element by element in pool order."""
        out: list[ElementCommand] = []
        plan = [
            (TriggerMethod.TIME_INTERVAL, Command.MEASUREMENT_TIME_INTERVAL,
             self.time_interval_ms),
            (TriggerMethod.DISTANCE_INTERVAL, Command.MEASUREMENT_DISTANCE_INTERVAL,
             self.distance_interval_mm),
            (TriggerMethod.THRESHOLD_LIMITS, Command.MEASUREMENT_MINIMUM_THRESHOLD,
             self.minimum_threshold),
            (TriggerMethod.THRESHOLD_LIMITS, Command.MEASUREMENT_MAXIMUM_THRESHOLD,
             self.maximum_threshold),
            (TriggerMethod.ON_CHANGE, Command.MEASUREMENT_CHANGE_THRESHOLD,
             self.change_threshold),
        ]
        for element in pool.elements:
            if self.request_default_process_data and element.element_type == ElementType.DEVICE:
                out.append(ElementCommand(Command.REQUEST_VALUE, element.element_number,
                                          REQUEST_DEFAULT_PROCESS_DATA))
            for child in pool.children(element):
                if not isinstance(child, ProcessData):
                    continue
                if child.properties & ProcessDataProperty.SETTABLE:
                    continue
                for method, command, value in plan:
                    if value is not None and child.trigger_methods & method:
                        out.append(ElementCommand(command, element.element_number, child.ddi,
                                                  value))
        return out
