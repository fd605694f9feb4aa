"""DUT profiles: valid ones load into frozen dataclasses; invalid ones name file and key."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.cli.main import main
from hil.dut.profile import load_profile
from hil.errors import ConfigError

from .conftest import profile_text


def test_valid_profile_loads(write_profile) -> None:
    path = write_profile()
    profile = load_profile(path)
    assert profile.name == "toy-good-daemon"
    assert profile.wiring.heartbeat_id == 0x710
    assert profile.limits["flow.step.overshoot"].high == 5.0
    assert len(profile.sha256) == 64
    with pytest.raises(AttributeError):
        profile.dut.name = "x"  # type: ignore[misc]


@pytest.mark.parametrize(("change", "key"), [
    (("kind = \"daemon\"", "kind = \"deamon\""), "dut.kind"),
    (("node_id = 0x10", "node_id = 200"), "wiring"),
    (("control_period_ms = 100", "control_period_ms = -1"), "timing"),
    (("control_period_ms = 100", "control_period_ms = \"fast\""), "timing.control_period_ms"),
    (("[timing]", "[timing]\nperiod = 3"), "timing.period"),
    (("\"flow.step.overshoot\"", "\"flow.step.overshot\""), "limits.flow.step.overshot"),
    (("high = 5.0", "low = 9.0, high = 5.0"), "limits.flow.step.overshoot"),
    (("rig = \"fertilizer\"", "rig = \"sprayer\""), "dut.rig"),
    (("ready = \"bootup\"", "ready = \"soon\""), "launch"),
    (("\"{python}\"", "\"{pyhton}\""), "launch"),
])
def test_invalid_profiles_name_the_key(write_profile, change: tuple[str, str], key: str) -> None:
    text = profile_text().replace(*change)
    assert text != profile_text()
    path = write_profile(text=text)
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert info.value.path == str(path)
    assert info.value.key is not None and info.value.key.startswith(key)


def test_name_must_match_file(write_profile) -> None:
    path = write_profile(name="other-name", text=profile_text("toy-good-daemon"))
    with pytest.raises(ConfigError, match="differs from the file name"):
        load_profile(path)


def test_daemon_without_command_and_firmware_without_build(write_profile) -> None:
    text = profile_text().replace('command = ["{python}"', 'lockstep_args = ["{python}"')
    with pytest.raises(ConfigError) as info:
        load_profile(write_profile(text=text))
    assert info.value.key == "launch.command"
    text = profile_text().replace('kind = "daemon"', 'kind = "firmware"')
    with pytest.raises(ConfigError) as info:
        load_profile(write_profile(text=text))
    assert info.value.key == "build"


def test_missing_and_broken_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_profile(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[dut\nname=")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_profile(bad)


def test_cli_profile_check(write_profile, capsys: pytest.CaptureFixture[str]) -> None:
    good = write_profile()
    assert main(["profile", "check", str(good)]) == 0
    assert "ok" in capsys.readouterr().out
    bad = write_profile(name="toy-bad-daemon",
                        text=profile_text("toy-bad-daemon").replace("node_id = 0x10", ""))
    assert main(["profile", "check", str(good), str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "[wiring.node_id] missing required key" in err


def test_invalid_profile_never_starts_a_run(write_profile, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    text = profile_text().replace("high = 5.0", "high = \"five\"")
    path = write_profile(text=text)
    out = tmp_path / "run"
    assert main(["run", "--dut", str(path), "--scenario", "bench-step-23", "--out",
                 str(out)]) == 2
    assert "limits.flow.step.overshoot" in capsys.readouterr().err
    assert not out.exists()
