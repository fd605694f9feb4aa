"""An in-process bus with a controller on the other end, for lockstep runs.

python-can's ``virtual`` bus hands every frame to a receiving *thread*; in lockstep that thread
hand-off at every SYNC and the message copies are most of a run's cost, and the thread adds
nothing (the controller only ever acts on what the rig sends). :class:`InlineBus` is a
``can.BusABC`` whose ``send`` hands the frame straight to the controller's ``on_frame`` and queues
its answers for the rig's ``recv``: the same frames in the same order, no threads, and nothing
can arrive that the rig did not cause, so ``recv`` never blocks.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

import can

FrameHandler = Callable[[can.Message], list[can.Message]]


class InlineBus(can.BusABC):
    """A ``can.BusABC`` whose other end is a function: ``send`` calls it, ``recv`` gets its answers.

    Parameters
    ----------
    handler : callable
        Called with each frame sent; returns the frames to send in answer (a controller's
        ``on_frame``).
    channel : str, optional
        The channel name python-can reports.
    **kwargs
        Passed to ``can.BusABC``.
    """

    #: the other end's answers are queued within ``send``: none can arrive late (the lockstep
    #: barrier takes frames after the command frame as in order, see hil.clock.sync)
    answers_synchronously = True

    def __init__(self, handler: FrameHandler, channel: str = "inline", **kwargs: Any) -> None:
        self._handler = handler
        self._rx: deque[can.Message] = deque()
        self.channel_info = f"inline bus to {getattr(handler, '__self__', handler)!r}"
        super().__init__(channel=channel, **kwargs)

    def inject(self, msgs: list[can.Message]) -> None:
        """Queue frames from the other end (a controller's start-up frames, say)."""
        self._rx.extend(msgs)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Hand ``msg`` to the handler; queue its answers for :meth:`recv` (no ``timeout``)."""
        self._rx.extend(self._handler(msg))

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self._rx:
            return self._rx.popleft(), False
        return None, False

    def shutdown(self) -> None:
        """Drop the queued frames and shut the bus down."""
        self._rx.clear()
        super().shutdown()
