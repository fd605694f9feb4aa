"""The exception tree: one root, each subclass also a matching built-in.

Callers can catch ``HilError`` for anything agrihil raises on purpose, or the built-in
(``ValueError``, ``TimeoutError`` …) when they only care about the kind of failure.
"""


class HilError(Exception):
    """Root of every error agrihil raises on purpose."""


class ConfigError(HilError, ValueError):
    """A configuration file (rig config, DUT profile, scenario) is invalid.

    The message names the file and the key.
    """

    def __init__(self, message: str, *, path: str | None = None, key: str | None = None) -> None:
        self.path = path
        self.key = key
        where = ""
        if path:
            where = f"{path}: "
        if key:
            where += f"[{key}] "
        super().__init__(f"{where}{message}")


class BusSpecError(HilError, ValueError):
    """A bus spec string cannot be parsed or names no known transport."""


class BusError(HilError, OSError):
    """The bus failed while in use (connection lost, interface down, bus-off)."""


class StepTimeoutError(HilError, TimeoutError):
    """A lockstep step waited too long for a participant (usually the DUT's command frames)."""


class ClockError(HilError, RuntimeError):
    """A clock was used out of order (ticked before start, started twice)."""


class FrameError(HilError, ValueError):
    """A CAN frame cannot be encoded or decoded; the message names the frame and the signal."""
