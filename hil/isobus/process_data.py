"""Process data messages of ISO 11783-10 (PGN 0xCB00) and the working-set master message.

Every process data message starts with a command byte: the low nibble is the command, the high
nibble either a sub-command (technical capabilities, device descriptor) or the low 4 bits of a
12-bit element number whose high 8 bits are byte 2. Element commands then carry the DDI (16 bits,
little-endian) and a 32-bit value::

    byte 1        byte 2        bytes 3-4  bytes 5-8
    EEEE CCCC     EEEE EEEE     DDI        value

:func:`decode` turns a payload into one of the frozen message classes below and :func:`encode`
back; every class encodes to exactly the bytes it was decoded from when the reserved bytes are
0xFF as the standard sends them. Byte layouts follow ISO 11783-10 as implemented by AgIsoStack++
(``isobus_task_controller_server.cpp``/``_client.cpp``), checked field by field against it.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, IntFlag

from hil.errors import FrameError

PROCESS_DATA_PGN = 0xCB00
"""Process data, client to TC and TC to client (PDU1: the destination is the other side)."""
WORKING_SET_MASTER_PGN = 0xFE0D
"""Working-set master, broadcast by the client's master (ISO 11783-7/-10)."""

ELEMENT_NUMBER_ALL = 0xFFF
"""The element number of messages that are not about an element (status, client task)."""
DDI_NONE = 0xFFFF


class Command(IntEnum):
    """The command nibble of byte 1."""

    TECHNICAL_CAPABILITIES = 0x0
    DEVICE_DESCRIPTOR = 0x1
    REQUEST_VALUE = 0x2
    VALUE = 0x3
    MEASUREMENT_TIME_INTERVAL = 0x4
    MEASUREMENT_DISTANCE_INTERVAL = 0x5
    MEASUREMENT_MINIMUM_THRESHOLD = 0x6
    MEASUREMENT_MAXIMUM_THRESHOLD = 0x7
    MEASUREMENT_CHANGE_THRESHOLD = 0x8
    PEER_CONTROL_ASSIGNMENT = 0x9
    SET_VALUE_AND_ACKNOWLEDGE = 0xA
    ACKNOWLEDGE = 0xD
    STATUS = 0xE
    CLIENT_TASK = 0xF


ELEMENT_COMMANDS = frozenset({
    Command.REQUEST_VALUE, Command.VALUE, Command.MEASUREMENT_TIME_INTERVAL,
    Command.MEASUREMENT_DISTANCE_INTERVAL, Command.MEASUREMENT_MINIMUM_THRESHOLD,
    Command.MEASUREMENT_MAXIMUM_THRESHOLD, Command.MEASUREMENT_CHANGE_THRESHOLD,
    Command.SET_VALUE_AND_ACKNOWLEDGE,
})
"""Commands of the form element number + DDI + value."""

MEASUREMENT_COMMANDS = frozenset({
    Command.MEASUREMENT_TIME_INTERVAL, Command.MEASUREMENT_DISTANCE_INTERVAL,
    Command.MEASUREMENT_MINIMUM_THRESHOLD, Command.MEASUREMENT_MAXIMUM_THRESHOLD,
    Command.MEASUREMENT_CHANGE_THRESHOLD,
})


class TechnicalCapability(IntEnum):
    """Sub-commands of technical capabilities (command 0)."""

    REQUEST_VERSION = 0x0
    VERSION = 0x1
    IDENTIFY_TASK_CONTROLLER = 0x2


class DeviceDescriptorCommand(IntEnum):
    """Sub-commands of device descriptor (command 1)."""

    REQUEST_STRUCTURE_LABEL = 0x0
    STRUCTURE_LABEL = 0x1
    REQUEST_LOCALIZATION_LABEL = 0x2
    LOCALIZATION_LABEL = 0x3
    REQUEST_OBJECT_POOL_TRANSFER = 0x4
    REQUEST_OBJECT_POOL_TRANSFER_RESPONSE = 0x5
    OBJECT_POOL_TRANSFER = 0x6
    OBJECT_POOL_TRANSFER_RESPONSE = 0x7
    OBJECT_POOL_ACTIVATE_DEACTIVATE = 0x8
    OBJECT_POOL_ACTIVATE_DEACTIVATE_RESPONSE = 0x9
    DELETE_OBJECT_POOL = 0xA
    DELETE_OBJECT_POOL_RESPONSE = 0xB
    CHANGE_DESIGNATOR = 0xC
    CHANGE_DESIGNATOR_RESPONSE = 0xD


