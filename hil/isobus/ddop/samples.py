"""Ready-made pools: an AgIsoStack++-style section control implement, for tests and references.

:func:`section_control_pool` is the shape AgIsoStack++'s section control example describes (a
device, a connector, a boom function with its offsets and width, a product bin, N sections with
offsets and widths, condensed work states, the rate set-point and actual) with the rig's own
DDIs: mass per area rate (DDI 6/7) for a fertilizer meter, and the look-ahead times (DDI 205/206).
"""

from __future__ import annotations

from hil.isobus import ddi
from hil.isobus.ddop.builder import PoolBuilder
from hil.isobus.ddop.codec import serialise_pool
from hil.isobus.ddop.objects import (
    DdopObject,
    Device,
    DeviceElement,
    ElementType,
    Property,
    TriggerMethod,
)
from hil.isobus.ddop.pool import ObjectPool

ON_CHANGE_OR_TIME = TriggerMethod.ON_CHANGE | TriggerMethod.TIME_INTERVAL


def section_control_pool(*, sections: int = 4, section_width_mm: int = 500,
                         name: int = 0xA00C80000AE00002, structure_label: bytes = b"AGRIHIL",
                         version: int = 4, turn_on_ms: int = 300,
                         turn_off_ms: int = 200) -> ObjectPool:
    """A fertilizer planter with one boom of ``sections`` sections (validated).

    Parameters
    ----------
    sections : int
        Number of sections (1 .. 256); each gets an element, offsets and a width.
    section_width_mm : int
        Width of each section; the boom's working width is their sum.
    name : int
        The client's NAME, which the device object carries.
    structure_label : bytes
        Up to 7 bytes; padded with spaces.
    version : int
        ISO 11783-10 version of the pool.
    turn_on_ms, turn_off_ms : int
        Look-ahead times declared as DDI 205/206 properties of the boom.
    """
    b = PoolBuilder(version=version)
    dvc = b.device("agrihil planter", software_version="1.0.0", name=name, serial_number="1",
                   structure_label=structure_label)
    mm = b.presentation("mm")
    metres = b.presentation("m", scale=0.001, decimals=2)
    kg_ha = b.presentation("kg/ha", scale=0.01, decimals=1)
    device = b.element(ElementType.DEVICE, "Planter", parent=dvc)
    b.process_data(device, ddi=ddi.ACTUAL_WORK_STATE, designator="Actual work state")
    b.process_data(device, ddi=ddi.REQUEST_DEFAULT_PROCESS_DATA, designator="Default PD",
                   default_set=False, triggers=TriggerMethod.TOTAL)
    b.process_data(device, ddi=ddi.TOTAL_AREA, designator="Total area",
                   triggers=TriggerMethod.TOTAL)
    connector = b.element(ElementType.CONNECTOR, "Connector", parent=device)
    b.property(connector, ddi=ddi.DEVICE_ELEMENT_OFFSET_X, value=0, designator="Offset X",
               presentation=mm)
    b.property(connector, ddi=ddi.DEVICE_ELEMENT_OFFSET_Y, value=0, designator="Offset Y",
               presentation=mm)
    b.property(connector, ddi=ddi.CONNECTOR_TYPE, value=9, designator="Type")
    boom = b.element(ElementType.FUNCTION, "Boom", parent=device)
    b.property(boom, ddi=ddi.DEVICE_ELEMENT_OFFSET_X, value=-1500, designator="Offset X",
               presentation=mm)
    b.property(boom, ddi=ddi.DEVICE_ELEMENT_OFFSET_Y, value=0, designator="Offset Y",
               presentation=mm)
    b.property(boom, ddi=ddi.DEVICE_ELEMENT_OFFSET_Z, value=0, designator="Offset Z",
               presentation=mm)
    b.property(boom, ddi=ddi.SC_SETPOINT_TURN_ON_TIME, value=turn_on_ms,
               designator="Turn on time")
    b.property(boom, ddi=ddi.SC_SETPOINT_TURN_OFF_TIME, value=turn_off_ms,
               designator="Turn off time")
    b.process_data(boom, ddi=ddi.ACTUAL_WORKING_WIDTH, designator="Working width",
                   presentation=metres)
    b.process_data(boom, ddi=ddi.SETPOINT_WORK_STATE, designator="Setpoint work state",
                   settable=True)
    b.process_data(boom, ddi=ddi.SECTION_CONTROL_STATE, designator="Section control state",
                   settable=True, triggers=ON_CHANGE_OR_TIME)
    for first in range(0, sections, ddi.SECTIONS_PER_CONDENSED_DDI):
        actual, _ = ddi.condensed_work_state_ddi(first, setpoint=False)
        setpoint, _ = ddi.condensed_work_state_ddi(first, setpoint=True)
        span = f"{first + 1}-{first + 16}"
        b.process_data(boom, ddi=actual, designator=f"Actual work state {span}")
        b.process_data(boom, ddi=setpoint, designator=f"Setpoint work state {span}",
                       settable=True)
    product = b.element(ElementType.BIN, "Product", parent=boom)
    b.process_data(product, ddi=ddi.SETPOINT_MASS_PER_AREA_RATE, designator="Target rate",
                   settable=True, presentation=kg_ha)
    b.process_data(product, ddi=ddi.ACTUAL_MASS_PER_AREA_RATE, designator="Actual rate",
                   triggers=ON_CHANGE_OR_TIME | TriggerMethod.DISTANCE_INTERVAL
                   | TriggerMethod.THRESHOLD_LIMITS, presentation=kg_ha)
    b.process_data(product, ddi=ddi.PRESCRIPTION_CONTROL_STATE,
                   designator="Rx control state", settable=True)
    total = sections * section_width_mm
    for i in range(sections):
        section = b.element(ElementType.SECTION, f"Section {i + 1}", parent=boom)
        b.property(section, ddi=ddi.DEVICE_ELEMENT_OFFSET_X, value=0, designator="Offset X",
                   presentation=mm)
        b.property(section, ddi=ddi.DEVICE_ELEMENT_OFFSET_Y,
                   value=-total // 2 + i * section_width_mm + section_width_mm // 2,
                   designator="Offset Y", presentation=mm)
        b.property(section, ddi=ddi.ACTUAL_WORKING_WIDTH, value=section_width_mm,
                   designator="Width", presentation=metres)
    return b.build()


