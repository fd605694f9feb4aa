"""A bus-level FMU (FMI 3.0 + FMI-LS-BUS CAN) as a controller: frames in, frames out.

agrihil is the importer. The FMU is instantiated with event mode; its time follows the rig's
SYNC: the k-th SYNC (from 0) is bus time ``k x control period``, and every other frame reaches
the FMU at the time of the last SYNC (the rig's frames carry no bus time of their own; in
lockstep they are the frames of the control period that SYNC opened). For each frame:

1. ``doStep`` up to the frame's bus time (nothing when it is not later); a time-based
   ``Tx_Clock`` is activated at each of its ticks on the way (``doStep`` to the tick, event
   mode, ``setClock``, ``updateDiscreteStates``, ``Tx_Data`` read);
2. event mode; the frame (and any confirm, bus error or status the bus owes the node) as
   operations in ``Rx_Data`` with an ``Rx_Clock`` tick; ``updateDiscreteStates``;
3. a triggered ``Tx_Clock`` read before and after the update; when it ticked, ``Tx_Data``'s
   frames go on the rig's bus (:class:`hil.fmi.canbus.CanNodeBus` says what becomes of them).

Notifications the bus owes the node are delivered with the next frame; a frame is confirmed
when the bus time moves on (the next SYNC) and no error frame destroyed it before.
"""

from __future__ import annotations

from typing import Any

import can

from hil.dut.inprocess import Controller
from hil.fmi.canbus import CanNodeBus
from hil.fmi.fmufile import CanTerminal, FmuFile
from hil.fmi.instance import FmuInstance

__all__ = ["BusFmuController"]

SYNC_ID = 0x080