class VersionOption(IntFlag):
    """Byte 4 of the version message: what the TC (or client) supports."""

    DOCUMENTATION = 0x01
    TC_GEO_WITHOUT_POSITION_BASED_CONTROL = 0x02
    TC_GEO_WITH_POSITION_BASED_CONTROL = 0x04
    PEER_CONTROL_ASSIGNMENT = 0x08
    IMPLEMENT_SECTION_CONTROL = 0x10


class AckError(IntFlag):
    """Process data acknowledge error bits (byte 5)."""

    NONE = 0x00
    COMMAND_NOT_SUPPORTED = 0x01
    INVALID_ELEMENT_NUMBER = 0x02
    DDI_NOT_SUPPORTED_BY_ELEMENT = 0x04
    TRIGGER_METHOD_NOT_SUPPORTED = 0x08
    NOT_SETTABLE = 0x10
    INVALID_INTERVAL_OR_THRESHOLD = 0x20
    VALUE_DOES_NOT_CONFORM_TO_DDI = 0x40
    VALUE_OUT_OF_OPERATIONAL_RANGE = 0x80


class ServerStatus(IntFlag):
    """Byte 5 of the TC status message."""

    NONE = 0x00
    TASK_TOTALS_ACTIVE = 0x01
    BUSY_SAVING_DATA = 0x02
    BUSY_READING_DATA = 0x04
    BUSY_EXECUTING_COMMAND = 0x08
    OUT_OF_MEMORY = 0x80


LABEL_NONE = b"\xff" * 7
"""A structure or localization label of all 0xFF: no pool known (or: the latest, in a request)."""


# --- technical capabilities -------------------------------------------------------------------

@dataclass(frozen=True)
class RequestVersion:
    """Ask the other side for its version message."""


@dataclass(frozen=True)
class Version:
    """The version message: ISO 11783-10 version and what the sender supports.

    Attributes
    ----------
    version : int
        3 (second edition draft) or 4 (second edition); 0xFF unknown.
    boot_time_s : int
        Seconds the sender needs to boot (0xFF: not available).
    options : int
        :class:`VersionOption` bits.
    booms, sections, channels : int
        Most booms, sections and position-based control channels supported.
    """

    version: int
    options: int = 0
    booms: int = 0
    sections: int = 0
    channels: int = 0
    boot_time_s: int = 0xFF


@dataclass(frozen=True)
class IdentifyTaskController:
    """Ask the TC to show its number."""


# --- device descriptor --------------------------------------------------------------------------

@dataclass(frozen=True)
class RequestStructureLabel:
    """Ask for the structure label of the pool the TC holds for this client.

    ``label`` of all 0xFF asks for the latest; a version 4 client may append the extended
    structure label it looks for.
    """

    label: bytes = LABEL_NONE
    extended: bytes = b""


@dataclass(frozen=True)
class StructureLabel:
    """The TC's answer: the stored pool's label, all 0xFF when it holds none."""

    label: bytes = LABEL_NONE
    extended: bytes = b""


@dataclass(frozen=True)
class RequestLocalizationLabel:
    """Ask for the localization label of the pool the TC holds for this client."""

    label: bytes = LABEL_NONE


@dataclass(frozen=True)
class LocalizationLabel:
    """The TC's answer: the stored pool's localization label, all 0xFF when none."""

    label: bytes = LABEL_NONE


@dataclass(frozen=True)
class RequestObjectPoolTransfer:
    """The client asks whether it may transfer a pool of ``size`` bytes."""

    size: int


@dataclass(frozen=True)
class RequestObjectPoolTransferResponse:
    """The TC's answer: whether it has the memory for the pool."""

    enough_memory: bool


@dataclass(frozen=True)
class ObjectPoolTransfer:
    """(Part of) the binary pool (sent over TP or ETP)."""

    pool: bytes


@dataclass(frozen=True)
class ObjectPoolTransferResponse:
    """The TC's answer to a transfer: error bits (0x01 no memory, 0x02 other) and bytes taken."""

    errors: int
    size: int


@dataclass(frozen=True)
class ObjectPoolActivate:
    """Activate (``True``) or deactivate (``False``) the transferred pool."""

    activate: bool


@dataclass(frozen=True)
class ObjectPoolActivateResponse:
    """The TC's answer: activation error bits, the faulty object and its parent, pool errors.

    The object ids are 0xFFFF when there is no error.
    """

    activation_errors: int
    parent_id: int = 0xFFFF
    object_id: int = 0xFFFF
    pool_errors: int = 0


@dataclass(frozen=True)
class DeleteObjectPool:
    """The client asks the TC to delete its stored pool."""


