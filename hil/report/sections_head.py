"""The top of the page: the verdict with its reasons, then who was tested on what bench."""

from __future__ import annotations

import datetime as dt
from typing import Any

from hil.report.markup import DASH, deflist, esc, fmt_num, fmt_seconds
from hil.report.record import MeasurementRow, QualRecord
from hil.report.rundata import RunData

VERDICT_WORDS = {"pass": "PASS", "fail": "FAIL", "invalid-bench": "INVALID BENCH",
                 "error": "ERROR"}
MAX_REASONS = 8


def _limit_text(m: MeasurementRow) -> str:
    at = f" ({m.per_condition})" if m.per_condition else ""
    if m.low is not None and m.high is not None:
        return f"limits {fmt_num(m.low)} to {fmt_num(m.high)}{at}"
    if m.high is not None:
        return f"limit ≤ {fmt_num(m.high)}{at}"
    if m.low is not None:
        return f"limit ≥ {fmt_num(m.low)}{at}"
    return "no limit"


def _measurement_reason(m: MeasurementRow) -> str:
    cond = f" ({m.conditions_label})" if m.conditions else ""
    value = "no value" if m.value is None else f"{fmt_num(m.value)} {m.unit}".strip()
    return f"{m.name}{cond}: {value}, {_limit_text(m)}" + (f" ({m.note})" if m.note else "")


def _why(message: str) -> str:
    """The line of a pytest message that says why: the last ``E`` line, else the last line."""
    lines = [line.strip() for line in message.splitlines() if line.strip()]
    errors = [line[1:].strip() for line in lines if line.startswith("E ")]
    why = errors[-1] if errors else lines[-1] if lines else "no message"
    return why[:200]


def _reasons(qual: QualRecord, runs: list[RunData]) -> list[str]:
    out: list[str] = []
    if qual.error:
        out.append(qual.error)
    timing = qual.timing or {}
    if qual.verdict == "invalid-bench" or timing.get("valid") is False:
        raw = timing.get("invalid_reasons") or []
        for reason in raw if isinstance(raw, list) else [raw]:
            out.append(f"bench timing out of bounds: {reason}")
        out.append("an invalid bench says nothing about the DUT: rerun on a quieter bench")
    bad = [m for m in qual.measurements if m.status in ("fail", "error")]
    out += [f"{m.status.upper()} {_measurement_reason(m)}" for m in bad]
    explained = {m.test for m in bad}
    for t in qual.tests:
        if t.outcome in ("failed", "error") and t.nodeid not in explained:
            out.append(f"test {t.nodeid} {t.outcome}: {_why(t.message)}")
    for run in runs:
        if run.verdict in ("error", "aborted"):
            out.append(f"run {run.ref.dir} ({run.scenario}) ended in {run.verdict}: "
                       f"{run.error or 'see Errors'}")
    if len(out) > MAX_REASONS:
        out = [*out[:MAX_REASONS], f"… and {len(out) - MAX_REASONS} more (see below)"]
    return out


def verdict_section(qual: QualRecord, runs: list[RunData], has_errors: bool) -> str:
    word = VERDICT_WORDS.get(qual.verdict, qual.verdict.upper() or "UNKNOWN")
    cls = qual.verdict if qual.verdict in VERDICT_WORDS else "unknown"
    counts = qual.counts()
    chips = "".join(
        f'<span class="chip c-{key}"><b>{counts[key]}</b> {label}</span>'
        for key, label in (("pass", "pass"), ("marginal", "marginal pass"), ("fail", "fail"),
                           ("error", "error"), ("info", "info")))
    dut = qual.dut
    who = " ".join(str(x) for x in (dut.get("name"), dut.get("version")) if x) or "unnamed DUT"
    if dut.get("build_id"):
        who += f" (build {dut['build_id']})"
    reasons = _reasons(qual, runs)
    items = "".join(f"<li>{esc(r)}</li>" for r in reasons)
    more = ' <a href="#errors">Errors</a>' if has_errors else ""
    return f"""
<section class="verdict v-{esc(cls)}" id="verdict">
  <div class="verdict-word">{esc(word)}</div>
  <div class="verdict-body">
    <div class="verdict-who">{esc(who)} on the {esc(qual.rig_name or '?')} rig ·
      {esc(when(qual.started_at) or DASH)}</div>
    <div class="chips">{chips}</div>
    <div class="small">{len(qual.measurements)} measurements (the chips add up to it) ·
      {len(qual.tests)} tests · {len(runs)} runs · marginal pass: a pass within 5 % of its
      limit span, counted apart from the other passes{more}</div>
    {f'<ul class="reasons">{items}</ul>' if items else ''}
  </div>
</section>"""


def when(iso: str) -> str:
    """An ISO timestamp as a person reads it (as given when it does not parse)."""
    try:
        stamp = dt.datetime.fromisoformat(iso)
    except ValueError:
        return iso
    if stamp.utcoffset() == dt.timedelta(0):
        return f"{stamp:%Y-%m-%d %H:%M:%S} UTC"
    return stamp.isoformat(sep=" ")


def _code(value: Any) -> str:
    return f"<code>{esc(value)}</code>" if value not in (None, "") else DASH


