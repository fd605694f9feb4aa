"""The CiA 402 side of the depth controller: which controlword moves the drive on.

Section 2, "CAN adapter", of the contract, from the statusword (CiA 402 state coding):

=====================  ===================  ===========
state                  statusword pattern   controlword
=====================  ===================  ===========
Fault                  xxxx xxxx x0xx 1000  0x80 (fault reset), then 0x00 on the next step
Switch on disabled     xxxx xxxx x1xx 0000  0x06 (shutdown)
Ready to switch on     xxxx xxxx x01x 0001  0x07 (switch on)
Switched on            xxxx xxxx x01x 0011  0x0F (enable operation)
Operation enabled      xxxx xxxx x01x 0111  0x0F
anything else                               0x06
=====================  ===================  ===========

Fault reset acts on a rising edge of bit 7, so after a step that sent 0x80 the next sends 0x00.

>>> next_controlword(0x0040, 0x00), next_controlword(0x0021, 0x06), next_controlword(0x0027, 0x0F)
(6, 7, 15)
>>> next_controlword(0x0008, 0x0F), next_controlword(0x0008, 0x80)
(128, 0)
"""

from __future__ import annotations

SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, FAULT_RESET, NO_COMMAND = 0x06, 0x07, 0x0F, 0x80, 0x00
MODE_PROFILE_VELOCITY = 3


def is_fault(statusword: int) -> bool:
    """Fault or Fault reaction active (bit 3)."""
    return bool(statusword & 0x0008)


def is_operation_enabled(statusword: int) -> bool:
    """Operation enabled: x01x 0111."""
    return statusword & 0x006F == 0x0027


def next_controlword(statusword: int, last_controlword: int) -> int:
    """The controlword that moves the drive one step towards Operation enabled."""
    if is_fault(statusword):
        return NO_COMMAND if last_controlword == FAULT_RESET else FAULT_RESET
    if statusword & 0x004F == 0x0040:
        return SHUTDOWN
    if statusword & 0x006F == 0x0021:
        return SWITCH_ON
    if statusword & 0x006F in (0x0023, 0x0027):
        return ENABLE_OPERATION
    return SHUTDOWN
