"""The qualification record (``record.json``, schema ``agrihil.qualification/1``): what a
finished session is, as one JSON document, and where it is written.

:func:`qualification_record` makes the document from what the session kept (a pure function
of its arguments, apart from the rig config it hashes); :func:`write_outputs` writes it,
atomically, and the HTML report beside it. The format is documented in
``docs/reference/record-format.md``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any

from hil.dut.profile import DutProfile
from hil.effective_limits import record_limits
from hil.qualification.summary import summary
from hil.record.atomic import write_json_atomic
from hil.record.recorder import versions
from hil.rig import Rig, load_rig

SCHEMA = "agrihil.qualification/1"


@dataclasses.dataclass(frozen=True)
class Completeness:
    """Which of the selected tests ran (a record of a session that did not run them all says
    so)."""

    complete: bool
    planned: list[str]
    completed: set[str]

    def to_dict(self) -> dict[str, Any]:
        """The record's keys for an incomplete session (none for a complete one)."""
        if self.complete:
            return {}
        return {"complete": False, "tests_planned": len(self.planned),
                "tests_completed": len(self.completed & set(self.planned)),
                "tests_not_run": [n for n in self.planned if n not in self.completed]}


def qualification_record(*, run_id: str, started_at: str, wall_s: float, verdict: str,
                         profile: DutProfile, bus: str, clock: str, seed: int | None,
                         suites: set[str], measurements: list[dict[str, Any]],
                         tests: list[dict[str, Any]], runs: list[dict[str, Any]],
                         timing: dict[str, Any] | None, completeness: Completeness,
                         setup_error: str = "", rig_overrides: dict[str, Any] | None = None,
                         record_mode: str = "full") -> dict[str, Any]:
    """The record of a session (see ``docs/reference/record-format.md`` for each key).

    Parameters
    ----------
    run_id, started_at : str
        The session's id and start (ISO 8601, UTC).
    wall_s : float
        The session's wall time so far.
    verdict : str
        Its verdict (:func:`hil.qualification.verdict.session_verdict`).
    profile : DutProfile
        The DUT under qualification.
    bus, clock : str
        The session's bus spec and clock.
    seed : int, optional
        The base seed (``--hil-seed``).
    suites : set of str
        The suites selected.
    measurements, tests, runs : list of dict
        The record's lists, as the session kept them.
    timing : dict, optional
        The timing of the run with the worst lateness.
    completeness : Completeness
        Which selected tests ran.
    setup_error : str, optional
        The setup problem that ended the session.
    rig_overrides : dict, optional
        The ``--hil-rig-override`` table.
    record_mode : str, optional
        ``full`` or ``measurements``.

    Returns
    -------
    dict
        The record, keys in the order ``record.json`` has them.
    """
    rig_cls = load_rig(profile.dut.rig)
    return {
        "schema": SCHEMA,
        "run_id": run_id,
        "started_at": started_at,
        "wall_s": round(wall_s, 3),
        "verdict": verdict,
        "dut": {**profile.identity(), "parameters": profile.parameters},
        "rig": {"name": rig_cls.name, **rig_config_identity(rig_cls, profile)},
        "bus": bus, "clock": clock, "seed": seed,
        "suites": sorted(suites),
        "versions": versions(),
        "limits": record_limits(profile.limits),
        "summary": summary(measurements),
        "measurements": measurements,
        "tests": tests,
        "runs": runs,
        "timing": timing,
        # only in a record of a qualification that did not run all its tests
        **completeness.to_dict(),
        **({"error": setup_error} if setup_error else {}),
        **({"rig_overrides": dotted(rig_overrides)} if rig_overrides else {}),
        **({"record_mode": record_mode} if record_mode != "full" else {}),
    }


def write_outputs(report_dir: Path, record: dict[str, Any], *, html: bool) -> str:
    """Write ``record.json`` (atomically) and, with ``html``, ``report.html``.

    A failure to write the HTML report does not lose the record.

    Returns
    -------
    str
        Why ``report.html`` was not written ("" when it was, or was not asked for).
    """
    report_dir.mkdir(parents=True, exist_ok=True)
    # atomic: a second Ctrl-C or a kill while writing leaves the old file or the new one
    write_json_atomic(report_dir / "record.json", record)
    if not html:
        return ""
    from hil.report import write_html

    try:
        write_html(report_dir)
    except Exception as exc:  # the record is written; say loudly the page is not
        return f"report.html not written: {exc}"
    return ""


def rig_config_identity(rig_cls: type[Rig], profile: DutProfile) -> dict[str, Any]:
    """What the record says of the rig's config.

    Its hash (the packaged config with the profile's ``[rig]`` overrides applied) and the
    overrides as dotted keys.
    """
    config = rig_cls.load_config(profile.rig_config, source=str(profile.path or ""))
    out: dict[str, Any] = {}
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        text = json.dumps(dataclasses.asdict(config), sort_keys=True, default=str)
        out["config_sha256"] = hashlib.sha256(text.encode()).hexdigest()
    out["config_overrides"] = dotted(profile.rig_config) or "none (the packaged config)"
    return out


def dotted(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """A nested table as dotted keys: ``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        if isinstance(value, dict):
            out.update(dotted(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out
