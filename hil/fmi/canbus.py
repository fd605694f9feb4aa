"""agrihil as the LS-BUS importer: the bus simulation one CAN node FMU sees.

FMI-LS-BUS leaves the bus to the importer: it takes the node's ``Tx_Data`` operations, puts its
frames on the bus and answers with operations on ``Rx_Data``. :class:`CanNodeBus` is that
answer for one CAN terminal, on a **classic CAN** bus (the rig's):

* **transmit** (0x10): the frame goes on the rig's bus. With ``BusNotifications`` true it is
  **confirmed** (0x20) when the bus time moves on (the next SYNC) unless an error frame
  destroyed it first; with ``BusNotifications`` false nothing comes back (fire and forget).
* **CAN FD / CAN XL transmit** (0x11, 0x12): refused (:class:`LsBusError`): the rig's bus is
  classic CAN.
* **arbitration lost** (0x30): a frame the node makes ready at the bus time a rig frame is
  sent (a time-based ``Tx_Clock`` or a ``doStep`` ending there) contends with it; a higher
  arbitration key (the lower id wins, a standard id before an extended one with the same base)
  loses. Under *buffer and retransmit* (the default) the frame is sent after the rig's; under
  *discard and notify* (configured by the node) it is dropped. The node hears of it only with
  ``BusNotifications`` true.
* **bus error** (0x31): an error frame on the bus (the software bus's ``error`` and ``busoff``
  fault rules put one there) is a transmit error of the node's oldest unconfirmed frame when
  it has one (``isSender`` 1, transmit error counter +8), else a receive error (``isSender``
  0, receive error counter +1), as ISO 11898-1 counts them; a confirmed frame takes 1 off the
  transmit counter. An error frame of the SocketCAN class *bus off* (``CAN_ERR_BUSOFF``,
  0x040 in its id: the software bus's ``busoff`` rule sends one) while the node has a frame
  on the bus says that frame's sender went bus off: the node's transmit counter goes past 255
  at once.
* **status** (0x41): error active at start; error passive when a counter passes 127; bus off
  when the transmit counter passes 255. A node that is bus off sends and hears nothing.
* **bus-off recovery**: ISO 11898-1 lets a node that is bus off become error active again,
  both counters 0, once it has monitored 128 occurrences of 11 consecutive recessive bits.
  Counted on the rig's bus time at its bit rate: every frame on the bus while the node is
  off ends in 11 recessive bits (ACK delimiter, end of frame, intermission: one occurrence),
  and the time the bus is idle gives one per 11 bit times, the frames' own bits (from
  :func:`hil.softbus.timing.frame_bits`) taken out of it. The node hears *error active* at the
  first bus time the count reaches 128 (on an idle 250 kbit/s bus 128 x 11 bits are 5.6 ms:
  in lockstep, the next SYNC) and its frames go on the bus again.
* **configuration** (0x40): the baud rate and the arbitration-lost behaviour the node asks for
  are kept (and recorded); the rig's bit rate stays what the rig's bus runs at.
* **wake-up** (0x42) from the node is counted; the rig's bus never sleeps, so no wake-up is
  sent to a node.
* a **format error** (0x01) from the node, an operation the bus alone may send (confirm,
  arbitration lost, bus error, status) or an unknown code is refused (:class:`LsBusError`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import can

from hil.errors import HilError
from hil.fmi import lsbus

__all__ = ["CanNodeBus", "LsBusError"]

ERROR_PASSIVE_LIMIT = 127
BUS_OFF_LIMIT = 255
#: ISO 11898-1 bus-off recovery: 128 occurrences of 11 consecutive recessive bits
RECOVERY_OCCURRENCES = 128
RECESSIVE_RUN_BITS = 11
#: SocketCAN's error classes (linux/can/error.h): controller problems, bus off
CAN_ERR_CRTL = 0x004
CAN_ERR_BUSOFF = 0x040


_DELIVERED = {lsbus.CanTransmit: "frames", lsbus.Confirm: "confirm",
              lsbus.ArbitrationLost: "arbitration_lost", lsbus.BusError: "bus_error",
              lsbus.Status: "status"}


class LsBusError(HilError, RuntimeError):
    """The node FMU sent an operation the rig's bus cannot carry or the node may not send."""


