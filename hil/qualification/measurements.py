"""The measurements of a qualification: judged against the profile's limits and kept for the
record, by test.

A suite names a measurement of the catalogue (:mod:`hil.limits`) and gives its value and
conditions; :meth:`MeasurementBook.judge` finds the limit that applies (the profile's
``[limits]`` entry or case, else the catalogue's default) and makes the
:class:`~hil.measurements.Measurement`; :meth:`MeasurementBook.keep` files it under the test
and the run it comes from, as the record's ``measurements`` list has it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hil.dut.profile import DutProfile
from hil.errors import ConfigError
from hil.limits import MEASUREMENTS, applied_limit, known_measurement
from hil.measurements import Measurement


@dataclass
class MeasurementBook:
    """Every measurement of a session, as the record lists them and by test."""

    profile: DutProfile
    #: the record's ``measurements`` (each with its ``test`` and ``run``)
    entries: list[dict[str, Any]] = field(default_factory=list)
    #: the judged measurements of each test (node id -> measurements)
    by_test: dict[str, list[Measurement]] = field(default_factory=dict)

    @property
    def rig(self) -> str:
        """The DUT's rig as the catalogue names it (``sowing_depth``)."""
        return self.profile.dut.rig.replace("-", "_")

    def judge(self, nodeid: str, name: str, value: float, *,
              conditions: dict[str, Any] | None = None, note: str = "") -> Measurement:
        """``name`` = ``value`` judged by the limit that applies to it (not kept).

        Raises
        ------
        ConfigError
            ``name`` is not in the catalogue for the DUT's rig.
        """
        if not known_measurement(name, self.rig):
            raise ConfigError(f"{nodeid}: measurement {name!r} is not in the catalogue "
                              f"(hil/limits.py) for the {self.rig} rig")
        conditions = dict(conditions or {})
        limit = applied_limit(name, conditions, self.profile.limit(name))
        if limit.problem:   # a limit stated for conditions this measurement cannot have
            where = f"{self.profile.path}: " if limit.source == "profile" else ""
            measured = (f"; measured {float(value):g} {MEASUREMENTS[name].unit}"
                        if math.isfinite(float(value)) else "")
            note = f"limit not applied: {where}{limit.problem}{measured}" + (
                f"; {note}" if note else "")
            value = math.nan
        return Measurement(name, float(value), MEASUREMENTS[name].unit, low=limit.low,
                           high=limit.high, conditions=conditions, note=note,
                           limit_source=limit.source,
                           **({"marginal_band": limit.marginal}
                              if limit.marginal is not None else {}))

    def keep(self, nodeid: str, m: Measurement, run_dir: str = "") -> Measurement:
        """File ``m`` under the test ``nodeid`` and the run directory it comes from."""
        entry = m.to_dict()
        entry["test"] = nodeid
        entry["run"] = run_dir
        self.entries.append(entry)
        self.by_test.setdefault(nodeid, []).append(m)
        return m

    def of_test(self, nodeid: str) -> list[Measurement]:
        """The measurements the test ``nodeid`` made (so far)."""
        return self.by_test.get(nodeid, [])
