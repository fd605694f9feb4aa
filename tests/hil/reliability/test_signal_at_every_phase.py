"""A SIGINT at every phase boundary of ``hil qualify`` (issue 30): injected deterministically
through ``HIL_TEST_SIGNAL_AT`` (:mod:`hil.cli.phases`), not by timing luck. Whatever the
phase, the signal is not lost (exit 130), no record says ``pass`` unless every selected test
ran, nothing staged is left behind and the previous record is kept."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.fuzz.cli import run_cli
from tests.helpers.hil_forkserver import Done, HilForkServer

ROOT = Path(__file__).resolve().parents[3]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
#: two short tests on the inline bus: the second one's start is a boundary between scenarios
SELECTION = "test_flow_step and (23 or 34)"
PREVIOUS = {"schema": "agrihil.qualification/1", "run_id": "old", "verdict": "pass",
            "dut": {"name": "fertilizer-piecewise-pid-daemon"}, "measurements": []}
#: every boundary, in order: before --out is touched, then inside the qualification
BEFORE_OUT = ("qualify:built",)
PHASES = ("qualify:built", "qualify:staged", "qualify:suites", "qualify:test@1",
          "qualify:test@2", "qualify:record", "qualify:promote")


def _qualify(hil: HilForkServer, out: Path, env: dict[str, str]) -> Done:
    """``hil qualify`` with ``env`` in a process of its own (forked by the ``hil_forked``
    server: the signal is its own, as in a new interpreter, without the start-up)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "record.json").write_text(json.dumps(PREVIOUS))
    return hil.run(["qualify", str(PROFILE), "--bus", "inline", "--quiet", "--out", str(out),
                    "-k", SELECTION], ROOT, timeout_s=300, env=env)


def _assert_not_lost(done: Done, out: Path) -> dict:
    output = done.stdout + done.stderr
    assert done.returncode == 130, output[-3000:]
    assert "Traceback" not in output, output[-3000:]
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    record = json.loads((out / "record.json").read_text())
    if record["run_id"] != "old":
        assert json.loads((out / "record.previous.json").read_text()) == PREVIOUS
        if record["verdict"] == "pass":            # only a record of every selected test
            assert record.get("complete", True) is True
            assert len(record["tests"]) == 2, record["tests"]
    return record


@pytest.mark.parametrize("at", PHASES)
def test_a_sigint_at_each_phase_is_never_lost(tmp_path: Path, at: str,
                                              hil_forked: HilForkServer) -> None:
    out = tmp_path / "q"
    done = _qualify(hil_forked, out, {"HIL_TEST_SIGNAL_AT": at})
    record = _assert_not_lost(done, out)
    if at in BEFORE_OUT:
        assert record == PREVIOUS                 # --out untouched
    elif at == "qualify:promote":
        # held while the outputs moved in, delivered right after: the record is complete
        assert record["verdict"] == "pass" and len(record["tests"]) == 2
    else:
        assert record["verdict"] == "interrupted", record["verdict"]
        gate = run_cli("gate", str(out / "record.json"))     # in this process
        assert gate.code == 2, gate.stdout + gate.stderr


def test_a_swallowed_keyboard_interrupt_still_ends_interrupted(
        tmp_path: Path, hil_forked: HilForkServer) -> None:
    out = tmp_path / "q"
    done = _qualify(hil_forked, out,
                    {"PYTEST_PLUGINS": "tests.hil.reliability.swallowing_plugin"})
    _assert_not_lost(done, out)
    assert "interrupted" in done.stderr