def arbitration_key(can_id: int, extended: bool) -> tuple[int, int]:
    """Lower wins: the 11-bit base id, then standard before extended, then the 18 low bits."""
    if extended:
        return (can_id >> 18) & 0x7FF, 1 << 18 | (can_id & 0x3FFFF)
    return can_id & 0x7FF, 0


@dataclass
class CanNodeBus:
    """The bus simulation for one CAN node FMU (see the module's description).

    Parameters
    ----------
    terminal : str
        The node's terminal name (named in errors).
    notifications : bool
        ``BusNotifications``: confirm, arbitration lost and bus error reach the node.
    bitrate_bps : int, optional
        The rig's bus bit rate (the bus-off recovery's bit times).
    """

    terminal: str
    notifications: bool
    bitrate_bps: int = 250_000
    tec: int = 0
    rec: int = 0
    status: int = lsbus.ERROR_ACTIVE
    baudrate: int | None = None
    fd_baudrate: int | None = None
    xl_baudrate: int | None = None
    arbitration_lost_behavior: int = lsbus.BUFFER_AND_RETRANSMIT
    counts: dict[str, int] = field(default_factory=lambda: {
        "transmitted": 0, "confirmed": 0, "arbitration_lost": 0, "discarded": 0,
        "bus_errors": 0, "wakeups": 0, "dropped_bus_off": 0,
        "missed_bus_off": 0, "bus_off": 0, "bus_off_recoveries": 0})
    #: the bus time now (s): the last :meth:`time_advanced`
    now_s: float = 0.0
    #: when the node last went bus off and last recovered (bus time, s)
    bus_off_at_s: float | None = None
    recovered_at_s: float | None = None
    #: while bus off: the frames on the bus since, and their bits
    _off_frames: int = 0
    _off_bits: int = 0
    #: operations handed to the node, by kind (``confirm``, ``bus_error`` ...)
    delivered: dict[str, int] = field(default_factory=dict)
    _unconfirmed: deque[int] = field(default_factory=deque)
    _to_node: list[Any] = field(default_factory=list)

    def start(self) -> None:
        """The node joins the bus: it hears that it is error active."""
        self._to_node.append(lsbus.Status(lsbus.ERROR_ACTIVE))

    # --- from the node ---------------------------------------------------------------------
    def from_node(self, buffer: bytes, *, contending: can.Message | None = None
                  ) -> list[can.Message]:
        """The frames the node's ``Tx_Data`` puts on the rig's bus, in order.

        Parameters
        ----------
        buffer : bytes
            The node's ``Tx_Data``.
        contending : can.Message, optional
            A rig frame sent at the same bus time as these frames became ready: they
            contend with it for the wire.

        Raises
        ------
        LsBusError
            CAN FD or XL transmit on the classic bus, a format error from the node, an
            operation the node may not send, a broken buffer.
        """
        try:
            ops = lsbus.decode(buffer, where=f"{self.terminal}.Tx_Data")
        except HilError as exc:
            raise LsBusError(str(exc)) from exc
        out: list[can.Message] = []
        for op in ops:
            if isinstance(op, lsbus.CanTransmit):
                msg = self._transmit(op, contending)
                if msg is not None:
                    out.append(msg)
            elif isinstance(op, lsbus.CanFdTransmit | lsbus.CanXlTransmit):
                kind = "CAN FD" if isinstance(op, lsbus.CanFdTransmit) else "CAN XL"
                raise LsBusError(f"{self.terminal}.Tx_Data: {kind} transmit of id 0x{op.id:X} "
                                 f"({len(op.data)} bytes) on the rig's classic CAN bus: agrihil's "
                                 f"rigs carry classic frames only (0x10, up to 8 bytes)")
            elif isinstance(op, lsbus.Configuration):
                self._configure(op)
            elif isinstance(op, lsbus.Wakeup):
                self.counts["wakeups"] += 1
            elif isinstance(op, lsbus.FormatError):
                raise LsBusError(f"{self.terminal}.Tx_Data: the FMU reports a format error on "
                                 f"an operation agrihil sent ({op.data[:16].hex()}...)")
            else:
                name = type(op).__name__
                code = getattr(op, "code", 0)
                raise LsBusError(f"{self.terminal}.Tx_Data: operation 0x{code:02X} ({name}) "
                                 f"is not one a CAN node sends (LS-BUS 1.0: the bus simulation "
                                 f"sends confirm, arbitration lost, bus error and status)")
        return out

    def _transmit(self, op: lsbus.CanTransmit, contending: can.Message | None
                  ) -> can.Message | None:
        if self.status == lsbus.BUS_OFF:
            self.counts["dropped_bus_off"] += 1
            return None
        if len(op.data) > 8:
            raise LsBusError(f"{self.terminal}.Tx_Data: CAN transmit of id 0x{op.id:X} with "
                             f"{len(op.data)} bytes: a classic frame carries 8 at most")
        if contending is not None and not contending.is_error_frame and \
                arbitration_key(contending.arbitration_id, contending.is_extended_id) < \
                arbitration_key(op.id, op.ide):
            self.counts["arbitration_lost"] += 1
            if self.notifications:
                self._to_node.append(lsbus.ArbitrationLost(op.id))
            if self.arbitration_lost_behavior == lsbus.DISCARD_AND_NOTIFY:
                self.counts["discarded"] += 1
                return None
        self.counts["transmitted"] += 1
        self._unconfirmed.append(op.id)
        return can.Message(arbitration_id=op.id, is_extended_id=op.ide,
                           is_remote_frame=op.rtr, data=op.data, dlc=len(op.data))

    def _configure(self, op: lsbus.Configuration) -> None:
        if op.parameter == lsbus.CAN_BAUDRATE:
            self.baudrate = op.value
        elif op.parameter == lsbus.CANFD_BAUDRATE:
            self.fd_baudrate = op.value
        elif op.parameter == lsbus.CANXL_BAUDRATE:
            self.xl_baudrate = op.value
        elif op.value in (lsbus.BUFFER_AND_RETRANSMIT, lsbus.DISCARD_AND_NOTIFY):
            self.arbitration_lost_behavior = op.value
        else:
            raise LsBusError(f"{self.terminal}.Tx_Data: arbitration-lost behaviour {op.value} "
                             f"is not one LS-BUS 1.0 defines (1 buffer and retransmit, 2 "
                             f"discard and notify)")

    # --- from the bus ----------------------------------------------------------------------
    def time_advanced(self, now_s: float | None = None) -> None:
        """The bus time moves on (a SYNC, to ``now_s``): the node's frames that no error frame
        destroyed meanwhile have been transmitted, and are confirmed; a node that is bus off
        recovers once the bus has shown it 128 x 11 recessive bits since.

        Not at any frame: on a paced bus the frames the node hears right after sending were on
        the wire before its own.
        """
        if now_s is not None:
            self.now_s = now_s
        if self.status != lsbus.BUS_OFF:
            self._confirm_all()
        elif self.recovery_occurrences() >= RECOVERY_OCCURRENCES:
            self._recover()

    def recovery_occurrences(self) -> int:
        """While bus off: the occurrences of 11 consecutive recessive bits since it went off
        (one per frame on the bus, one per 11 idle bit times)."""
        if self.bus_off_at_s is None:
            return 0
        # bit times are whole: rounded, so that a float's last digit does not lose one
        elapsed = round((self.now_s - self.bus_off_at_s) * self.bitrate_bps, 6)
        idle = max(0.0, elapsed - self._off_bits)
        return self._off_frames + int(idle // RECESSIVE_RUN_BITS)

    def _recover(self) -> None:
        self.status = lsbus.ERROR_ACTIVE
        self.tec = self.rec = 0
        self.recovered_at_s = self.now_s
        self.counts["bus_off_recoveries"] += 1
        self._to_node.append(lsbus.Status(lsbus.ERROR_ACTIVE))

    def from_bus(self, msg: can.Message) -> None:
        """A frame of the rig's bus reaches the node (an error frame: a bus error).

        A node that is bus off takes no part in the bus: it hears nothing.
        """
        if self.status == lsbus.BUS_OFF:
            from hil.softbus.timing import ERROR_FRAME_BITS, frame_bits

            self.counts["missed_bus_off"] += 1
            self._off_frames += 1
            self._off_bits += ERROR_FRAME_BITS if msg.is_error_frame else frame_bits(
                msg.arbitration_id, msg.is_extended_id, bytes(msg.data))
            return
        if msg.is_error_frame:
            self._bus_error(bus_off=bool(msg.arbitration_id & CAN_ERR_BUSOFF))
            return
        self._to_node.append(lsbus.CanTransmit(id=msg.arbitration_id, data=bytes(msg.data),
                                               ide=msg.is_extended_id, rtr=msg.is_remote_frame))

    def _confirm_all(self) -> None:
        while self._unconfirmed:
            can_id = self._unconfirmed.popleft()
            self.counts["confirmed"] += 1
            self.tec = max(0, self.tec - 1)
            if self.notifications:
                self._to_node.append(lsbus.Confirm(can_id))
        self._update_status()

    def _bus_error(self, *, bus_off: bool = False) -> None:
        self.counts["bus_errors"] += 1
        if self._unconfirmed:
            can_id = self._unconfirmed.popleft()
            self.tec = BUS_OFF_LIMIT + 1 if bus_off else self.tec + 8
            op = lsbus.BusError(can_id, lsbus.BIT_ERROR, lsbus.PRIMARY_ERROR_FLAG, True)
        else:
            self.rec = min(self.rec + 1, 255)
            op = lsbus.BusError(0, lsbus.FORM_ERROR, lsbus.SECONDARY_ERROR_FLAG, False)
        if self.notifications:
            self._to_node.append(op)
        self._update_status()

    def _update_status(self) -> None:
        if self.status == lsbus.BUS_OFF:
            return
        if self.tec > BUS_OFF_LIMIT:
            new = lsbus.BUS_OFF
        elif self.tec > ERROR_PASSIVE_LIMIT or self.rec > ERROR_PASSIVE_LIMIT:
            new = lsbus.ERROR_PASSIVE
        else:
            new = lsbus.ERROR_ACTIVE
        if new != self.status:
            self.status = new
            if new == lsbus.BUS_OFF:
                self._unconfirmed.clear()
                self.counts["bus_off"] += 1
                self.bus_off_at_s = self.now_s
                self._off_frames = self._off_bits = 0
            self._to_node.append(lsbus.Status(new))

    def pending(self) -> bool:
        """Whether operations wait for the node's next ``Rx_Clock`` tick."""
        return bool(self._to_node)

    def take(self) -> bytes:
        """The node's next ``Rx_Data`` (and forget it)."""
        ops, self._to_node = self._to_node, []
        for op in ops:
            name = _DELIVERED.get(type(op))
            if name is not None:
                self.delivered[name] = self.delivered.get(name, 0) + 1
        return lsbus.encode(ops)

    def record(self) -> dict[str, Any]:
        """What the run's record keeps of the node's bus."""
        return {"terminal": self.terminal, "bus_notifications": self.notifications,
                "status": lsbus.STATUS_NAMES.get(self.status, str(self.status)),
                "transmit_error_counter": self.tec, "receive_error_counter": self.rec,
                "configured_baudrate": self.baudrate,
                "bus_off_at_s": self.bus_off_at_s, "recovered_at_s": self.recovered_at_s,
                "arbitration_lost_behavior": ("discard and notify"
                                              if self.arbitration_lost_behavior ==
                                              lsbus.DISCARD_AND_NOTIFY
                                              else "buffer and retransmit"),
                **self.counts, "delivered": dict(self.delivered)}
