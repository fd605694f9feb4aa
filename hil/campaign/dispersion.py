"""Dispersion files: which rig parameters a campaign draws per sample, and from what.

A dispersion file is TOML with one table per rig config parameter, named by its dotted key,
holding a distribution and where its spread comes from::

    [fertilizer.density_offset_mean_frac]
    dist = "truncnormal"          # normal | uniform | truncnormal
    mean = -0.035
    sd = 0.01
    low = -0.07
    high = 0.0
    source = "papers.md: deficit of 3-4 % ([F] Table 2); lot-to-lot spread: estimate"

``normal`` takes ``mean`` and ``sd``; ``uniform`` ``low`` and ``high``; ``truncnormal``
``mean``, ``sd``, ``low`` and ``high`` (a normal cut to ``[low, high]``). ``source`` is
required: every entry says where its spread comes from. An unknown parameter, a parameter that
is not a number, an unknown distribution, a missing or extra argument, a number out of range
(``mean = 1e308``: a span that overflows a float, a truncated normal's bounds more than a
million sd from its mean): each is a :class:`~hil.errors.ConfigError` naming the file and the
key (``[table.mean]`` for a number out of range).

Draws depend on the sample's seed alone (``S+i``): sample *i* of a campaign can be drawn again
on its own, and the values it ran with are recorded with the sample.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hil.errors import ConfigError

#: the arguments each distribution takes
DISTRIBUTIONS: dict[str, tuple[str, ...]] = {
    "normal": ("mean", "sd"),
    "uniform": ("low", "high"),
    "truncnormal": ("mean", "sd", "low", "high"),
}
#: a normal's draws are taken to lie within this many sd of its mean (the range checked)
SPAN_SD = 40.0
#: a truncated normal's bounds must lie within this many sd of its mean: further out, scipy's
#: sampler loses the bounds' difference (a draw of -inf at 5e307 sd) and the normal's own mass
#: in [low, high] is nil anyway
MAX_BOUND_SD = 1e6
#: second word of the seed sequence of the draws: a stream apart from the rig's own
_STREAM = 0xD15_9E25


class OutOfRange(ValueError):
    """A distribution's number out of range; ``arg`` names it (``mean``, ``sd``, ``low``…)."""

    def __init__(self, arg: str, why: str) -> None:
        self.arg = arg
        super().__init__(f"{arg} is out of range: {why}")


@dataclass(frozen=True)
class Distribution:
    """One parameter's distribution: ``dist`` and its ``args`` (see :data:`DISTRIBUTIONS`).

    Examples
    --------
    >>> d = Distribution("uniform", {"low": 1.0, "high": 2.0})
    >>> 1.0 <= d.draw(np.random.default_rng(0)) <= 2.0
    True
    """

    dist: str
    args: dict[str, float]
    source: str = ""

    def __post_init__(self) -> None:
        if self.dist not in DISTRIBUTIONS:
            raise ValueError(f"unknown distribution {self.dist!r} (known: "
                             f"{', '.join(DISTRIBUTIONS)})")
        want = DISTRIBUTIONS[self.dist]
        missing = [a for a in want if a not in self.args]
        extra = [a for a in self.args if a not in want]
        if missing or extra:
            raise ValueError(f"{self.dist} takes {', '.join(want)}"
                             + (f"; missing {', '.join(missing)}" if missing else "")
                             + (f"; unknown {', '.join(extra)}" if extra else ""))
        for name, value in self.args.items():
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
        if "sd" in self.args and not self.args["sd"] > 0:
            raise ValueError(f"sd must be > 0, got {self.args['sd']!r}")
        if "low" in self.args and not self.args["low"] < self.args["high"]:
            raise ValueError(f"low {self.args['low']!r} must be below high "
                             f"{self.args['high']!r}")
        self._check_range()

    def _check_range(self) -> None:
        """Finite numbers can still be out of range: a span that overflows a float, bounds
        the normal cannot reach (``mean = 1e308``). Each is refused here, naming the number
        (:class:`OutOfRange`), instead of by numpy or scipy at the first draw."""
        a = self.args
        if self.dist == "normal":
            # a normal's draws lie within 40 sd of its mean (beyond 9 sd: never, in practice)
            if not math.isfinite(abs(a["mean"]) + SPAN_SD * a["sd"]):
                culprit = "sd" if SPAN_SD * a["sd"] > abs(a["mean"]) else "mean"
                raise OutOfRange(culprit, f"mean ± {SPAN_SD:g} sd overflows a float")
        elif self.dist == "uniform":
            if not math.isfinite(a["high"] - a["low"]):
                culprit = "high" if abs(a["high"]) >= abs(a["low"]) else "low"
                raise OutOfRange(culprit, "high - low overflows a float")
        else:
            lo, hi = (a["low"] - a["mean"]) / a["sd"], (a["high"] - a["mean"]) / a["sd"]
            culprit = "sd" if a["low"] <= a["mean"] <= a["high"] else "mean"
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi
                    and max(abs(lo), abs(hi)) <= MAX_BOUND_SD):
                raise OutOfRange(culprit, f"low and high lie {min(abs(lo), abs(hi)):.3g} sd "
                                 f"from the mean: the bounds must lie within "
                                 f"{MAX_BOUND_SD:g} sd of it")

    def draw(self, rng: np.random.Generator) -> float:
        """One value."""
        a = self.args
        if self.dist == "normal":
            return float(rng.normal(a["mean"], a["sd"]))
        if self.dist == "uniform":
            return float(rng.uniform(a["low"], a["high"]))
        from scipy.stats import truncnorm

        lo, hi = (a["low"] - a["mean"]) / a["sd"], (a["high"] - a["mean"]) / a["sd"]
        return float(truncnorm.rvs(lo, hi, loc=a["mean"], scale=a["sd"], random_state=rng))

    def describe(self) -> str:
        return f"{self.dist}(" + ", ".join(f"{k}={v:g}" for k, v in self.args.items()) + ")"


