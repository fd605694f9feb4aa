"""Hypothesis fuzzes bindings and databases: whatever the input, a named error or a result,
never a traceback (only :class:`hil.errors.HilError` escapes, naming a file or a key)."""

from __future__ import annotations

import contextlib
import tomllib
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hil.contract.binding import parse_binding
from hil.contract.checks import check_binding
from hil.contract.codec import ContractCodec
from hil.contract.quantity import Contract
from hil.errors import ConfigError, HilError
from tests.hil.contract.conftest import ACME_BINDING, ACME_DBC, DATA

NAMES = ["target_flow", "row_flow", "mode", "enable", "motor_command", "setpoint_counter",
         "row_baseline_ready", "nonsense", ""]
MESSAGES = ["AcmeSetpoint", "AcmeRowFlow", "ValveCmd", "GroundSpeed", "Nope", "Flow{row}", ""]
SIGNALS = ["FlowKgH", "Flow_R{row}", "Program", "Run", "Alive", "MotorMv", "RowIdx", "x", ""]
ANY = st.one_of(st.none(), st.booleans(), st.integers(-5, 70000), st.floats(allow_nan=True),
                st.text(max_size=8), st.lists(st.integers(-2, 6), max_size=5))

carrier = st.one_of(
    st.fixed_dictionaries(
        {"message": st.sampled_from(MESSAGES), "signal": st.sampled_from(SIGNALS)},
        optional={"unit": st.sampled_from(["g/s", "kg/h", "m", "furlong", "", "mV"]),
                  "values": st.dictionaries(st.sampled_from(["0", "1", "2", "x"]),
                                            st.one_of(st.integers(-3, 9), st.text(max_size=2)),
                                            max_size=3),
                  "multiplexer": st.sampled_from(["RowIdx", "Run", ""]),
                  "rows": st.lists(st.integers(-1, 6), max_size=5),
                  "cycle_ms": st.one_of(st.floats(-1, 200), st.integers(0, 70000)),
                  "junk": ANY}),
    st.fixed_dictionaries({"ddi": st.integers(-1, 70000)},
                          optional={"element": st.one_of(st.integers(-1, 5000),
                                                         st.lists(st.integers(0, 9),
                                                                  max_size=5))}),
    ANY)

bindings = st.fixed_dictionaries(
    {"rig": st.sampled_from(["fertilizer", "sowing_depth", "", 3]),
     "database": st.sampled_from([ACME_DBC.name, "missing.dbc", "", 7]),
     "quantities": st.dictionaries(st.sampled_from(NAMES), carrier, max_size=6)},
    optional={"dut_node": ANY, "extra": ANY})


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=bindings)
def test_any_binding_is_a_binding_or_a_named_error(fert: Contract, data: dict) -> None:
    try:
        binding = parse_binding(data, source="fuzz.toml", base=DATA)
    except ConfigError as exc:
        assert "fuzz.toml" in str(exc) and exc.key is not None
        return
    problems = check_binding(fert, binding)
    assert all(p.path and p.key and p.message for p in problems)
    try:
        codec = ContractCodec(fert, binding)
    except ConfigError as exc:
        assert exc.key
        return
    for values, row in (({"target_flow": 12.0, "mode": 1, "enable": 1}, None),
                        ({"row_flow": 3.0, "row_baseline_ready": 1}, 2)):
        with contextlib.suppress(HilError):       # a value the carrier refuses, by name
            codec.encode(values, row=row)


LINES = ACME_DBC.read_text().splitlines()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(drop=st.sets(st.integers(0, len(LINES) - 1), max_size=3),
       swap=st.dictionaries(st.integers(0, len(LINES) - 1),
                            st.sampled_from(["|", "@0-", "(0,0)", "[9|1]", " m9 ", " M ",
                                             "BO_ 544 X: 0 Y", "", "65", "\xff"]),
                            max_size=2))
def test_any_database_is_checked_or_refused_by_name(fert: Contract, tmp_path_factory,
                                                    drop: set, swap: dict) -> None:
    lines = [line for i, line in enumerate(LINES) if i not in drop]
    for i, text in swap.items():
        if i < len(lines):
            cut = len(lines[i]) // 2
            lines[i] = lines[i][:cut] + text + lines[i][cut:]
    folder = tmp_path_factory.mktemp("db")
    (folder / ACME_DBC.name).write_text("\n".join(lines) + "\n", encoding="utf-8",
                                        errors="surrogateescape")
    data = tomllib.loads(ACME_BINDING.read_text())
    binding = parse_binding(data, source=str(folder / "b.toml"), base=folder)
    problems = check_binding(fert, binding)
    assert all(isinstance(p.message, str) and p.key for p in problems)
    try:
        codec = ContractCodec(fert, binding)
        codec.encode({"target_flow": 12.0, "mode": 1, "enable": 1, "setpoint_counter": 3})
        codec.encode({"row_flow": 3.0}, row=4)
    except HilError as exc:
        assert str(exc)


def test_fuzz_inputs_exist() -> None:
    assert Path(ACME_DBC).is_file() and Path(ACME_BINDING).is_file()
