"""The scripted operator: keys and buttons (pressed, held, released), input, alarms, scripts."""

from __future__ import annotations

import pytest

from hil.errors import ConfigError
from hil.isobus.vt.bench import VtBench
from hil.isobus.vt.client import KeyEvent
from hil.isobus.vt.messages import KeyActivation
from hil.isobus.vt.operator import Operator, OperatorStep, check_steps
from hil.isobus.vt.testing import VtOperatorDriver

from .pools import IDS, implement_pool


class Implement:
    """What the test implement does with its operator's input: Settings opens the settings
    mask, Ack closes the alarm, Master toggles metering."""

    def __init__(self, bench: VtBench) -> None:
        assert bench.client is not None
        self.client = bench.client
        self.metering = False
        bench.client.on_key = self.on_key

    def on_key(self, event: KeyEvent) -> None:
        if event.activation != KeyActivation.RELEASED:
            return
        if event.object_id == IDS.key_settings:
            self.client.change_active_mask(IDS.ws, IDS.settings)
        elif event.object_id == IDS.key_ack:
            self.client.change_active_mask(IDS.ws, IDS.home)
        elif event.object_id == IDS.key_master:
            self.metering = not self.metering

    def alarm(self) -> None:
        self.client.change_active_mask(IDS.ws, IDS.alarm)


def connected(script: list[OperatorStep] = ()) -> tuple[VtBench, Implement, Operator]:  # type: ignore[assignment]
    bench = VtBench([implement_pool().to_bytes()])
    implement = Implement(bench)
    bench.run_until(3.0)
    operator = Operator(bench.vt)
    operator.schedule(script)
    return bench, implement, operator


@pytest.fixture
def vt_bench() -> VtBench:
    bench, _implement, _ = connected()
    return bench


def test_a_held_soft_key_by_label() -> None:
    bench, implement, _ = connected([OperatorStep(at_s=4.0, press="Master", hold_s=1.0)])
    bench.run_until(6.0)
    keys = implement.client.keys
    assert [k.activation for k in keys] == [KeyActivation.PRESSED] + \
        [KeyActivation.STILL_HELD] * 4 + [KeyActivation.RELEASED]
    assert [round(k.time_s, 3) for k in keys] == [4.0, 4.2, 4.4, 4.6, 4.8, 5.0]
    assert {(k.object_id, k.parent_id, k.key_code, k.button) for k in keys} == {
        (IDS.key_master, IDS.keys, 1, False)}
    assert implement.metering
    # the implement's activation responses are taken as responses: not refused, not NACKed
    assert [r[2][:2] for r in bench.vt.responses] == [bytes([0x00, a]) for a in
                                                     (1, 2, 2, 2, 2, 0)]
    assert not [c for c in bench.vt.commands if c.error == 0xFF]
    assert not [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00
                == 0xE800]


def test_a_button_by_id_reports_its_mask() -> None:
    bench, implement, _ = connected([OperatorStep(at_s=4.0, press=IDS.button)])
    bench.run_until(5.0)
    keys = implement.client.keys
    assert [(k.activation, k.object_id, k.parent_id, k.key_code, k.button) for k in keys] == [
        (KeyActivation.PRESSED, IDS.button, IDS.home, 9, True),
        (KeyActivation.RELEASED, IDS.button, IDS.home, 9, True)]


def test_numeric_and_string_input_in_shown_units() -> None:
    bench, implement, operator = connected([
        OperatorStep(at_s=4.0, press="Settings"),
        OperatorStep(at_s=5.0, enter=IDS.cal_in, value=15.5),
        OperatorStep(at_s=5.5, type=IDS.name_in, text="North"),
        OperatorStep(at_s=6.0, enter=IDS.cal_in, value=500.0)])   # above its 100.0 maximum
    bench.run_until(7.0)
    assert implement.client.numbers == [(5.0, IDS.cal_in, 155)]
    assert implement.client.strings == [(5.5, IDS.name_in, "North")]
    ws = bench.vt.sessions[implement.client.port.address]  # type: ignore[index]
    assert ws.obj(IDS.cal_var)["value"] == 155                 # type: ignore[index]
    assert len(operator.missed) == 1 and "outside 10 .. 1000" in operator.missed[0][1]


def test_a_key_not_on_the_screen_is_not_pressed() -> None:
    bench, implement, operator = connected([OperatorStep(at_s=4.0, press="Ack")])
    bench.run_until(5.0)
    assert implement.client.keys == []
    assert "is not on the screen" in operator.missed[0][1]
    assert bench.vt.events[-1].kind == "operator"


