"""The valid range of every numeric CLI option and profile key, in one table.

Each entry is a :class:`Range`: a type (integer or finite number), bounds (open or closed), a
unit and the reason for the bounds. The same entry

* is the ``type=`` of the option's argparse argument (:func:`option_type`), so a value out of
  range is a usage error naming the option (exit 2) before anything starts;
* is appended to the option's help (:func:`help_with_range`), which ``hil --help`` prints and the
  CLI reference page is generated from (sphinx-argparse);
* checks the profile keys (:func:`check_key`, from the profile dataclasses' ``__post_init__``);
* is listed in the table below, which the reference page includes with autodoc.

A bound is a physical or protocol limit where one exists (a CANopen heartbeat time is an
UNSIGNED16 of milliseconds; an extended CAN identifier has 29 bits) and otherwise a bound past
which the value cannot be meant (a DUT that needs more than an hour to boot).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass

from hil.errors import ConfigError

__all__ = ["CLI_RANGES", "PROFILE_RANGES", "Range", "check_key", "check_option",
           "check_value", "help_with_range", "option_type", "parse_number", "ranges_table"]


@dataclass(frozen=True)
class Range:
    """The valid values of one numeric option or key.

    Parameters
    ----------
    kind : {"int", "float"}
        An integer (decimal or ``0x`` hexadecimal on the command line) or a finite number.
    low, high : float, optional
        The bounds (None: unbounded on that side).
    low_open, high_open : bool
        True when the bound itself is not valid (``0 < x`` rather than ``0 <= x``).
    unit : str
        The unit of the value ("" for a count or a pure number).
    why : str
        Where the bounds come from, for the reference page.
    """

    kind: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    unit: str = ""
    why: str = ""

    def contains(self, value: float) -> bool:
        """True when ``value`` is valid (finite, an integer for ``int``, within the bounds)."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False
        if self.kind == "int" and not isinstance(value, int):
            return False
        if isinstance(value, float) and not math.isfinite(value):
            return False
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return self.high is None or not (value >= self.high if self.high_open
                                         else value > self.high)

    def describe(self) -> str:
        """The range as text: ``integer 0 ≤ x ≤ 65535 ms``, ``number 0 < x ≤ 1``."""
        what = "integer" if self.kind == "int" else "number"
        parts = []
        if self.low is not None:
            parts.append(f"{_fmt(self.low)} {'<' if self.low_open else '≤'} ")
        parts.append("x")
        if self.high is not None:
            parts.append(f" {'<' if self.high_open else '≤'} {_fmt(self.high)}")
        if self.low is None and self.high is None:
            parts = ["any finite value"]
        unit = f" {self.unit}" if self.unit else ""
        return f"{what} {''.join(parts)}{unit}"


def _a(text: str) -> str:
    """``text`` with its indefinite article: "an integer …", "a number …"."""
    return ("an " if text[:1] in "aeiou" else "a ") + text


def _fmt(bound: float) -> str:
    if isinstance(bound, int) and bound >= 0x10000:
        if bound == 2**63 - 1:
            return "2**63-1"
        return f"0x{bound:X}"
    return f"{bound:g}"


#: every numeric option of the ``hil`` command, by ``command option``
CLI_RANGES: dict[str, Range] = {
    "--seed": Range("int", 0, 2**63 - 1, why="numpy SeedSequence entropy, stored as a "
                                                 "64-bit JSON/TOML integer"),
    "campaign --samples": Range("int", 1, 1_000_000, why="at least one sample"),
    "campaign --workers": Range("int", 1, 1024, why="local worker processes"),
    "campaign --timeout-s": Range("float", 0, 86_400, low_open=True, unit="s",
                                  why="a sample longer than a day is a hung sample"),
    "campaign --worst": Range("int", 0, 1000, why="worst samples rerun per measurement"),
    "campaign --max-reruns": Range("int", 0, 1_000_000, why="0: no rerun"),
    "campaign --connect-timeout-s": Range("float", 0, 3600, low_open=True, unit="s",
                                          why="waiting for a Dask scheduler"),
    "gate --shift-fraction": Range("float", 0, 1, low_open=True,
                                   why="a fraction of the measurement's tolerance band"),
    "run --step-timeout": Range("float", 0, 3600, low_open=True, unit="s",
                                why="lockstep wait for the DUT's answer to SYNC"),
    "--port": Range("int", 0, 65535, why="a TCP port (0: pick a free one)"),
    "bus serve --bitrate": Range("int", 10_000, 1_000_000, unit="bit/s",
                                 why="the CAN bit rates (ISOBUS: 250000)"),
    "bus serve --seed": Range("int", 0, 2**63 - 1, why="as --seed"),
    "bus serve --busy-poll-us": Range("float", 0, 1_000_000, unit="us", why="0: off"),
    "bus fault --id": Range("int", 0, 0x1FFFFFFF, why="a CAN identifier: 11 or 29 bits"),
    "bus fault --mask": Range("int", 0, 0x1FFFFFFF, why="a mask over a 29-bit identifier"),
    "bus fault --probability": Range("float", 0, 1, why="a probability"),
    "bus fault --count": Range("int", 0, 2**31 - 1, why="0: every matching frame"),
    "bus fault --delay": Range("float", 0, 3600, unit="s", why="with kind delay"),
    "bus fault --rule": Range("int", 0, 2**31 - 1, why="a rule number of fault list"),
    "bus fault -n": Range("int", 1, 10_000, why="error frames to send"),
    "isobus serve --duration": Range("float", 0, 31_536_000, low_open=True, unit="s",
                                     why="run time (a year at most); default: until Ctrl-C"),
    "isobus serve --drive-after": Range("float", 0, 3600, unit="s",
                                        why="standing still, key on, before the path"),
    "isobus serve --wheel-slip": Range("float", 0, 1, high_open=True,
                                       why="a slip fraction: the wheels cannot turn with no "
                                           "ground travel"),
}