def _text(value: Any) -> str:
    if isinstance(value, dict):
        value = ", ".join(f"{k}={v}" for k, v in value.items())
    elif isinstance(value, list | tuple):
        value = ", ".join(str(v) for v in value)
    return esc(value) if value not in (None, "") else DASH


def build_items(build: Any) -> list[tuple[str, str]]:
    """Device-block rows of a firmware build: the source set's and each artifact's SHA-256,
    the compiler, whether the build came from the cache. A DUT that was not built (in-process,
    daemon, physical, or a firmware twin on the inline bus) says so in one row."""
    if not isinstance(build, dict) or not build:
        return []
    items = [("build sources sha256", _code(build.get("source_sha256")))]
    for artifact in build.get("artifacts") or []:
        if not isinstance(artifact, dict):
            continue
        size = artifact.get("bytes")
        size_text = f" ({int(size):,} bytes)" if isinstance(size, int) else ""
        items.append((f"artifact {artifact.get('path', '?')}",
                      f"{_code(artifact.get('sha256'))}{esc(size_text)}"))
    items.append(("compiler", _text(build.get("compiler") or "unknown (no CMake cache)")))
    if "cached" in build:
        items.append(("build", _text("from the build cache" if build.get("cached")
                                     else "built for this qualification")))
    return items


def code_items(code: Any) -> list[tuple[str, str]]:
    """Device-block rows of the code under test (the record's ``dut.code``): the program its
    command runs with its SHA-256, an in-process twin's module, and the git revision of its
    files with whether they differed from it."""
    if not isinstance(code, dict) or not code:
        return []
    items: list[tuple[str, str]] = []
    program = code.get("program")
    if isinstance(program, dict):
        label = f"program {program.get('path') or '(' + str(program.get('what')) + ')'}"
        value = _code(program.get("sha256")) if program.get("sha256") else _text(
            program.get("note") or "not hashed")
        items.append((label, value))
    module = code.get("inprocess_module")
    if isinstance(module, dict):
        items.append((f"in-process module {module.get('path', '?')}",
                      _code(module.get("sha256"))))
    git = code.get("git")
    if isinstance(git, dict):
        dirty = " (its files differ from it)" if git.get("dirty") else ""
        items.append(("git revision", f"{_code(git.get('revision'))}{esc(dirty)}"))
    return items


def dut_build(qual: QualRecord, runs: list[RunData]) -> Any:
    """The build facts of the qualified DUT: the record's ``dut.build`` if it has one, else
    the ``dut_build`` its runs' records carry (the first run of this DUT that was built)."""
    if isinstance(qual.dut.get("build"), dict):
        return qual.dut["build"]
    name = qual.dut.get("name")
    for run in runs:
        build = run.record.get("dut_build")
        identity = run.record.get("dut_identity")
        same = not isinstance(identity, dict) or identity.get("name") == name
        if isinstance(build, dict) and build and same:
            return build
    return None


def identity_section(qual: QualRecord, runs: list[RunData]) -> str:
    dut = qual.dut
    dut_items = [("name", _text(dut.get("name"))), ("version", _text(dut.get("version"))),
                 ("build id", _code(dut.get("build_id"))), ("kind", _text(dut.get("kind"))),
                 ("controller", _text(dut.get("controller"))), ("rig", _text(dut.get("rig"))),
                 ("profile", _code(dut.get("profile"))),
                 ("profile sha256", _code(dut.get("profile_sha256")))]
    shown = {"name", "version", "build_id", "kind", "controller", "rig", "profile",
             "profile_sha256", "build", "code"}
    dut_items += code_items(dut.get("code"))
    dut_items += build_items(dut_build(qual, runs))
    dut_items += [(k, _text(v)) for k, v in dut.items() if k not in shown]
    rig = qual.rig
    bench = [("rig", _text(rig.get("name"))),
             ("rig config sha256", _code(rig.get("config_sha256"))),
             *((k, _text(v)) for k, v in rig.items() if k not in ("name", "config_sha256")),
             ("bus", _code(qual.bus)), ("clock", _text(qual.clock)), ("seed", _text(qual.seed)),
             ("suites", _text(", ".join(qual.suites))), ("started", _text(when(qual.started_at))),
             ("wall time", esc(fmt_seconds(qual.wall_s))), ("qualification id", _code(qual.run_id)),
             ("record schema", _code(qual.schema))]
    versions = " · ".join(f"{esc(k)} <code>{esc(v)}</code>" for k, v in qual.versions.items())
    return f"""
<section id="identity">
  <h2>Device and bench</h2>
  <div class="cards">
    <div class="card"><h3>Device under test</h3>{deflist(dut_items)}</div>
    <div class="card"><h3>Rig and bench</h3>{deflist(bench)}</div>
  </div>
  <p class="small versions"><b>Versions:</b> {versions or DASH}</p>
</section>"""


def header(qual: QualRecord) -> str:
    name = qual.dut.get("name") or "unnamed DUT"
    return (f'<header><div class="small">agrihil · device qualification report</div>'
            f"<h1>{esc(name)} {esc(qual.dut.get('version') or '')}</h1></header>")
