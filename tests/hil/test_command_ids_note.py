"""``hil profile check``'s note on ``wiring.command_ids`` says what is true (issue 43).

On the depth rig the drive's EDS maps a target into RPDO1 (0x202) and RPDO2 (0x302); the rig
waits for both by default. A profile listing ``[0x302]`` names one of those defaults: a
controller commanding target velocity on the drive's default RPDO2 configures nothing, so the
note must not say that the DUT must remap. An id outside the defaults does need the DUT to
configure an RPDO there, and the note says so.
"""

from __future__ import annotations

from pathlib import Path

from hil.cli.profile import profile_problems
from hil.dut.profile import load_profile

ROOT = Path(__file__).resolve().parents[2]
DP200 = ROOT / "docs" / "examples" / "byo-depth" / "depthpro-dp200-daemon.toml"


def _note(tmp_path: Path, ids: str) -> str:
    text = DP200.read_text(encoding="utf-8")
    assert "command_ids = [0x302]" in text
    path = tmp_path / DP200.name
    path.write_text(text.replace("command_ids = [0x302]", f"command_ids = [{ids}]"),
                    encoding="utf-8")
    for name in ("depthpro_dp200.dbc", "depthpro_dp200.binding.toml"):
        if (DP200.parent / name).exists():
            (tmp_path / name).write_bytes((DP200.parent / name).read_bytes())
    notes = [p for p in profile_problems(load_profile(path))
             if p.key == "wiring.command_ids"]
    assert len(notes) == 1 and notes[0].note, notes
    return notes[0].message


def test_a_default_id_needs_no_remapping(tmp_path: Path) -> None:
    note = _note(tmp_path, "0x302")
    assert "must configure" not in note
    assert "one of the frames the rig waits for by default ([0x202, 0x302]" in note


def test_an_id_outside_the_defaults_needs_the_dut_to_configure_it(tmp_path: Path) -> None:
    note = _note(tmp_path, "0x303")
    assert "must configure the RPDOs" in note and "0x303" in note