@dataclass(frozen=True)
class DeleteObjectPoolResponse:
    """The TC's answer: ``deleted`` and an error code (0xFF: no details)."""

    deleted: bool
    error_code: int = 0xFF


@dataclass(frozen=True)
class DeviceDescriptorOther:
    """A device descriptor sub-command this codec keeps as bytes (change designator)."""

    subcommand: int
    payload: bytes


# --- element commands and acknowledgements -----------------------------------------------------

@dataclass(frozen=True)
class ElementCommand:
    """Request value, value, a measurement command or set value and acknowledge.

    Attributes
    ----------
    command : Command
        One of :data:`ELEMENT_COMMANDS`.
    element : int
        Element number, 0 .. 4095.
    ddi : int
    value : int
        The 32-bit value as a signed integer (request value carries 0xFFFFFFFF, i.e. -1).
    """

    command: Command
    element: int
    ddi: int
    value: int = -1

    @property
    def unsigned(self) -> int:
        """The value as an unsigned 32-bit field (condensed work states)."""
        return self.value & 0xFFFFFFFF


@dataclass(frozen=True)
class ProcessDataAcknowledge:
    """PDACK: the answer to a command (error bits 0 = accepted) naming the command it answers."""

    element: int
    ddi: int
    errors: AckError
    command: int


@dataclass(frozen=True)
class TaskControllerStatus:
    """The TC's status, broadcast every 2 s.

    Attributes
    ----------
    status : ServerStatus
    client_address : int
        Source address of the client whose command the TC is busy with (0 when none).
    command_byte : int
        That command's first byte (0 when none).
    """

    status: ServerStatus = ServerStatus.NONE
    client_address: int = 0
    command_byte: int = 0


@dataclass(frozen=True)
class ClientTask:
    """The client's status, every 2 s: bit 0 of byte 5 says a task is active on it."""

    task_active: bool = False
    status_bits: int = 0


@dataclass(frozen=True)
class WorkingSetMaster:
    """The working-set master message (PGN 0xFE0D): how many members the working set has."""

    members: int = 1


ProcessDataMessage = (
    RequestVersion | Version | IdentifyTaskController | RequestStructureLabel | StructureLabel
    | RequestLocalizationLabel | LocalizationLabel | RequestObjectPoolTransfer
    | RequestObjectPoolTransferResponse | ObjectPoolTransfer | ObjectPoolTransferResponse
    | ObjectPoolActivate | ObjectPoolActivateResponse | DeleteObjectPool
    | DeleteObjectPoolResponse | DeviceDescriptorOther | ElementCommand
    | ProcessDataAcknowledge | TaskControllerStatus | ClientTask
)
"""Any message :func:`decode` returns."""


_FF = 0xFF


def _pad(body: bytes) -> bytes:
    return body + b"\xff" * (8 - len(body)) if len(body) < 8 else body


def _u16(data: bytes, at: int) -> int:
    return int.from_bytes(data[at:at + 2], "little")


def _element_head(command: int, element: int) -> bytes:
    if not 0 <= element <= ELEMENT_NUMBER_ALL:
        raise FrameError(f"process data: element number {element} does not fit 12 bits")
    return bytes([(command & 0x0F) | ((element & 0x0F) << 4), element >> 4])


def _check_label(label: bytes, what: str) -> bytes:
    if len(label) != 7:
        raise FrameError(f"process data: {what} must be 7 bytes, not {len(label)}")
    return label


