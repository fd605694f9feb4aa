"""Every measurement that can judge has a default limit from its standard (issue 43).

A profile without ``[limits]`` is judged by the catalogue (``hil/limits.py``); a profile may
tighten a default, and loosening one states its reason (``reason``), which ``hil profile
check`` prints; ``hil limits`` prints the catalogue without building the docs.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.dut.profile import load_profile
from hil.effective_limits import effective_limits, loosening, origin_of
from hil.errors import ConfigError
from hil.limits import BUILT_IN, MEASUREMENTS, applied_limit

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ["fertilizer-piecewise-pid-daemon.toml", "fertilizer-piecewise-pid-firmware.toml",
             "sowing-depth-fuzzy-pid-daemon.toml", "sowing-depth-fuzzy-pid-firmware.toml"]


def _judges(name: str) -> bool:
    spec = MEASUREMENTS[name]
    return (spec.low is not None or spec.high is not None or bool(spec.cases)
            or bool(spec.default_rule))


def test_every_measurement_has_a_default_with_its_source_or_says_why_not() -> None:
    # the built-in catalogue: a rig of your own loaded by an earlier test in this process adds
    # its measurements, whose defaults are its rig file's
    silent = [n for n in BUILT_IN if not _judges(n) and not MEASUREMENTS[n].information]
    assert not silent, f"neither a default limit nor a reason to be information only: {silent}"
    unsourced = [n for n in BUILT_IN if _judges(n) and not MEASUREMENTS[n].source]
    assert not unsourced, f"default limits without their source: {unsourced}"


def test_information_only_is_the_exception() -> None:
    info = sorted(n for n in BUILT_IN if MEASUREMENTS[n].information)
    assert info == ["bus.sync_latency.max", "bus.sync_latency.p50", "depth.field.cv",
                    "rig.timing.lateness_p99"]


@pytest.mark.parametrize("name", REFERENCE)
def test_the_reference_profiles_limits_are_the_defaults(name: str) -> None:
    """So removing their [limits] would judge them the same: what a new profile gets."""
    profile = load_profile(ROOT / "dut_profiles" / name)
    assert profile.limits
    for measurement, limit in profile.limits.items():
        assert origin_of(measurement, limit) == "default", measurement
        spec = MEASUREMENTS[measurement]
        assert limit.marginal == spec.marginal, measurement


def test_a_profile_without_limits_is_judged_by_the_catalogue() -> None:
    limit = applied_limit("depth.field.pass_rate", {"speed_band_kmh": "3-5"})
    assert (limit.low, limit.high, limit.marginal, limit.source) == (90.0, None, 0.5,
                                                                      "catalogue")
    assert applied_limit("depth.field.cv", {"speed_band_kmh": "3-5"}).source == "none"


def _profile(tmp_path: Path, entry: str, name: str = "sowing-depth-fuzzy-pid-daemon") -> Path:
    text = (ROOT / "dut_profiles" / f"{name}.toml").read_text(encoding="utf-8")
    text = text.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/')
    start = text.index("[limits]")
    end = text.index("\n[", start + 1)
    path = tmp_path / f"{name}.toml"
    path.write_text(text[:start] + "[limits]\n" + entry + "\n" + text[end:], encoding="utf-8")
    return path


def test_loosening_without_a_reason_is_refused_naming_file_and_key(tmp_path: Path) -> None:
    path = _profile(tmp_path, '"depth.field.pass_rate" = { low = 80.0 }')
    with pytest.raises(ConfigError) as caught:
        load_profile(path)
    assert caught.value.path == str(path)
    assert caught.value.key == "limits.depth.field.pass_rate.reason"
    assert "low 80 below the default 90" in str(caught.value)


@pytest.mark.parametrize("entry", [
    '"depth.step.response_time" = { low = 0.0 }',                     # drops the high bound
    '"depth.field.mean" = { low = 27.0, high = 34.0 }',
    '"depth.step.overshoot" = { when = [ { to_mm = 40, high = 15.0 } ] }',   # one case
    '"bus.heartbeat.max_interval" = { high = 50.0 }',      # replaces a rule of the run
])
def test_every_way_of_loosening_needs_a_reason(tmp_path: Path, entry: str) -> None:
    with pytest.raises(ConfigError, match="say why with reason"):
        load_profile(_profile(tmp_path, entry))
    fixed = entry[:-2] + ', reason = "installation X" }'
    name = entry.split('"')[1]
    assert load_profile(_profile(tmp_path, fixed)).limits[name].reason == "installation X"


@pytest.mark.parametrize("entry", [
    '"depth.field.pass_rate" = { low = 95.0 }',
    '"depth.field.mean" = { low = 28.0, high = 32.0 }',
    '"depth.step.overshoot" = { when = [ { to_mm = 40, high = 5.0 } ] }',
    '"bus.share" = { high = 5.0 }',
    '"depth.field.cv" = { high = 6.0 }',                   # information only: any limit
])
def test_tightening_needs_no_reason(tmp_path: Path, entry: str) -> None:
    profile = load_profile(_profile(tmp_path, entry))
    name = entry.split('"')[1]
    assert loosening(name, profile.limits[name]) == []


def test_profile_check_prints_the_effective_limits_with_their_sources(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _profile(tmp_path, '"depth.field.pass_rate" = { low = 85.0, reason = "stony plot" }\n'
                              '"depth.step.overshoot" = { high = 8.0 }')
    assert main(["profile", "check", str(path)]) == 0
    out = capsys.readouterr().out
    lines = {line.split()[0]: line for line in out.splitlines()[1:]}
    counted = re.search(r"(\d+) measurements judged, (\d+) information only", out)
    assert counted and int(counted[1]) + int(counted[2]) == len(lines), out
    assert int(counted[2]) == 4
    assert re.search(r"loosened \(default >= 90, from GB/T 20865-2007 band, \[D\] Table 3\); "
                     r"reason: stony plot", lines["depth.field.pass_rate"])
    assert ">= 85 [%]" in lines["depth.field.pass_rate"]
    assert "tightened (default <= 10, from [D] Table 3)" in lines["depth.step.overshoot"]
    assert "<= 3 [s]" in lines["depth.step.response_time"]
    assert "default from [D] rod speed" in lines["depth.step.response_time"]
    assert "information only: every sample" in lines["depth.field.cv"]
    assert not any(name.startswith("isobus.") for name in lines)   # not an ISOBUS DUT
    assert main(["profile", "check", "-q", str(path)]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 1


def test_effective_limits_cover_the_rig_catalogue() -> None:
    limits = effective_limits("sowing_depth", {})
    names = [lim.name for lim in limits]
    assert "depth.field.pass_rate" in names and "flow.bench.accuracy" not in names
    assert {lim.origin for lim in limits} == {"default", "information"}


def test_hil_limits_prints_the_catalogue_as_json_and_text(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["limits", "--rig", "sowing-depth", "--format", "json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert rows["depth.field.pass_rate"]["limit"] == ">= 90"
    assert rows["depth.field.pass_rate"]["source"] == "GB/T 20865-2007 band, [D] Table 3"
    assert rows["depth.field.cv"]["origin"] == "information"
    assert "bus.share" in rows and "flow.bench.accuracy" not in rows
    assert main(["limits"]) == 0
    text = capsys.readouterr().out
    assert re.search(r"^fertilizer\s+flow\.bench\.accuracy\s+>= 97\.5 \[%\]\s+\(\[F\] eq\. 15",
                     text, re.MULTILINE)
    assert main(["limits", "--rig", "nope"]) == 2


@pytest.mark.slow
def test_a_bad_controller_without_limits_fails_by_the_catalogue(tmp_path: Path) -> None:
    """The must-fail controller without integral action, its [limits] removed: the
    catalogue's default fails it (a profile that says nothing no longer passes)."""
    source = ROOT / "dut_profiles" / "must_fail" / "fertilizer-no-integral-daemon.toml"
    text = source.read_text(encoding="utf-8")
    start = text.index("[limits]")
    end = text.find("\n[", start + 1)
    text = text[:start] + (text[end + 1:] if end >= 0 else "")
    assert "[limits]" not in text
    profile = tmp_path / source.name
    profile.write_text(text.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/'),
                       encoding="utf-8")
    done = subprocess.run(
        [sys.executable, "-m", "hil", "qualify", str(profile), "--bus", "inline",
         "--out", str(tmp_path / "q"), "-k", "test_flow_step"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 1, done.stdout[-3000:] + done.stderr[-3000:]
    record = json.loads((tmp_path / "q" / "record.json").read_text(encoding="utf-8"))
    failed = [m for m in record["measurements"] if m["outcome"] == "fail"]
    assert any(m["name"] == "flow.step.steady_state_error" for m in failed), failed
    assert {m["limit_source"] for m in failed} == {"catalogue"}
    assert record["limits"] == {}


def test_profile_show_gives_the_effective_limits_and_the_code(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _profile(tmp_path, '"depth.field.pass_rate" = { low = 85.0, reason = "stony plot" }')
    assert main(["profile", "show", str(path)]) == 0
    shown = json.loads(capsys.readouterr().out)
    limits = {lim["name"]: lim for lim in shown["limits"]}
    assert limits["depth.field.pass_rate"]["origin"] == "loosened"
    assert limits["depth.field.pass_rate"]["reason"] == "stony plot"
    assert limits["depth.step.overshoot"]["limit"] == "<= 10"
    assert shown["identity"]["code"]["program"]["path"] == "reference_controllers/daemon.py"
