"""The CiA 402 power-drive state machine as data: states, commands, transitions, statusword bits.

Controlword commands (bits 7, 3, 2, 1, 0; x = don't care)::

    shutdown            0 x 1 1 0      transitions 2, 6, 8
    switch on           0 0 1 1 1      3 (also "disable operation": 5)
    enable operation    0 1 1 1 1      4, 16 (and 3 + 4 from Ready to switch on)
    disable voltage     0 x x 0 x      7, 9, 10, 12
    quick stop          0 x 0 1 x      7, 10, 11
    fault reset         0 -> 1 on bit 7, from Fault: 15

Statusword (bits 6, 5, 3, 2, 1, 0 identify the state)::

    Not ready to switch on   x0xx 0000      Switch on disabled   x1xx 0000
    Ready to switch on       x01x 0001      Switched on          x01x 0011
    Operation enabled        x01x 0111      Quick stop active    x00x 0111
    Fault reaction active    x0xx 1111      Fault                x0xx 1000

The automatic transitions (0, 1, 12 after a quick stop with option code 0-2, 13, 14) and fault
reset (15) depend on the drive's state, not on a command; :class:`~.cia402.Cia402Drive` performs
them.

Example
-------
>>> transitions(DriveState.READY_TO_SWITCH_ON, decode_command(0x0F), quick_stop_option_code=2)
(<DriveState.SWITCHED_ON: 'SWITCHED ON'>, <DriveState.OPERATION_ENABLED: 'OPERATION ENABLED'>)
"""

from __future__ import annotations

import enum

__all__ = [
    "CW_CHANGE_SET_IMMEDIATELY",
    "CW_FAULT_RESET",
    "CW_HALT",
    "CW_NEW_SET_POINT",
    "CW_RELATIVE",
    "POWERED_STATES",
    "STATE_BITS",
    "SW_FAULT",
    "SW_INTERNAL_LIMIT",
    "SW_OPERATION_ENABLED",
    "SW_OP_SPECIFIC_12",
    "SW_OP_SPECIFIC_13",
    "SW_QUICK_STOP",
    "SW_READY_TO_SWITCH_ON",
    "SW_REMOTE",
    "SW_SWITCHED_ON",
    "SW_SWITCH_ON_DISABLED",
    "SW_TARGET_REACHED",
    "SW_VOLTAGE_ENABLED",
    "SW_WARNING",
    "Command",
    "DriveState",
    "decode_command",
    "transitions",
]

# Statusword bits.
SW_READY_TO_SWITCH_ON = 1 << 0
SW_SWITCHED_ON = 1 << 1
SW_OPERATION_ENABLED = 1 << 2
SW_FAULT = 1 << 3
SW_VOLTAGE_ENABLED = 1 << 4
SW_QUICK_STOP = 1 << 5
SW_SWITCH_ON_DISABLED = 1 << 6
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_INTERNAL_LIMIT = 1 << 11
SW_OP_SPECIFIC_12 = 1 << 12   # pp: set-point acknowledge; pv: speed = 0
SW_OP_SPECIFIC_13 = 1 << 13   # pp: following error; pv: max slippage (never set here)

# Controlword bits beyond the device-control nibble.
CW_NEW_SET_POINT = 1 << 4
CW_CHANGE_SET_IMMEDIATELY = 1 << 5
CW_RELATIVE = 1 << 6
CW_FAULT_RESET = 1 << 7
CW_HALT = 1 << 8


class DriveState(enum.Enum):
    """The eight states of the CiA 402 power drive system (values as canopen's BaseNode402)."""

    NOT_READY_TO_SWITCH_ON = "NOT READY TO SWITCH ON"
    SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
    READY_TO_SWITCH_ON = "READY TO SWITCH ON"
    SWITCHED_ON = "SWITCHED ON"
    OPERATION_ENABLED = "OPERATION ENABLED"
    QUICK_STOP_ACTIVE = "QUICK STOP ACTIVE"
    FAULT_REACTION_ACTIVE = "FAULT REACTION ACTIVE"
    FAULT = "FAULT"


#: Statusword bits 0-3, 5, 6 of each state.
STATE_BITS = {
    DriveState.NOT_READY_TO_SWITCH_ON: 0x00,
    DriveState.SWITCH_ON_DISABLED: SW_SWITCH_ON_DISABLED,
    DriveState.READY_TO_SWITCH_ON: SW_QUICK_STOP | SW_READY_TO_SWITCH_ON,
    DriveState.SWITCHED_ON: SW_QUICK_STOP | SW_SWITCHED_ON | SW_READY_TO_SWITCH_ON,
    DriveState.OPERATION_ENABLED: (SW_QUICK_STOP | SW_OPERATION_ENABLED | SW_SWITCHED_ON
                                   | SW_READY_TO_SWITCH_ON),
    DriveState.QUICK_STOP_ACTIVE: SW_OPERATION_ENABLED | SW_SWITCHED_ON | SW_READY_TO_SWITCH_ON,
    DriveState.FAULT_REACTION_ACTIVE: (SW_FAULT | SW_OPERATION_ENABLED | SW_SWITCHED_ON
                                       | SW_READY_TO_SWITCH_ON),
    DriveState.FAULT: SW_FAULT,
}

