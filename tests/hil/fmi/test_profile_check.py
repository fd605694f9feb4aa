"""``kind = "fmu"`` profiles: what ``hil profile check`` and every run refuse, by name."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from hil.dut.fmu import check_fmu, fmu_problems
from hil.dut.profile import load_profile
from hil.errors import ConfigError

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-fmu-lsbus.toml"
MEMBER = ('      <TerminalMemberVariable variableKind="signal" '
          'variableName="CanChannel.{m}" memberName="{m}"/>\n')
TERMINAL = ('<Terminal terminalKind="org.fmi-ls-bus.network-terminal" '
            'matchingRule="org.fmi-ls-bus.transceiver" name="{name}">\n'
            + "".join(MEMBER.replace("{m}", m)
                      for m in ("Rx_Clock", "Rx_Data", "Tx_Clock", "Tx_Data"))
            + "    </Terminal>\n")


def profile_for(tmp_path: Path, fmu: Path, *, fmu_table: str = "", parameters: str = "",
                name: str = "probe-fmu") -> Path:
    """The shipped LS-BUS profile, pointed at ``fmu`` (no [build]), with extra lines."""
    text = SHIPPED.read_text(encoding="utf-8")
    head, _, rest = text.partition("[build]")
    _, _, rest = rest.partition("[fmu]")
    fmu_lines = f'[fmu]\npath = "{fmu}"\nlevel = "bus"\n{fmu_table}\n'
    _, _, rest = rest.partition("[wiring]")
    rest = "[wiring]" + rest
    rest = rest.replace('mode = "physical"\n', "").replace("ff_coeff = 4.390\n", parameters)
    body = head.replace('name = "fertilizer-piecewise-pid-fmu-lsbus"', f'name = "{name}"')
    body = body.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/')
    rest = rest.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/')
    path = tmp_path / f"{name}.toml"
    path.write_text(body + fmu_lines + rest, encoding="utf-8")
    return path


def rezip(src: Path, dst: Path, *, replace: dict[str, bytes | None]) -> Path:
    """A copy of the FMU ``src`` with members replaced (None: removed)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            if item.filename in replace:
                data = replace[item.filename]
                if data is not None:
                    zout.writestr(item.filename, data)
            else:
                zout.writestr(item, zin.read(item.filename))
    return dst


def test_the_shipped_profile_loads_and_a_good_fmu_passes(fmus: Path, tmp_path: Path) -> None:
    assert load_profile(SHIPPED).fmu is not None
    profile = load_profile(profile_for(tmp_path, fmus / "agrihil-lsbus-probe.fmu",
                                       parameters="baudrate = 250000\n"))
    assert fmu_problems(profile) == []


def test_no_can_terminal_is_refused(fmus: Path, tmp_path: Path) -> None:
    fmu = rezip(fmus / "agrihil-lsbus-probe.fmu", tmp_path / "bare.fmu",
                replace={"terminalsAndIcons/terminalsAndIcons.xml": None})
    with pytest.raises(ConfigError, match=r"\[fmu.path\] the FMU declares no CAN terminal"):
        check_fmu(load_profile(profile_for(tmp_path, fmu)))


def test_more_terminals_than_the_profile_binds_are_refused_naming_them(
        fmus: Path, tmp_path: Path) -> None:
    src = fmus / "agrihil-lsbus-probe.fmu"
    with zipfile.ZipFile(src) as z:
        xml = z.read("terminalsAndIcons/terminalsAndIcons.xml").decode()
    two = xml.replace("</Terminals>", TERMINAL.format(name="SecondCan") + "  </Terminals>")
    fmu = rezip(src, tmp_path / "two.fmu",
                replace={"terminalsAndIcons/terminalsAndIcons.xml": two.encode()})
    profile = profile_for(tmp_path, fmu, fmu_table='terminal = "CanChannel"')
    with pytest.raises(ConfigError, match=r"\[fmu.terminal\] the FMU declares 2 terminals and "
                                          r"the profile binds one \(CanChannel\): SecondCan"):
        check_fmu(load_profile(profile))


def test_a_terminal_the_fmu_lacks_and_an_unknown_parameter_are_each_named(
        fmus: Path, tmp_path: Path) -> None:
    path = profile_for(tmp_path, fmus / "agrihil-lsbus-probe.fmu",
                       fmu_table='terminal = "Can2"', parameters="gain = 2.0\n")
    with pytest.raises(ConfigError) as info:
        check_fmu(load_profile(path))
    assert "no CAN terminal 'Can2' (its CAN terminals: CanChannel)" in str(info.value)
    assert "more problem" in str(info.value)


def test_fmpy_validation_problems_are_refused(fmus: Path, tmp_path: Path) -> None:
    src = fmus / "agrihil-lsbus-probe.fmu"
    with zipfile.ZipFile(src) as z:
        md = z.read("modelDescription.xml").decode()
    broken = md.replace('    <InitialUnknown valueReference="3"/>\n', "")
    assert broken != md
    fmu = rezip(src, tmp_path / "broken.fmu", replace={"modelDescription.xml": broken.encode()})
    with pytest.raises(ConfigError, match="fmpy's validation: ModelStructure/InitialUnknowns"):
        check_fmu(load_profile(profile_for(tmp_path, fmu)))


def test_hil_run_exits_2_naming_the_problem(fmus: Path, tmp_path: Path) -> None:
    fmu = rezip(fmus / "agrihil-lsbus-probe.fmu", tmp_path / "bare.fmu",
                replace={"terminalsAndIcons/terminalsAndIcons.xml": None})
    done = subprocess.run([sys.executable, "-m", "hil", "run", "--dut",
                           str(profile_for(tmp_path, fmu)), "--scenario", "bench-step-23",
                           "--bus", "inline", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "no CAN terminal" in done.stderr and "Traceback" not in done.stderr


def test_hil_profile_check_exits_2_naming_the_problem(fmus: Path, tmp_path: Path) -> None:
    src = fmus / "agrihil-lsbus-probe.fmu"
    with zipfile.ZipFile(src) as z:
        xml = z.read("terminalsAndIcons/terminalsAndIcons.xml").decode()
    two = xml.replace("</Terminals>", TERMINAL.format(name="SecondCan") + "  </Terminals>")
    fmu = rezip(src, tmp_path / "two.fmu",
                replace={"terminalsAndIcons/terminalsAndIcons.xml": two.encode()})
    done = subprocess.run([sys.executable, "-m", "hil", "profile", "check", "-q",
                           str(profile_for(tmp_path, fmu))], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "[fmu.terminal]" in done.stderr and "SecondCan" in done.stderr
    assert "Traceback" not in done.stderr