#: every numeric key of a DUT profile, by ``table.key``
PROFILE_RANGES: dict[str, Range] = {
    "launch.ready_timeout_s": Range("float", 0, 3600, low_open=True, unit="s",
                                    why="a DUT that needs more than an hour to start is hung"),
    "launch.ready_delay_s": Range("float", 0, 3600, unit="s", why="as ready_timeout_s"),
    "launch.stop_timeout_s": Range("float", 0, 3600, low_open=True, unit="s",
                                   why="as ready_timeout_s"),
    "timing.control_period_ms": Range("float", 0, 60_000, low_open=True, unit="ms",
                                      why="equal to the rig's SYNC period"),
    "timing.heartbeat_period_ms": Range("float", 1, 65535, unit="ms",
                                        why="CANopen producer heartbeat time (object 0x1017) "
                                            "is an UNSIGNED16 of ms; 0 disables it"),
    "timing.max_frames_per_period": Range("int", 1, 100_000,
                                          why="frames a DUT may send in one period"),
    "campaign.pass_probability": Range("float", 0, 1, low_open=True, high_open=True,
                                       why="a probability; no finite campaign demonstrates "
                                           "0 or 1"),
    "campaign.confidence": Range("float", 0, 1, low_open=True, high_open=True,
                                 why="the coverage of the one-sided exact bound"),
    "campaign.sequential_good_probability": Range(
        "float", 0, 1, low_open=True, high_open=True,
        why="--sequential: the pass probability of a good build (above pass_probability)"),
    "campaign.sequential_alpha": Range(
        "float", 0, 0.5, low_open=True, high_open=True,
        why="--sequential: the risk of failing a good build (below confidence)"),
}


def check_value(value: float, rng: Range, *, what: str) -> None:
    """Raise :class:`ValueError` naming ``what`` when ``value`` is outside ``rng``."""
    if not rng.contains(value):
        raise ValueError(f"{what} must be {_a(rng.describe())}, got {value!r}")


def check_key(obj: object, table: str, *names: str) -> None:
    """Check the fields ``names`` of a profile dataclass against ``PROFILE_RANGES``.

    Raises :class:`ValueError` naming the key (the profile loader adds the file)."""
    for name in names:
        check_value(getattr(obj, name), PROFILE_RANGES[f"{table}.{name}"], what=name)


def parse_number(text: str, rng: Range) -> int | float:
    """``text`` as the number ``rng`` wants: integers in decimal or ``0x`` hexadecimal."""
    text = text.strip()
    if rng.kind == "int":
        return int(text, 0)
    return float(text)


def option_type(key: str) -> Callable[[str], int | float]:
    """An argparse ``type=`` for the option ``key`` of :data:`CLI_RANGES`: parses the text and
    refuses a value out of range, so argparse names the option (exit 2)."""
    rng = CLI_RANGES[key]

    def parse(text: str) -> int | float:
        try:
            value = parse_number(text, rng)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {_a(rng.describe())}") from None
        if not rng.contains(value):
            raise argparse.ArgumentTypeError(f"{text} is out of range: give "
                                             f"{_a(rng.describe())}")
        return value
    parse.__name__ = rng.kind   # what argparse calls the type in its messages
    return parse


def help_with_range(key: str, text: str) -> str:
    """``text`` followed by the option's range, for its ``help=``."""
    return f"{text} [{CLI_RANGES[key].describe()}]".replace("%", "%%")


def check_option(value: float | None, key: str) -> None:
    """Refuse ``value`` of the option ``key`` (for values that do not come from argparse)."""
    if value is None:
        return
    rng = CLI_RANGES[key]
    if not rng.contains(value):
        raise ConfigError(f"{value} is out of range: give {_a(rng.describe())}",
                          key=key.split()[-1])


def ranges_table() -> str:
    """Both tables as reStructuredText (the reference page shows it through autodoc)."""
    rows = [("``hil " + k + "``" if not k.startswith("--") else f"``{k}``", r)
            for k, r in CLI_RANGES.items()]
    rows += [(f"``[{k.split('.')[0]}] {k.split('.')[1]}``", r)
             for k, r in PROFILE_RANGES.items()]
    lines = [".. list-table::", "   :header-rows: 1", "", "   * - option or profile key",
             "     - valid values", "     - why"]
    for name, rng in rows:
        lines += [f"   * - {name}", f"     - ``{rng.describe()}``", f"     - {rng.why}"]
    return "\n".join(lines)


__doc__ = (__doc__ or "") + "\n\n" + ranges_table() + "\n"