def parent_chain_pool(elements: int, *, name: int = 0xA00C80000AE00002,
                      designator: bytes = b"", width_mm: int | None = None) -> bytes:
    """The bytes of a pool whose ``elements`` function elements each hang from the one before:
    the deepest parent chain a pool of its size can have (6,000 elements: 78 kB), for timing
    the validation of large pools. Element numbers beyond 4,095 break the standard's 12 bits
    and a validating TC refuses the pool; it must take time in proportion to its size to say
    so. Not validated here. With ``width_mm`` the device element carries a working width
    (DDI 67), so that a pool within the 12 bits is one the rig's tractor can use."""
    objects: list[DdopObject] = [
        Device(0, b"Chain", b"1", name, b"1", b"CHAIN  ", b"en\x00\x00\x00\x00\xff", b"")]
    if width_mm is None:
        objects.append(DeviceElement(1, ElementType.DEVICE, b"Chain", 0, 0))
    else:
        oid = elements + 2
        objects += [DeviceElement(1, ElementType.DEVICE, b"Chain", 0, 0, (oid,)),
                    Property(oid, ddi.ACTUAL_WORKING_WIDTH, width_mm, b"Width")]
    for k in range(elements):
        objects.append(DeviceElement(2 + k, ElementType.FUNCTION, designator, 1 + k, 1 + k))
    return serialise_pool(objects, version=4)