class BusFmuController(Controller):
    """One bus-level FMU on the rig's bus.

    Parameters
    ----------
    fmu : FmuFile
        The FMU (FMI 3.0, with a CAN terminal).
    terminal : CanTerminal
        The terminal wired to the rig's bus.
    period_s : float
        The control period (the SYNC period).
    bus_notifications : bool
        ``Can_BusNotifications`` (set when the FMU declares it).
    parameters : dict, optional
        Values for the FMU's parameters by variable name.
    name : str, optional
        The instance's name.
    bitrate_bps : int, optional
        The rig's bus bit rate (the bus-off recovery counts its bit times).
    """

    def __init__(self, fmu: FmuFile, terminal: CanTerminal, *, period_s: float,
                 bus_notifications: bool, parameters: dict[str, Any] | None = None,
                 name: str = "fmu", bitrate_bps: int = 250_000) -> None:
        self.fmu = fmu
        self.terminal = terminal
        self.period_s = period_s
        self.notifications = bus_notifications
        self.parameters = dict(parameters or {})
        self.name = name
        self.inst: FmuInstance | None = None
        self.env_parameters: dict[str, str] = {}
        self.bitrate_bps = bitrate_bps
        self.bus = CanNodeBus(terminal.name, bus_notifications, bitrate_bps)
        self.syncs = 0
        self.bus_time = 0.0
        self.next_tx_tick: float | None = None

    # --- life cycle ----------------------------------------------------------------------
    def configure(self, env: dict[str, str]) -> None:
        """The rig's offers (a serial port): the FMU's string parameters of that name."""
        from hil.fmi.parameters import environment_parameters

        self.env_parameters = environment_parameters(self.fmu, env)

    def on_start(self) -> list[can.Message]:
        from hil.fmi.parameters import apply_parameters

        self.close()
        inst = FmuInstance(self.fmu, self.name, event_mode=True)
        self.inst = inst
        if self.fmu.bus_notifications_vr is not None:
            inst.set_boolean_vr(self.fmu.bus_notifications_vr, self.notifications)
        apply_parameters(inst, self.fmu, {**self.env_parameters, **self.parameters})
        inst.initialize(0.0)
        self.bus = CanNodeBus(self.terminal.name, self.notifications, self.bitrate_bps)
        self.bus.start()
        self.syncs = 0
        self.bus_time = 0.0
        if not self.terminal.tx_triggered:
            self.next_tx_tick = self._interval()
        out = self._read_tx(None)
        out += self._deliver()
        return out

    def close(self) -> None:
        """Free the FMU instance (safe to call twice)."""
        if self.inst is not None:
            self.inst.close()
            self.inst = None

    def _interval(self) -> float:
        """A time-based ``Tx_Clock``'s interval (the description's, else the FMU's answer)."""
        if self.terminal.tx_clock_interval:
            return self.terminal.tx_clock_interval
        assert self.inst is not None
        import ctypes

        intervals = (ctypes.c_double * 1)()
        qualifiers = (ctypes.c_int * 1)()
        vrs = (ctypes.c_uint32 * 1)(self.terminal.tx_clock)
        self.inst.call("getIntervalDecimal", vrs, intervals, qualifiers)
        if not intervals[0] > 0:
            from hil.fmi.canbus import LsBusError

            raise LsBusError(f"{self.terminal.name}.Tx_Clock: the FMU gives interval "
                             f"{intervals[0]!r} s for its time-based clock")
        return float(intervals[0])

    # --- frames ----------------------------------------------------------------------------
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        assert self.inst is not None, "on_frame before on_start"
        sync = (not msg.is_error_frame and not msg.is_extended_id
                and msg.arbitration_id == SYNC_ID)
        if sync:
            self.bus_time = self.syncs * self.period_s
            self.syncs += 1
            self.bus.time_advanced(self.bus_time)
        out = self._advance(self.bus_time, msg)
        self.bus.from_bus(msg)
        out += self._deliver()
        return out

    def _advance(self, t: float, contending: can.Message) -> list[can.Message]:
        """``doStep`` to ``t``, with the time-based ``Tx_Clock``'s ticks on the way."""
        inst = self.inst
        assert inst is not None
        out: list[can.Message] = []
        while self.next_tx_tick is not None and self.next_tx_tick <= t + 1e-9:
            tick = self.next_tx_tick
            inst.do_step(tick)
            inst.enter_event_mode()
            inst.set_clock([self.terminal.tx_clock])
            inst.update_discrete_states()
            out += self._take_tx(contending if abs(tick - t) < 1e-9 else None)
            self.next_tx_tick = tick + self._interval()
        if inst.do_step(t):
            inst.enter_event_mode()
            out += self._read_tx(contending)
            inst.update_discrete_states()
            out += self._read_tx(contending)
        return out

    def _deliver(self) -> list[can.Message]:
        """Hand the node what the bus owes it (one ``Rx_Clock`` tick), collect its answer
        (frames that answer a frame do not contend with it: it is already on the bus)."""
        inst = self.inst
        assert inst is not None
        out: list[can.Message] = []
        for _ in range(8):   # notifications answering frames answering notifications ...
            if not self.bus.pending():
                break
            inst.enter_event_mode()
            inst.set_binary(self.terminal.rx_data, self.bus.take())
            inst.set_clock([self.terminal.rx_clock])
            inst.update_discrete_states()
            out += self._read_tx(None)
        return out

    def _read_tx(self, contending: can.Message | None) -> list[can.Message]:
        """A triggered ``Tx_Clock``: read it, and ``Tx_Data`` when it ticked."""
        inst = self.inst
        assert inst is not None
        if not self.terminal.tx_triggered:
            return []
        if not inst.get_clock(self.terminal.tx_clock):
            return []
        return self._take_tx(contending)

    def _take_tx(self, contending: can.Message | None) -> list[can.Message]:
        assert self.inst is not None
        data = self.inst.get_binary(self.terminal.tx_data)
        return self.bus.from_node(data, contending=contending) if data else []

    def record(self) -> dict[str, Any]:
        """The node's bus for the run's record."""
        return {**self.bus.record(), "fmu_time_s": self.inst.time if self.inst else None}