def encode(message: ProcessDataMessage) -> bytes:
    """The payload of ``message`` (8 bytes, or longer for a pool transfer or extended label).

    Raises
    ------
    FrameError
        When a field does not fit (an element number over 12 bits, a label not 7 bytes ...).
    """
    dd = Command.DEVICE_DESCRIPTOR
    try:
        match message:
            case RequestVersion():
                return _pad(bytes([TechnicalCapability.REQUEST_VERSION << 4]))
            case Version():
                return bytes([TechnicalCapability.VERSION << 4, message.version,
                              message.boot_time_s, int(message.options), 0x00, message.booms,
                              message.sections, message.channels])
            case IdentifyTaskController():
                return _pad(bytes([TechnicalCapability.IDENTIFY_TASK_CONTROLLER << 4]))
            case RequestStructureLabel():
                return (bytes([dd | DeviceDescriptorCommand.REQUEST_STRUCTURE_LABEL << 4])
                        + _check_label(message.label, "structure label") + message.extended)
            case StructureLabel():
                return (bytes([dd | DeviceDescriptorCommand.STRUCTURE_LABEL << 4])
                        + _check_label(message.label, "structure label") + message.extended)
            case RequestLocalizationLabel():
                return (bytes([dd | DeviceDescriptorCommand.REQUEST_LOCALIZATION_LABEL << 4])
                        + _check_label(message.label, "localization label"))
            case LocalizationLabel():
                return (bytes([dd | DeviceDescriptorCommand.LOCALIZATION_LABEL << 4])
                        + _check_label(message.label, "localization label"))
            case RequestObjectPoolTransfer():
                return _pad(bytes([dd | DeviceDescriptorCommand.REQUEST_OBJECT_POOL_TRANSFER << 4])
                            + message.size.to_bytes(4, "little"))
            case RequestObjectPoolTransferResponse():
                sub = DeviceDescriptorCommand.REQUEST_OBJECT_POOL_TRANSFER_RESPONSE
                return _pad(bytes([dd | sub << 4, 0 if message.enough_memory else 1]))
            case ObjectPoolTransfer():
                return bytes([dd | DeviceDescriptorCommand.OBJECT_POOL_TRANSFER << 4]) \
                    + message.pool
            case ObjectPoolTransferResponse():
                sub = DeviceDescriptorCommand.OBJECT_POOL_TRANSFER_RESPONSE
                return _pad(bytes([dd | sub << 4, message.errors])
                            + message.size.to_bytes(4, "little"))
            case ObjectPoolActivate():
                sub = DeviceDescriptorCommand.OBJECT_POOL_ACTIVATE_DEACTIVATE
                return _pad(bytes([dd | sub << 4, 0xFF if message.activate else 0x00]))
            case ObjectPoolActivateResponse():
                sub = DeviceDescriptorCommand.OBJECT_POOL_ACTIVATE_DEACTIVATE_RESPONSE
                return (bytes([dd | sub << 4, message.activation_errors])
                        + message.parent_id.to_bytes(2, "little")
                        + message.object_id.to_bytes(2, "little")
                        + bytes([message.pool_errors, _FF]))
            case DeleteObjectPool():
                return _pad(bytes([dd | DeviceDescriptorCommand.DELETE_OBJECT_POOL << 4]))
            case DeleteObjectPoolResponse():
                sub = DeviceDescriptorCommand.DELETE_OBJECT_POOL_RESPONSE
                return _pad(bytes([dd | sub << 4, 0 if message.deleted else 1,
                                   message.error_code]))
            case DeviceDescriptorOther():
                return _pad(bytes([dd | (message.subcommand & 0x0F) << 4]) + message.payload)
            case ElementCommand():
                if message.command not in ELEMENT_COMMANDS:
                    raise FrameError(f"process data: {message.command!r} is not an element "
                                     f"command")
                return (_element_head(message.command, message.element)
                        + message.ddi.to_bytes(2, "little")
                        + (message.value & 0xFFFFFFFF).to_bytes(4, "little"))
            case ProcessDataAcknowledge():
                return (_element_head(Command.ACKNOWLEDGE, message.element)
                        + message.ddi.to_bytes(2, "little")
                        + bytes([int(message.errors), 0xF0 | (message.command & 0x0F), _FF, _FF]))
            case TaskControllerStatus():
                return bytes([0xF0 | Command.STATUS, _FF, _FF, _FF, int(message.status),
                              message.client_address, message.command_byte, _FF])
            case ClientTask():
                return bytes([0xF0 | Command.CLIENT_TASK, _FF, _FF, _FF,
                              (message.status_bits & 0xFE) | int(message.task_active), 0, 0, 0])
    except (OverflowError, ValueError) as exc:
        if isinstance(exc, FrameError):
            raise
        raise FrameError(f"process data: {message!r} does not fit its fields: {exc}") from exc
    raise FrameError(f"process data: cannot encode {message!r}")


def _short(data: bytes, what: str) -> FrameError:
    return FrameError(f"process data (PGN 0xCB00) {what}: {len(data)} bytes, at least 8 needed "
                      f"({data.hex(' ')})")