def test_alarm_acknowledged_with_its_soft_key(vt_operator: VtOperatorDriver,
                                              vt_bench: VtBench) -> None:
    assert vt_bench.client is not None
    vt_bench.client.change_active_mask(IDS.ws, IDS.alarm)
    vt_operator.wait_for_mask(IDS.alarm, timeout_s=1.0)
    assert vt_operator.value(IDS.rate_out) == 25.0
    vt_bench.client.on_key = lambda e: (e.activation == KeyActivation.RELEASED and
                                        vt_bench.client.change_active_mask(  # type: ignore[union-attr]
                                            IDS.ws, IDS.home))
    vt_operator.acknowledge()
    vt_operator.wait_for_mask(IDS.home, timeout_s=1.0)
    with pytest.raises(AssertionError, match=r"not shown within 0\.5 s"):
        vt_operator.wait_for_mask(IDS.settings, timeout_s=0.5)


def test_fixture_press_by_label_and_read_values(vt_operator: VtOperatorDriver,
                                                vt_bench: VtBench) -> None:
    assert vt_bench.client is not None
    vt_bench.client.on_key = lambda e: (e.activation == KeyActivation.RELEASED and
                                        vt_bench.client.change_active_mask(  # type: ignore[union-attr]
                                            IDS.ws, IDS.settings))
    vt_operator.press("Settings")
    vt_operator.wait_for_mask(IDS.settings, timeout_s=1.0)
    vt_operator.enter(IDS.cal_in, 20.0)
    assert vt_operator.value(IDS.cal_in) == 20.0
    vt_operator.type(IDS.name_in, "Rye")
    assert vt_operator.value(IDS.name_in) == "Rye"
    with pytest.raises(LookupError, match="no key/button labelled 'Start metering'"):
        vt_operator.press("Start metering")


def test_a_script_naming_what_the_pool_lacks_is_a_setup_error() -> None:
    pool = implement_pool()
    good = [OperatorStep(at_s=1, press="Master"), OperatorStep(at_s=2, enter=IDS.cal_in,
                                                                value=1.0)]
    check_steps(good, pool)
    with pytest.raises(ConfigError, match=r"s.toml: \[operator\[1\]\] press 'Stop'.*no "
                                          r"key/button labelled 'Stop'.*'Master'"):
        check_steps([good[0], OperatorStep(at_s=3, press="Stop")], pool, path="s.toml")
    with pytest.raises(ConfigError, match="the pool has no object 9999"):
        check_steps([OperatorStep(at_s=3, enter=9999, value=1.0)], pool)
    with pytest.raises(ConfigError, match="is a output_number, not a input_number"):
        check_steps([OperatorStep(at_s=3, enter=IDS.rate_out, value=1.0)], pool)
    with pytest.raises(ConfigError, match="exactly one of"):
        OperatorStep(at_s=1, press="Master", escape=True)


def test_two_lockstep_runs_give_identical_bus_logs() -> None:
    script = [OperatorStep(at_s=4.0, press="Master", hold_s=0.7),
              OperatorStep(at_s=5.0, press="Settings"),
              OperatorStep(at_s=6.0, enter=IDS.cal_in, value=42.0)]

    def run() -> list[tuple[float, int, bytes]]:
        bench, _, _ = connected(script)
        bench.run_until(8.0)
        return [(f.time_s, f.frame.arbitration_id, bytes(f.frame.data))
                for f in bench.wire.frames]

    first, second = run(), run()
    assert len(first) > 100 and first == second


def test_operator_list_of_a_scenario_file(tmp_path: pytest.TempPathFactory) -> None:
    from hil.isobus.vt.operator import read_operator_steps
    path = tmp_path / "s.toml"                  # type: ignore[operator]
    path.write_text('name = "x"\n[[operator]]\nat_s = 12.0\nenter = 5002\nvalue = 12.5\n'
                    '[[operator]]\nat_s = 2.0\npress = "Master"\nhold_s = 1.5\n'
                    '[[operator]]\nat_s = 20.0\nacknowledge = true\n')
    steps = read_operator_steps(path)
    assert [s.what for s in steps] == ["press 'Master' for 1.5 s", "enter 12.5 into 5002",
                                       "acknowledge the alarm"]
    path.write_text('[[operator]]\nat_s = 2.0\npress = "Master"\nhold = 1.5\n')
    with pytest.raises(ConfigError, match=r"s\.toml: \[operator\[0\]\.hold\] unknown key"):
        read_operator_steps(path)
    path.write_text('[[operator]]\nat_s = 2.0\n')
    with pytest.raises(ConfigError, match=r"\[operator\[0\]\] an operator step needs exactly"):
        read_operator_steps(path)
