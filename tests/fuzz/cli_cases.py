"""Bad command-line arguments for every ``hil`` subcommand, as Hypothesis strategies.

Each case is a full argv with exactly one bad option value (the rest valid and fast), so the
only right answer is a refusal before anything runs: exit 2, one line, no traceback.
"""

from __future__ import annotations

import math
from pathlib import Path

from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[2]
DAEMON = str(ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml")
RECORD = str(ROOT / "tests" / "fuzz" / "data" / "record.json")

negative_ints = st.integers(max_value=-1)
huge_ints = st.integers(min_value=2**64, max_value=2**80)
bad_seconds = st.sampled_from([-1.0, 0.0, math.nan, math.inf, -math.inf]) | st.floats(
    max_value=0.0, allow_nan=False)
bad_ports = st.integers(max_value=-1) | st.integers(min_value=65536, max_value=10**9)


def _run(*extra: str, out: str) -> list[str]:
    return ["run", "--dut", "builtin:pi", "--rig", "fertilizer", "--scenario",
            "bench-step-23", "--bus", "inline", "--out", out, *extra]


@st.composite
def bad_argv(draw: st.DrawFn, tmp: Path) -> tuple[str, list[str]]:
    """(what is bad, argv) for one subcommand; ``tmp`` is a fresh directory."""
    existing_file = tmp / "a-file"
    existing_file.write_text("x")
    out = str(tmp / "out")
    case = draw(st.sampled_from([
        "run-seed", "run-step-timeout", "run-out-file", "run-bus", "run-scenario",
        "run-clock-inline", "qualify-seed", "qualify-suite", "qualify-out-file",
        "serve-port", "serve-bitrate", "serve-busy-poll", "serve-log", "gate-summary-dir",
        "gate-record-dir", "profile-dir", "report-missing",
    ]))
    if case == "run-seed":
        seed = draw(negative_ints | huge_ints)
        return case, _run("--seed", str(seed), out=out)
    if case == "run-step-timeout":
        value = draw(bad_seconds)
        return case, _run("--step-timeout", repr(value), out=out)
    if case == "run-out-file":
        return case, _run(out=str(existing_file))
    if case == "run-bus":
        bus = draw(st.sampled_from(["socketcan:", "nosuchbus:x", ",", "socketcand:host",
                                    "virtual,=1", "socketcand:127.0.0.1:99999/can0"]))
        return case, ["run", "--dut", "builtin:pi", "--rig", "fertilizer", "--scenario",
                      "bench-step-23", "--bus", bus, "--out", out]
    if case == "run-scenario":
        name = draw(st.sampled_from(["nonsense", str(tmp / "missing.toml"), str(tmp)]))
        return case, ["run", "--dut", "builtin:pi", "--rig", "fertilizer", "--scenario", name,
                      "--bus", "inline", "--out", out]
    if case == "run-clock-inline":
        return case, _run("--clock", "realtime", out=out)
    if case == "qualify-seed":
        seed = draw(negative_ints | huge_ints)
        return case, ["qualify", DAEMON, "--bus", "inline", "--seed", str(seed), "--out", out]
    if case == "qualify-suite":
        suite = draw(st.sampled_from(["nonsense", "fast,nonsense", "", ","]))
        return case, ["qualify", DAEMON, "--bus", "inline", "--suite", suite, "--out", out]
    if case == "qualify-out-file":
        return case, ["qualify", DAEMON, "--bus", "inline", "--out", str(existing_file)]
    if case == "serve-port":
        return case, ["bus", "serve", "--port", str(draw(bad_ports))]
    if case == "serve-bitrate":
        rate = draw(st.sampled_from(["-5", "0", "nan", "inf", "-250000"]))
        return case, ["bus", "serve", "--port", "0", "--bitrate", rate]
    if case == "serve-busy-poll":
        return case, ["bus", "serve", "--port", "0", "--busy-poll-us",
                      str(draw(negative_ints))]
    if case == "serve-log":
        return case, ["bus", "serve", "--port", "0", "--log", str(tmp / "bus.xyz")]
    if case == "gate-summary-dir":
        return case, ["gate", RECORD, "--summary", str(tmp / "no" / "such" / "dir" / "s.md")]
    if case == "gate-record-dir":
        return case, ["gate", str(tmp)]
    if case == "profile-dir":
        return case, ["profile", "check", str(tmp)]
    return case, ["report", str(tmp / "missing")]