#: States in which the power stage is (or is about to be) energised.
POWERED_STATES = (DriveState.SWITCHED_ON, DriveState.OPERATION_ENABLED,
                  DriveState.QUICK_STOP_ACTIVE, DriveState.FAULT_REACTION_ACTIVE)


class Command(enum.Enum):
    """Device-control commands decoded from controlword bits 0-3."""

    SHUTDOWN = "shutdown"
    SWITCH_ON = "switch on"          # also "disable operation" from Operation enabled
    ENABLE_OPERATION = "enable operation"
    DISABLE_VOLTAGE = "disable voltage"
    QUICK_STOP = "quick stop"


def decode_command(controlword: int) -> Command:
    """Decode bits 0-3 of a controlword (bit 7, fault reset, is an edge handled apart).

    >>> decode_command(0x0006).value, decode_command(0x000F).value, decode_command(0x0002).value
    ('shutdown', 'enable operation', 'quick stop')
    """
    if not controlword & 0x02:
        return Command.DISABLE_VOLTAGE
    if not controlword & 0x04:
        return Command.QUICK_STOP
    if not controlword & 0x01:
        return Command.SHUTDOWN
    if controlword & 0x08:
        return Command.ENABLE_OPERATION
    return Command.SWITCH_ON


_S = DriveState
_C = Command
_TABLE: dict[tuple[DriveState, Command], tuple[DriveState, ...]] = {
    (_S.SWITCH_ON_DISABLED, _C.SHUTDOWN): (_S.READY_TO_SWITCH_ON,),                    # 2
    (_S.READY_TO_SWITCH_ON, _C.SWITCH_ON): (_S.SWITCHED_ON,),                          # 3
    (_S.READY_TO_SWITCH_ON, _C.ENABLE_OPERATION): (_S.SWITCHED_ON,
                                                   _S.OPERATION_ENABLED),              # 3, 4
    (_S.READY_TO_SWITCH_ON, _C.DISABLE_VOLTAGE): (_S.SWITCH_ON_DISABLED,),             # 7
    (_S.READY_TO_SWITCH_ON, _C.QUICK_STOP): (_S.SWITCH_ON_DISABLED,),                  # 7
    (_S.SWITCHED_ON, _C.ENABLE_OPERATION): (_S.OPERATION_ENABLED,),                    # 4
    (_S.SWITCHED_ON, _C.SHUTDOWN): (_S.READY_TO_SWITCH_ON,),                           # 6
    (_S.SWITCHED_ON, _C.DISABLE_VOLTAGE): (_S.SWITCH_ON_DISABLED,),                    # 10
    (_S.SWITCHED_ON, _C.QUICK_STOP): (_S.SWITCH_ON_DISABLED,),                         # 10
    (_S.OPERATION_ENABLED, _C.SWITCH_ON): (_S.SWITCHED_ON,),                           # 5
    (_S.OPERATION_ENABLED, _C.SHUTDOWN): (_S.READY_TO_SWITCH_ON,),                     # 8
    (_S.OPERATION_ENABLED, _C.DISABLE_VOLTAGE): (_S.SWITCH_ON_DISABLED,),              # 9
    (_S.OPERATION_ENABLED, _C.QUICK_STOP): (_S.QUICK_STOP_ACTIVE,),                    # 11
    (_S.QUICK_STOP_ACTIVE, _C.DISABLE_VOLTAGE): (_S.SWITCH_ON_DISABLED,),              # 12
    (_S.QUICK_STOP_ACTIVE, _C.ENABLE_OPERATION): (_S.OPERATION_ENABLED,),              # 16
}


def transitions(state: DriveState, command: Command, *, quick_stop_option_code: int,
                main_power: bool = True) -> tuple[DriveState, ...]:
    """States a command drives ``state`` through, in order (empty if it is no transition).

    Parameters
    ----------
    state : DriveState
        Present state.
    command : Command
        Decoded controlword.
    quick_stop_option_code : int
        0x605A: code 0 passes Quick stop active straight to Switch on disabled (11 then 12);
        transition 16 exists only for codes 5-8.
    main_power : bool, default True
        Transition 3 (switching the power stage on) needs the DC supply.
    """
    path = _TABLE.get((state, command), ())
    if path and path[0] is _S.SWITCHED_ON and state is _S.READY_TO_SWITCH_ON and not main_power:
        return ()
    if state is _S.QUICK_STOP_ACTIVE and command is _C.ENABLE_OPERATION \
            and quick_stop_option_code not in (5, 6, 7, 8):
        return ()
    if path == (_S.QUICK_STOP_ACTIVE,) and quick_stop_option_code == 0:
        return (_S.QUICK_STOP_ACTIVE, _S.SWITCH_ON_DISABLED)
    return path
