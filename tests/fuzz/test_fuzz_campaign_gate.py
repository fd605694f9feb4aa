"""Every ``hil campaign`` and ``hil gate`` option, and campaign records, fuzzed (issue 30).

* a campaign with one option out of its range (drawn from :data:`hil.validation.CLI_RANGES`, so
  a new option's range is fuzzed as soon as it is declared) or otherwise bad is refused with
  exit 2 and one line naming the option, before any Dask cluster is asked for;
* the gate with one bad option is exit 2, one line, nothing written;
* a damaged campaign record is refused naming the file (exit 2) or judged (0/1), never with a
  traceback, and a record that did not finish is never a pass.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.campaign.record import load_campaign
from hil.errors import ConfigError
from hil.gate.completeness import incomplete_reason
from hil.validation import CLI_RANGES, Range
from tests.fuzz.cli import run_cli
from tests.fuzz.mutate import json_mutations

ROOT = Path(__file__).resolve().parents[2]
DAEMON = str(ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml")
CAMPAIGN = ROOT / "tests" / "fuzz" / "data" / "campaign.json"
RECORD = str(ROOT / "tests" / "fuzz" / "data" / "record.json")
BASE = ["campaign", DAEMON, "--samples", "2", "--bus", "inline", "--dispersion", "none",
        "--no-progress"]
CAMPAIGN_OPTIONS = {key.split()[-1]: rng for key, rng in CLI_RANGES.items()
                    if key.startswith("campaign ")} | {"--seed": CLI_RANGES["--seed"]}


@st.composite
def out_of_range(draw: st.DrawFn, rng: Range) -> str:
    """A value ``rng`` refuses, as the command line would carry it."""
    choices: list[Any] = ["nan", "inf", "-inf", "", "x", "1e999"]
    if rng.low is not None:
        low = rng.low
        choices.append(repr(low) if rng.low_open else None)
        choices.append(str(draw(st.integers(max_value=math.ceil(low) - 1)))
                       if rng.kind == "int" else
                       repr(draw(st.floats(max_value=low, allow_nan=False,
                                           exclude_max=not rng.low_open))))
    if rng.high is not None:
        high = rng.high
        choices.append(str(draw(st.integers(min_value=math.floor(high) + 1,
                                            max_value=math.floor(high) + 2**70)))
                       if rng.kind == "int" else
                       repr(draw(st.floats(min_value=high, allow_nan=False,
                                           allow_infinity=False,
                                           exclude_min=not rng.high_open))))
    if rng.kind == "int":
        choices.append("1.5")
    return draw(st.sampled_from([c for c in choices if c is not None]))


@pytest.fixture
def no_cluster(monkeypatch: pytest.MonkeyPatch) -> None:
    import hil.campaign.engine as engine

    def refuse(**kwargs: Any) -> Any:
        raise AssertionError("a Dask cluster was asked for before the options were checked")
    monkeypatch.setattr(engine, "dask_client", refuse)


def _one_line_naming(outcome: Any, name: str, what: Any) -> None:
    assert outcome.code == 2, (what, outcome)
    assert "Traceback" not in outcome.stderr, (what, outcome.stderr)
    lines = [line for line in outcome.error_lines() if not line.startswith("usage:")]
    assert len(lines) == 1 and name in lines[0], (what, lines)


@given(data=st.data())
def test_every_campaign_option_out_of_range(data: st.DataObject, no_cluster: None,
                                            tmp_path_factory: pytest.TempPathFactory) -> None:
    option = data.draw(st.sampled_from(sorted(CAMPAIGN_OPTIONS)))
    value = data.draw(out_of_range(CAMPAIGN_OPTIONS[option]))
    out = tmp_path_factory.mktemp("campaign") / "out"
    argv = [*BASE, "--out", str(out), f"{option}={value}"]
    if option == "--connect-timeout-s":
        argv += ["--scheduler", "tcp://127.0.0.1:1"]
    _one_line_naming(run_cli(*argv), option, argv)
    assert not out.exists()


BAD_CAMPAIGN = {
    "-k": st.sampled_from(["(", "a and", "not", "x or (y", "and or"]),
    "--bus": st.sampled_from(["nosuchbus:0", "socketcan:", ",", "socketcand:h",
                              "socketcand:127.0.0.1:99999/can0"]),
    "--suite": st.sampled_from(["nosuch", "fast,nosuch", "", ","]),
    "--scheduler": st.sampled_from(["localhost", "tcp://", "tcp://h:0", "tcp://h:x", "h:8786",
                                    "ftp://h:1"]),
    "--clock": st.just("realtime"),        # with the inline bus
    "--isolation": st.sampled_from(["thread", ""]),
}


@given(data=st.data())
def test_every_other_campaign_option(data: st.DataObject, no_cluster: None,
                                     tmp_path_factory: pytest.TempPathFactory) -> None:
    option = data.draw(st.sampled_from(sorted(BAD_CAMPAIGN)))
    value = data.draw(BAD_CAMPAIGN[option])
    out = tmp_path_factory.mktemp("campaign") / "out"
    argv = [*BASE, "--out", str(out), option, value]
    outcome = run_cli(*argv)
    _one_line_naming(outcome, "--bus" if option == "--clock" else option, argv)
    assert not out.exists()


def _campaign_doc(**change: Any) -> dict[str, Any]:
    return {**json.loads(CAMPAIGN.read_text()), **change}


@given(data=st.data())
def test_every_gate_option(data: st.DataObject,
                           tmp_path_factory: pytest.TempPathFactory) -> None:
    tmp = tmp_path_factory.mktemp("gate")
    record = tmp / "campaign.json"
    record.write_text(json.dumps(_campaign_doc()))
    other = tmp / "other.json"
    case = data.draw(st.sampled_from([
        "shift-fraction", "baseline-other-rig", "baseline-interrupted", "baseline-missing",
        "baseline-not-json", "tolerance-missing", "summary-dir", "update-without-baseline",
        "record-missing", "qualification-record-shift"]))
    named = "--shift-fraction"
    if case == "shift-fraction":
        value = data.draw(out_of_range(CLI_RANGES["gate --shift-fraction"]))
        argv = ["gate", str(record), f"--shift-fraction={value}"]
    elif case == "baseline-other-rig":
        doc = _campaign_doc(rig={"name": "sowing-depth"})
        other.write_text(json.dumps(doc))
        argv, named = ["gate", str(record), "--baseline", str(other)], "--baseline"
    elif case == "baseline-interrupted":
        other.write_text(json.dumps(_campaign_doc(status="interrupted")))
        argv, named = ["gate", str(record), "--baseline", str(other)], "--baseline"
    elif case == "baseline-missing":
        argv, named = ["gate", str(record), "--baseline", str(tmp / "no.json")], "no.json"
    elif case == "baseline-not-json":
        other.write_text("{")
        argv, named = ["gate", str(record), "--baseline", str(other)], "other.json"
    elif case == "tolerance-missing":
        argv, named = ["gate", str(record), "--tolerance", str(tmp / "t.toml")], "t.toml"
    elif case == "summary-dir":
        argv, named = ["gate", RECORD, "--summary", str(tmp / "no" / "s.md")], "s.md"
    elif case == "update-without-baseline":
        argv, named = ["gate", str(record), "--update-baseline"], "--baseline"
    elif case == "record-missing":
        argv, named = ["gate", str(tmp / "none.json")], "none.json"
    else:
        argv = ["gate", RECORD, "--shift-fraction", "nan"]
    before = sorted(p.name for p in tmp.iterdir())
    _one_line_naming(run_cli(*argv), named, (case, argv))
    assert sorted(p.name for p in tmp.iterdir()) == before       # nothing written


@given(case=json_mutations(CAMPAIGN))
def test_mutated_campaign_records(case: tuple[str, bytes],
                                  tmp_path_factory: pytest.TempPathFactory) -> None:
    what, content = case
    tmp = tmp_path_factory.mktemp("record")
    path = tmp / "campaign.json"
    path.write_bytes(content)
    try:
        doc = json.loads(content)
    except (ValueError, UnicodeDecodeError):
        doc = None
    refused = False
    try:
        load_campaign(path)
    except ConfigError as exc:
        refused = True
        assert "\n" not in str(exc) and str(path) in str(exc), (what, str(exc))
    outcome = run_cli("gate", str(path), "--baseline", str(CAMPAIGN))
    assert "Traceback" not in outcome.stderr and "internal error" not in outcome.stderr, \
        (what, outcome.stderr)
    assert outcome.code in (0, 1, 2, 3), (what, outcome)
    if refused or (doc is not None and incomplete_reason(doc, path=str(path))):
        assert outcome.code == 2, (what, outcome)
        assert len(outcome.error_lines()) == 1, (what, outcome.stderr)
    if outcome.code == 0:
        assert isinstance(doc, dict) and doc.get("status") == "complete"
        assert len(doc["samples"]) >= doc["samples_requested"]
