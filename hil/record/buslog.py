"""The bus log in standard formats, through python-can's writers.

candump ``.log`` (can-utils, SavvyCAN, ``python -m can.player``) and Vector ``.asc`` (CANoe,
cantools, asammdf) are written side by side by default; any extension python-can knows
(``.blf``, ``.trc``, ``.csv``…) may be asked for.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import can

DEFAULT_FORMATS = ("log", "asc")


class BusLog:
    def __init__(self, directory: Path, *, stem: str = "bus",
                 formats: Iterable[str] = DEFAULT_FORMATS, channel: str = "can0") -> None:
        self.paths = [directory / f"{stem}.{fmt.lstrip('.')}" for fmt in formats]
        self.channel = channel
        self._writers: list[can.Listener] = [can.Logger(path) for path in self.paths]
        self.frames = 0

    def write(self, msg: can.Message, time_s: float, *, rx: bool) -> None:
        """Log ``msg`` at ``time_s`` (the run clock's time); ``rx``: received by the rig."""
        stamped = can.Message(timestamp=time_s, arbitration_id=msg.arbitration_id,
                              is_extended_id=msg.is_extended_id,
                              is_remote_frame=msg.is_remote_frame,
                              is_error_frame=msg.is_error_frame, dlc=msg.dlc, data=msg.data,
                              channel=self.channel, is_rx=rx)
        for writer in self._writers:
            writer.on_message_received(stamped)
        self.frames += 1

    def close(self) -> None:
        writers, self._writers = self._writers, []
        for writer in writers:
            writer.stop()
