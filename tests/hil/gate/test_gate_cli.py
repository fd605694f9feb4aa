"""``hil gate`` end to end: exit codes, the summaries, and the baseline update."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli.main import main

from .records import DUT, good, record, step_time, write

ROOT = Path(__file__).resolve().parents[3]
STEP23 = "flow.step.response_time[sensor=sliding,target_gps=23]"


@pytest.fixture
def files(tmp_path):
    """Paths of a passing record, a slower (regressed but passing) one, and a baseline path."""
    slower = good()
    slower[0] = step_time(1.45)                                  # limit 1.5; baseline 1.10
    return {"good": write(tmp_path / "good.json", record(good())),
            "slower": write(tmp_path / "slower.json", record(slower, run_id="slow00000000")),
            "baseline": tmp_path / "baselines" / f"{DUT}.json",
            "tol": ROOT / "ci" / "tolerances.toml", "dir": tmp_path}


def _gate(*args: object) -> int:
    return main(["gate", *map(str, args)])


def _stored(files) -> None:
    assert _gate(files["good"], "--baseline", files["baseline"], "--update-baseline") == 0


def test_a_passing_record_without_baseline_exits_0(files, capsys) -> None:
    assert _gate(files["good"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"hil gate: PASS: {DUT} 1.0.0 (build b-0001), run 3f2a9c1b7d10"
    assert out[1] == "  6 measurements: 5 pass, 1 info"
    assert "no baseline: limits only" in out[2]


def test_a_value_outside_limits_exits_1(files, capsys) -> None:
    bad = good()
    bad[0] = step_time(1.7)
    assert _gate(write(files["dir"] / "bad.json", record(bad))) == 1
    out = capsys.readouterr().out
    assert out.startswith("hil gate: FAIL:")
    assert f"  FAIL  {STEP23}: 1.7 s (limits <= 1.5)" in out
    assert "  why: 1 measurement outside limits" in out


def test_update_baseline_round_trip_and_regression(files, capsys) -> None:
    _stored(files)
    assert json.loads(files["baseline"].read_text())["source"]["run_id"] == "3f2a9c1b7d10"
    capsys.readouterr()
    # the same record against its own baseline passes
    assert _gate(files["good"], "--baseline", files["baseline"], "--tolerance", files["tol"]) == 0
    # 1.10 s -> 1.45 s is within the 1.5 s limit but beyond the 0.2 s band: a regression
    assert _gate(files["slower"], "--baseline", files["baseline"], "--tolerance",
                 files["tol"]) == 1
    out = capsys.readouterr().out
    assert (f"  regression  {STEP23}: 1.45 s, baseline 1.1 s (+0.35 s, band 0.2 s)") in out
    assert "  why: 1 regression beyond tolerance" in out
    assert _gate(files["slower"], "--baseline", files["baseline"], "--tolerance", files["tol"],
                 "--allow-regressions") == 0
    assert "warning: 1 regression beyond tolerance (allowed: --allow-regressions)" in (
        capsys.readouterr().out)
    # accepting the slower build deliberately: the new baseline holds 1.45 s, and it passes
    assert _gate(files["slower"], "--baseline", files["baseline"], "--update-baseline") == 0
    stored = json.loads(files["baseline"].read_text())
    assert stored["source"]["run_id"] == "slow00000000"
    assert stored["measurements"][STEP23]["value"] == 1.45
    assert _gate(files["slower"], "--baseline", files["baseline"]) == 0


def test_update_baseline_refuses_a_failing_record_unless_forced(files, capsys) -> None:
    _stored(files)
    before = files["baseline"].read_text()
    bad = good()
    bad[0] = step_time(1.7)
    bad_path = write(files["dir"] / "bad.json", record(bad, run_id="bad000000000"))
    assert _gate(bad_path, "--baseline", files["baseline"], "--update-baseline") == 1
    assert "baseline not written: the record did not pass" in capsys.readouterr().err
    assert files["baseline"].read_text() == before
    assert _gate(bad_path, "--baseline", files["baseline"], "--update-baseline", "--force") == 1
    assert json.loads(files["baseline"].read_text())["source"]["run_id"] == "bad000000000"


def test_a_missing_measurement_exits_1(files, capsys) -> None:
    _stored(files)
    fewer = [m for m in good() if m.name != "flow.bench.accuracy"]
    path = write(files["dir"] / "fewer.json", record(fewer))
    assert _gate(path, "--baseline", files["baseline"]) == 1
    out = capsys.readouterr().out
    assert "  missing  flow.bench.accuracy[target_g=1700]: not in the record, baseline 97 %" in out


@pytest.mark.parametrize(("verdict", "label"), [
    ("invalid-bench", "INVALID BENCH (no verdict on the DUT)"),
    ("error", "ERROR (the qualification did not run)")])
def test_invalid_bench_and_error_exit_2_never_1(files, capsys, verdict, label) -> None:
    bad = good()
    bad[0] = step_time(1.7)                                    # a failing value, even so
    path = write(files["dir"] / "r.json", record(bad, verdict=verdict))
    summary = files["dir"] / "summary.md"
    assert _gate(path, "--summary", summary) == 2
    assert capsys.readouterr().out.startswith(f"hil gate: {label}: {DUT}")
    assert summary.read_text().splitlines()[0] == f"### ⚠️ agrihil gate: {label} — {DUT} 1.0.0 " \
                                                   f"(build b-0001)"
    _stored(files)
    assert _gate(path, "--baseline", files["baseline"], "--update-baseline") == 2


def test_a_baseline_of_another_dut_exits_2_unless_forced(files, capsys) -> None:
    other = write(files["dir"] / "other.json", record(good(), dut="fertilizer-open-loop-daemon"))
    assert _gate(other, "--baseline", files["baseline"], "--update-baseline") == 0
    capsys.readouterr()
    assert _gate(files["good"], "--baseline", files["baseline"]) == 2
    err = capsys.readouterr().err
    assert err == (f"hil: error: {files['baseline']}: [dut.name] baseline is of DUT "
                   f"'fertilizer-open-loop-daemon', the record of '{DUT}'; compare them anyway "
                   f"with --force\n")
    assert _gate(files["good"], "--baseline", files["baseline"], "--force") == 0
    # and it is not overwritten by another DUT's record by accident either
    assert _gate(files["good"], "--baseline", files["baseline"], "--update-baseline") == 2


@pytest.mark.parametrize(("content", "message"), [
    ("{not json", "not valid JSON"),
    ('{"schema": "agrihil.baseline/1"}', "[schema] expected 'agrihil.qualification/1'")])
def test_a_bad_record_exits_2_with_one_line(files, capsys, content, message) -> None:
    path = files["dir"] / "r.json"
    path.write_text(content)
    assert _gate(path) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hil: error: {path}: ") and message in err and err.count("\n") == 1


def test_bad_options_and_tolerance_files_exit_2(files, capsys) -> None:
    assert _gate(files["good"], "--update-baseline") == 2
    assert "--update-baseline needs --baseline PATH" in capsys.readouterr().err
    tol = files["dir"] / "tol.toml"
    tol.write_text('[measurements]\n"flow.step.*" = { abs = -1 }\n')
    assert _gate(files["good"], "--tolerance", tol) == 2
    assert (f'{tol}: [measurements."flow.step.*"] abs must be a finite number >= 0'
            in capsys.readouterr().err)
    assert _gate(files["good"], "--baseline", files["dir"] / "none.json") == 2
    assert "baseline not found" in capsys.readouterr().err


def test_the_markdown_summary_has_the_verdict_first_then_the_table(files) -> None:
    _stored(files)
    summary = files["dir"] / "summary.md"
    assert _gate(files["slower"], "--baseline", files["baseline"], "--tolerance", files["tol"],
                 "--summary", summary) == 1
    lines = summary.read_text(encoding="utf-8").splitlines()
    assert lines[0] == f"### ❌ agrihil gate: FAIL — {DUT} 1.0.0 (build b-0001)"
    assert "- 1 regression beyond tolerance" in lines
    header = lines.index("| measurement | conditions | value | limits | baseline | delta "
                         "| status |")
    assert lines[header + 2] == ("| `flow.step.response_time` | sensor=sliding, target_gps=23 | "
                                 "1.45 s | ≤ 1.5 | 1.1 s | +0.35 s (band 0.2 s) | **regression** |")
    assert ("| `flow.bench.accuracy` | target_g=1700 | 97 % | ≥ 90 | 97 % | +0 % | pass |"
            in lines)
    assert "| `depth.field.mean` | speed_band=3-5 | 30.2 mm | 20 to 40 | 30.2 mm | +0 mm | pass |" \
        in lines


def test_the_summary_is_appended_to_the_github_step_summary(files, monkeypatch) -> None:
    page = files["dir"] / "step_summary.md"
    page.write_text("## earlier step\n", encoding="utf-8")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(page))
    assert _gate(files["good"]) == 0
    text = page.read_text(encoding="utf-8")
    assert text.startswith("## earlier step\n### ✅ agrihil gate: PASS")
    # an explicit --summary goes there instead
    own = files["dir"] / "own.md"
    assert _gate(files["good"], "--summary", own) == 0
    assert page.read_text(encoding="utf-8") == text and own.exists()


def test_python_dash_m_hil_gate_in_a_subprocess(files) -> None:
    _stored(files)
    env = {k: v for k, v in os.environ.items() if k != "GITHUB_STEP_SUMMARY"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))

    def run(*args: object) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "hil", "gate", *map(str, args)], cwd=ROOT,
                              env=env, capture_output=True, text=True, timeout=60)

    ok = run(files["good"], "--baseline", files["baseline"], "--tolerance", files["tol"])
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.startswith(f"hil gate: PASS: {DUT}")
    slow = run(files["slower"], "--baseline", files["baseline"], "--tolerance", files["tol"])
    assert slow.returncode == 1 and "regression" in slow.stdout
    broken = run(files["dir"] / "nothing.json")
    assert broken.returncode == 2
    assert broken.stderr.strip() == (f"hil: error: {files['dir'] / 'nothing.json'}: "
                                     f"qualification record not found")