def decode(data: bytes) -> ProcessDataMessage:
    """The message in a process data payload.

    Raises
    ------
    FrameError
        For a payload shorter than 8 bytes (the pool transfer needs only its command byte), a
        reserved command (0xB, 0xC) or sub-command; the message names the bytes.
    """
    data = bytes(data)
    if not data:
        raise FrameError("process data (PGN 0xCB00): empty payload")
    command = data[0] & 0x0F
    high = data[0] >> 4
    transfer = DeviceDescriptorCommand.OBJECT_POOL_TRANSFER
    if command == Command.DEVICE_DESCRIPTOR and high == transfer:
        return ObjectPoolTransfer(data[1:])
    if len(data) < 8:
        raise _short(data, f"command 0x{command:X}")
    if command == Command.TECHNICAL_CAPABILITIES:
        if high == TechnicalCapability.REQUEST_VERSION:
            return RequestVersion()
        if high == TechnicalCapability.VERSION:
            return Version(version=data[1], options=VersionOption(data[3] & 0x1F),
                           booms=data[5], sections=data[6], channels=data[7],
                           boot_time_s=data[2])
        if high == TechnicalCapability.IDENTIFY_TASK_CONTROLLER:
            return IdentifyTaskController()
        raise FrameError(f"process data: technical capabilities sub-command {high} is reserved "
                         f"({data.hex(' ')})")
    if command == Command.DEVICE_DESCRIPTOR:
        return _decode_device_descriptor(high, data)
    if command in ELEMENT_COMMANDS:
        element = high | (data[1] << 4)
        return ElementCommand(Command(command), element, _u16(data, 2),
                              int.from_bytes(data[4:8], "little", signed=True))
    if command == Command.ACKNOWLEDGE:
        return ProcessDataAcknowledge(high | (data[1] << 4), _u16(data, 2), AckError(data[4]),
                                      data[5] & 0x0F)
    if command == Command.STATUS:
        return TaskControllerStatus(ServerStatus(data[4] & 0x8F), data[5], data[6])
    if command == Command.CLIENT_TASK:
        return ClientTask(bool(data[4] & 0x01), data[4])
    raise FrameError(f"process data: command 0x{command:X} is reserved or not supported "
                     f"({data.hex(' ')})")


def _decode_device_descriptor(sub: int, data: bytes) -> ProcessDataMessage:
    d = DeviceDescriptorCommand
    match sub:
        case d.REQUEST_STRUCTURE_LABEL:
            return RequestStructureLabel(data[1:8], data[8:])
        case d.STRUCTURE_LABEL:
            return StructureLabel(data[1:8], data[8:])
        case d.REQUEST_LOCALIZATION_LABEL:
            return RequestLocalizationLabel(data[1:8])
        case d.LOCALIZATION_LABEL:
            return LocalizationLabel(data[1:8])
        case d.REQUEST_OBJECT_POOL_TRANSFER:
            return RequestObjectPoolTransfer(int.from_bytes(data[1:5], "little"))
        case d.REQUEST_OBJECT_POOL_TRANSFER_RESPONSE:
            return RequestObjectPoolTransferResponse(data[1] == 0)
        case d.OBJECT_POOL_TRANSFER_RESPONSE:
            return ObjectPoolTransferResponse(data[1], int.from_bytes(data[2:6], "little"))
        case d.OBJECT_POOL_ACTIVATE_DEACTIVATE:
            if data[1] not in (0x00, 0xFF):
                raise FrameError(f"process data: object pool activate/deactivate byte 2 is "
                                 f"0x{data[1]:02X}, neither 0xFF (activate) nor 0x00")
            return ObjectPoolActivate(data[1] == 0xFF)
        case d.OBJECT_POOL_ACTIVATE_DEACTIVATE_RESPONSE:
            return ObjectPoolActivateResponse(data[1], _u16(data, 2), _u16(data, 4), data[6])
        case d.DELETE_OBJECT_POOL:
            return DeleteObjectPool()
        case d.DELETE_OBJECT_POOL_RESPONSE:
            return DeleteObjectPoolResponse(data[1] == 0, data[2])
        case d.CHANGE_DESIGNATOR | d.CHANGE_DESIGNATOR_RESPONSE:
            return DeviceDescriptorOther(sub, data[1:])
    raise FrameError(f"process data: device descriptor sub-command {sub} is reserved "
                     f"({data.hex(' ')})")


def encode_working_set_master(message: WorkingSetMaster) -> bytes:
    """The working-set master payload (PGN 0xFE0D)."""
    if not 1 <= message.members <= 255:
        raise FrameError(f"working-set master: {message.members} members is not 1 .. 255")
    return _pad(bytes([message.members]))


def decode_working_set_master(data: bytes) -> WorkingSetMaster:
    """The working-set master message in a PGN 0xFE0D payload.

    Raises
    ------
    FrameError
        For a payload that is not 8 bytes or declares no members.
    """
    if len(data) != 8:
        raise FrameError(f"working-set master (PGN 0xFE0D): {len(data)} bytes, not 8")
    if data[0] == 0:
        raise FrameError("working-set master (PGN 0xFE0D): 0 members")
    return WorkingSetMaster(data[0])