@dataclass(frozen=True)
class Dispersion:
    """The parameters a campaign disperses, by dotted key, in file order."""

    parameters: dict[str, Distribution]
    path: str = ""
    sha256: str = ""

    def draw(self, seed: int) -> dict[str, float]:
        """The dispersed parameters of the sample at ``seed`` (a pure function of it)."""
        rng = np.random.default_rng(np.random.SeedSequence([seed & 0xFFFFFFFF, _STREAM]))
        return {key: dist.draw(rng) for key, dist in self.parameters.items()}

    def to_dict(self) -> dict[str, Any]:
        return {"path": self.path, "sha256": self.sha256,
                "parameters": {k: {"dist": d.dist, **d.args, "source": d.source}
                               for k, d in self.parameters.items()}}


def load_dispersion(path: str | Path, *, rig: str) -> Dispersion:
    """Read and check a dispersion file against ``rig``'s config.

    Raises
    ------
    ConfigError
        naming the file and the key: unreadable file, invalid TOML, a parameter the rig's
        config does not have or that is not a number, a bad distribution.
    """
    path = Path(path)
    where = str(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError as exc:
        raise ConfigError("dispersion file not found", path=where) from exc
    except OSError as exc:
        raise ConfigError(f"cannot read the dispersion file: {exc}", path=where) from exc
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=where) from exc
    from hil.rig.registry import load_rig

    nominal = load_rig(rig).load_config()
    parameters: dict[str, Distribution] = {}
    for key, table in _leaves(data, where):
        _check_parameter(nominal, key, where, rig)
        args = {k: v for k, v in table.items() if k not in ("dist", "source")}
        source = table.get("source", "")
        if not isinstance(source, str) or not source.strip():
            raise ConfigError("every entry needs a source (where its spread comes from)",
                              path=where, key=f"{key}.source")
        dist = table.get("dist")
        if not isinstance(dist, str):
            raise ConfigError(f"dist must be one of {', '.join(DISTRIBUTIONS)}", path=where,
                              key=f"{key}.dist")
        try:
            parameters[key] = Distribution(dist, args, source)
        except OutOfRange as exc:
            raise ConfigError(f"{exc} ({dist} with " + ", ".join(
                f"{k} = {v!r}" for k, v in args.items()) + ")",
                path=where, key=f"{key}.{exc.arg}") from exc
        except ValueError as exc:
            raise ConfigError(str(exc), path=where, key=key) from exc
    if not parameters:
        raise ConfigError("no parameters: a dispersion file names at least one", path=where)
    return Dispersion(parameters, path=where, sha256=hashlib.sha256(raw).hexdigest())


def _leaves(data: dict[str, Any], where: str, prefix: str = ""
            ) -> list[tuple[str, dict[str, Any]]]:
    """The tables that hold a ``dist`` (parameters), with their dotted keys."""
    out = []
    for name, value in data.items():
        key = f"{prefix}{name}"
        if not isinstance(value, dict):
            raise ConfigError(f"expected a table per parameter (with dist = ...), got "
                              f"{value!r}", path=where, key=key)
        if "dist" in value:
            out.append((key, value))
        else:
            out.extend(_leaves(value, where, f"{key}."))
    return out


def _check_parameter(config: object, key: str, where: str, rig: str) -> None:
    node: Any = config
    for part in key.split("."):
        names = ({f.name for f in dataclasses.fields(node)}
                 if dataclasses.is_dataclass(node) else set())
        if part not in names:
            raise ConfigError(f"unknown parameter: the {rig} rig config has no {key!r}",
                              path=where, key=key)
        node = getattr(node, part)
    if isinstance(node, bool) or not isinstance(node, float):
        raise ConfigError(f"not a real-valued parameter (nominal {node!r}): only float "
                          f"parameters can be dispersed", path=where, key=key)
