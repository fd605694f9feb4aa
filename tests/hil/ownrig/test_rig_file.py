"""A rig file is checked up front: every refusal names the file and the key."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.errors import ConfigError
from hil.ownrig.check import check_rig_file
from hil.ownrig.rig import rig_class

_names = itertools.count()


def variant(rig_file: Path, old: str, new: str) -> Path:
    """A copy of the rig file beside it with ``old`` replaced by ``new`` (once, checked)."""
    text = rig_file.read_text()
    assert old in text, old
    path = rig_file.with_name(f"variant-{next(_names)}.rig.toml")
    path.write_text(text.replace(old, new, 1))
    return path


BAD = [
    ("unknown top-level key", 'dut_node = "Controller"', 'dut_node = "Controller"\nspeed = 1',
     "[speed] unknown key"),
    ("missing FMU", 'path = "build/StateSpace.fmu"', 'path = "build/Missing.fmu"',
     "[fmu.path] FMU not found"),
    ("message not in the DBC", 'message = "MeterStatus"', 'message = "MeterState"',
     "[devices.meter.send[0].message] motor_meter.dbc has no message 'MeterState'"),
    ("signal not in the message", "signals.Flow = {", "signals.Flux = {",
     "[devices.meter.send[0].signals.Flux] MeterStatus has no signal 'Flux'"),
    ("FMU variable unknown", 'fmu = "y[2]"', 'fmu = "z[2]"',
     "[devices.meter.send[0].signals.Flow.fmu] StateSpace.fmu has no variable 'z'"),
    ("array element out of range", 'fmu = "y[2]"', 'fmu = "y[4]"',
     "[devices.meter.send[0].signals.Flow.fmu] y has 3 element(s)"),
    ("whole array", 'fmu = "y[2]"', 'fmu = "y"',
     "[devices.meter.send[0].signals.Flow.fmu] y is an array of 3"),
    ("command into an output", 'fmu = "u[1]", quantity = "drive_voltage"',
     'fmu = "y[1]", quantity = "drive_voltage"',
     "[devices.drive.receive[0].signals.Voltage.fmu] y is 'output'; this needs 'input'"),
    ("bad timeout behaviour", 'on_timeout = "zero"', 'on_timeout = "off"',
     "[devices.drive.receive[0].on_timeout] 'off' is not one of"),
    ("unit that does not convert", 'unit = "g/s", quantity = "meter_flow"',
     'unit = "m/s", quantity = "meter_flow"',
     "[devices.meter.send[0].signals.Flow.unit] 'm/s' does not convert to the DBC's 'g/s'"),
    ("wrong sender node", 'node = "Meter"', 'node = "Terminal"',
     "[devices.meter.send[0].message] MeterStatus is sent by Meter in the DBC, not by Terminal"),
    ("unknown parameter", "[fmu.parameters]\n", "[fmu.parameters]\nK = 1.0\n",
     "[fmu.parameters.K] StateSpace.fmu has no variable 'K'"),
    ("parameter of the wrong size", "u = [0.0, 0.0, 0.0]", "u = [0.0, 0.0]",
     "[fmu.parameters.u] u takes 3 value(s), got 2"),
    ("controlled truth not an output", 'truth = "y[1]"', 'truth = "x[1]"',
     "[controlled.speed.truth] x is 'local'; this needs 'output'"),
    ("controlled sensed unknown", 'sensed = "meter_speed"', 'sensed = "speed"',
     "[controlled.speed.sensed] no quantity 'speed' sent by a device"),
    ("controlled unit differs", 'unit = "rpm"\nband', 'unit = "rad/s"\nband',
     "[controlled.speed.unit] the sensed is in 'rpm'"),
    ("step of the FMU not dividing the SYNC", "step_ms = 1\n", "step_ms = 3\n",
     "[control_period_ms] must be a whole number of fmu.step_ms"),
    ("sensor model without a source", 'signals.Counter = { counter = true }',
     'signals.Counter = { gain = 2.0 }',
     "[devices.meter.send[0].signals.Counter] give exactly one source"),
]


@pytest.mark.parametrize(("what", "old", "new", "expected"), BAD, ids=[b[0] for b in BAD])
def test_bad_rig_file_is_refused_naming_the_key(motor_rig_file: Path, what: str, old: str,
                                                new: str, expected: str) -> None:
    path = variant(motor_rig_file, old, new)
    with pytest.raises(ConfigError) as info:
        rig_class(path)
    assert expected in str(info.value)
    assert path.name in str(info.value)


def test_no_command_message_is_refused(motor_rig_file: Path) -> None:
    path = variant(motor_rig_file, "timeout_ms = 300\n", "timeout_ms = 300\ncommand = false\n")
    with pytest.raises(ConfigError, match=r"\[devices\] no device receives a command"):
        rig_class(path)


def test_check_passes_the_example_and_says_what_it_plays(motor_rig_file: Path) -> None:
    lines = check_rig_file(motor_rig_file).lines
    text = "\n".join(lines)
    assert "FMI 3.0 co-simulation" in text and "fmpy validation: no problems" in text
    assert "meter sends MeterStatus (0x181) every 20 ms" in text
    assert "drive takes DriveCommand (0x220): Voltage -> u[1]" in text
    assert "scenarios: speed-step" in text


def test_cli_check_exit_codes(motor_rig_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["rig", "check", str(motor_rig_file)]) == 0
    assert "hil: rig file OK" in capsys.readouterr().out
    bad = variant(motor_rig_file, 'message = "Setpoint"', 'message = "SetPoint"')
    assert main(["rig", "check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "[devices.terminal.send[0].message]" in err and "Traceback" not in err


def test_a_finer_step_that_divides_the_periods_is_taken(motor_rig_file: Path) -> None:
    path = variant(motor_rig_file, "step_ms = 1\n", "step_ms = 0.5\n")
    assert "step 0.5 ms" in "\n".join(check_rig_file(path).lines)


def test_broken_fmu_is_refused_by_validation(motor_rig_file: Path, tmp_path: Path) -> None:
    import zipfile

    broken = motor_rig_file.parent / "build" / "Broken.fmu"
    with zipfile.ZipFile(motor_rig_file.parent / "build" / "StateSpace.fmu") as src, \
            zipfile.ZipFile(broken, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'valueReference="10"', b'valueReference="9"')
            dst.writestr(item, data)
    path = variant(motor_rig_file, 'path = "build/StateSpace.fmu"', 'path = "build/Broken.fmu"')
    with pytest.raises(ConfigError, match=r"\[fmu.path\]"):
        rig_class(path)
