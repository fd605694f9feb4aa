"""``campaign.json``: the campaign record (schema ``agrihil.campaign/1``), written atomically.

See ``docs/guide/campaigns.md`` for every field. The record is rewritten as samples arrive (and
on Ctrl-C), so a campaign stopped at any point leaves a valid record of what it finished, with
``status`` saying whether it is complete; ``samples.jsonl`` next to it gets each sample as it
arrives.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hil.errors import ConfigError
from hil.record.atomic import write_text_atomic

SCHEMA = "agrihil.campaign/1"
RECORD_NAME = "campaign.json"
SAMPLES_NAME = "samples.jsonl"


def write_record(out: Path, doc: dict[str, Any]) -> Path:
    """Write ``doc`` to ``out/campaign.json`` through a temporary file (never half a file)."""
    return write_text_atomic(out / RECORD_NAME,
                             json.dumps(doc, indent=1, default=_default, allow_nan=False))


def _default(obj: Any) -> Any:
    return str(obj)


def clean(value: Any) -> Any:
    """NaN and infinities as ``null`` (JSON has neither), recursively."""
    if isinstance(value, float):
        return value if value == value and abs(value) != float("inf") else None
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean(v) for v in value]
    return value


def load_campaign(path: str | Path) -> dict[str, Any]:
    """Read a campaign record (a file, or a directory holding ``campaign.json``).

    Raises :class:`ConfigError` naming the file when it is missing, not JSON or of another
    schema."""
    path = Path(path)
    if path.is_dir():
        path = path / RECORD_NAME
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise ConfigError("campaign record not found", path=str(path)) from exc
    except (OSError, ValueError) as exc:
        raise ConfigError(f"not a readable JSON campaign record: {exc}", path=str(path)) from exc
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        found = doc.get("schema") if isinstance(doc, dict) else None
        raise ConfigError(f"not a campaign record (schema {found!r}, expected {SCHEMA})",
                          path=str(path), key="schema")
    check_campaign_fields(doc, path=str(path))
    doc["_path"] = str(path)
    return doc


#: a campaign's own verdicts (summary.verdict) and a sample's
CAMPAIGN_VERDICTS = ("pass", "fail", "inconclusive", "error")
SAMPLE_VERDICTS = ("pass", "fail", "error", "invalid-bench", "interrupted")
STATUSES = ("running", "complete", "interrupted")


def check_campaign_fields(doc: dict[str, Any], *, path: str) -> None:
    """Check every field the gate reads, with its type; raise :class:`ConfigError` naming
    the file and the key (a hand-edited or damaged record is refused, never a traceback)."""
    from hil.gate.jsonfile import Fields

    top = Fields(doc, path=path)
    status = top.string("status")
    if status not in STATUSES:
        raise top.error("status", f"{status!r} is not one of {list(STATUSES)}")
    requested = top.data.get("samples_requested")
    if isinstance(requested, bool) or not isinstance(requested, int) or requested < 1:
        raise top.error("samples_requested", f"expected an integer >= 1, got {requested!r}")
    if not top.child("dut").string("name"):
        raise top.error("dut.name", "must not be empty")
    rig = top.child("rig", required=False)
    rig.string("name", required=False)
    summary = top.child("summary")
    verdict = summary.string("verdict")
    if verdict not in CAMPAIGN_VERDICTS:
        raise summary.error("verdict", f"{verdict!r} is not one of {list(CAMPAIGN_VERDICTS)}")
    summary.string("reason")
    for i, item in enumerate(top.array("samples")):
        sample = Fields(item, path=path, prefix=f"samples[{i}]")
        index = sample.data.get("index")
        if isinstance(index, bool) or not isinstance(index, int) or index < 0:
            raise sample.error("index", f"expected an integer >= 0, got {index!r}")
        sample_verdict = sample.string("verdict")
        if sample_verdict not in SAMPLE_VERDICTS:
            raise sample.error("verdict", f"{sample_verdict!r} is not one of "
                                          f"{list(SAMPLE_VERDICTS)}")
        for j, entry in enumerate(sample.array("measurements")):
            m = Fields(entry, path=path, prefix=f"samples[{i}].measurements[{j}]")
            if not m.string("name"):
                raise m.error("name", "must not be empty")
            m.number("value")
            m.number("low", required=False)
            m.number("high", required=False)
            m.mapping("conditions", required=False)
            m.string("outcome", required=False)


def is_campaign(path: str | Path) -> bool:
    """True when ``path`` holds a campaign record (peeks at the schema, never raises)."""
    path = Path(path)
    if path.is_dir():
        path = path / RECORD_NAME
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(4096)
    except (OSError, UnicodeDecodeError):   # not a campaign: the record loader says why
        return False
    return f'"schema": "{SCHEMA}"' in head
