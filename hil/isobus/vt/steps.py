"""One step of the scripted operator, as a scenario's ``[[operator]]`` list gives it.

Kept apart from :mod:`hil.isobus.vt.operator` (which plays the steps on a VT) so that a
scenario can be read and checked without loading the VT: :class:`OperatorStep` checks its own
keys and values; whether the objects it names are in the implement's pool is checked once the
pool is known (:func:`hil.isobus.vt.operator.check_steps`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hil.errors import ConfigError

__all__ = ["OperatorScriptError", "OperatorStep"]


class OperatorScriptError(ConfigError):
    """An ``[[operator]]`` step names an object the implement's pool does not have: a setup
    error of the scenario (``hil run`` and ``hil qualify`` exit 2), found once the pool is
    active."""


@dataclass(frozen=True)
class OperatorStep:
    """One step of an ``[[operator]]`` list: exactly one of press, enter, type, acknowledge,
    escape.

    Parameters
    ----------
    at_s : float
        When, in run time.
    press : int or str, optional
        A soft key or button: object id or label.
    hold_s : float
        How long a press lasts (0.2 s: one still-held report at most... none below 0.2 s).
    enter : int or str, optional
        An input number, list or boolean (object id), with ``value`` in its displayed units.
    value : float, optional
        The value entered.
    type : int or str, optional
        An input string (object id), with ``text``.
    text : str, optional
        The text typed.
    acknowledge : bool, int or str, optional
        ``true``: the active alarm mask's first soft key; an id or label: that key.
    escape : bool
        ESC.
    """

    at_s: float
    press: int | str | None = None
    hold_s: float = 0.2
    enter: int | str | None = None
    value: float | None = None
    type: int | str | None = None
    text: str | None = None
    acknowledge: bool | int | str | None = None
    escape: bool = False

    def __post_init__(self) -> None:
        actions = sum(x is not None for x in (self.press, self.enter, self.type,
                                              self.acknowledge)) + int(self.escape)
        if actions != 1:
            raise ConfigError("an operator step needs exactly one of press, enter, type, "
                              "acknowledge, escape")
        if not (math.isfinite(self.at_s) and self.at_s >= 0):
            raise ConfigError(f"at_s must be a finite time >= 0, got {self.at_s}", key="at_s")
        if not (math.isfinite(self.hold_s) and 0 < self.hold_s <= 60):
            raise ConfigError(f"hold_s must be in (0, 60] s, got {self.hold_s}", key="hold_s")
        if self.enter is not None and (self.value is None or not math.isfinite(self.value)):
            raise ConfigError("enter needs a finite value", key="value")
        if self.type is not None and self.text is None:
            raise ConfigError("type needs a text", key="text")

    @property
    def what(self) -> str:
        """The step in words."""
        if self.press is not None:
            return f"press {self.press!r} for {self.hold_s:g} s"
        if self.enter is not None:
            return f"enter {self.value:g} into {self.enter!r}"
        if self.type is not None:
            return f"type {self.text!r} into {self.type!r}"
        if self.acknowledge is not None:
            return "acknowledge the alarm" + (
                "" if self.acknowledge is True else f" with {self.acknowledge!r}")
        return "ESC"
