"""The bus conformance of each run of the DUT under qualification (:mod:`hil.conformance`).

Judged from the run's bus log, so only where one is written (``--hil-record full``); its
measurements are the test's, with the run's directory among their conditions (runs of one test
measure the same names), and its per-message table goes to the run's ``conformance.json``.
What a DUT that stopped left on the bus judges nothing: each check is then failed (NaN) with
the reason.
"""

from __future__ import annotations

import dataclasses
import math

from hil.dut.profile import DutProfile
from hil.measurements import Measurement
from hil.qualification.runs import stopped_reason
from hil.rig import Rig, RunResult


def judge_conformance(profile: DutProfile, rig_cls: type[Rig], result: RunResult,
                      run_dir: str) -> list[Measurement]:
    """The conformance measurements of one run (its ``conformance.json`` written).

    Parameters
    ----------
    profile : DutProfile
        The DUT under qualification (its declared frames and limits).
    rig_cls : type of Rig
        The run's rig (its physics period).
    result : RunResult
        The run.
    run_dir : str
        The run's directory relative to the report (``runs/...``).

    Returns
    -------
    list of Measurement
        The checks, failed with the reason if the DUT stopped in the run.
    """
    from hil.conformance import run_conformance, write_detail

    found = run_conformance(result.record, result.out_dir, profile,
                            physics_period_s=rig_cls.physics_period_s,
                            conditions={"run": run_dir.removeprefix("runs/")})
    write_detail(found, result.out_dir)
    stopped = stopped_reason(result) if result.record.get("error") else ""
    if not stopped:
        return list(found.measurements)
    return [dataclasses.replace(m, value=math.nan,
                                note=stopped + (f"; {m.note}" if m.note else ""))
            for m in found.measurements]
