"""Rig config: packaged file, units in key names, errors that name the file and the key."""

from __future__ import annotations

import dataclasses
import re
import typing
from pathlib import Path

import pytest

from hil.errors import ConfigError
from plant_emulators.sowing_depth.config import (
    SowingDepthRigConfig,
    default_rig_path,
    load_rig_config,
)

#: A key ends in one of these unit suffixes ...
UNIT_SUFFIX = re.compile(
    r"_(mm|m|n|n_m|ohm|v|a|kg|kg_cm2|ms|hz|deg|percent|rpm|mv|mm_per_s|mm_per_s2|m_per_s|"
    r"per_s|per_m|n_per_mm|n_s_per_mm|n_per_cm2|per_percent|per_n_per_cm2|per_m_per_s|"
    r"deg_per_m_per_s|vrms_per_krpm|bit_per_s|relative)$")
#: ... or is one of these dimensionless or non-numeric keys.
DIMENSIONLESS = {
    "rows", "belt_ratio", "reducer_ratio", "transmission_efficiency", "efficiency_max",
    "low_speed_loss", "noise_low_speed_gain", "clod_speed_weight", "bounce_speed_exponent",
    "shallow_depth_factor_min", "shallow_depth_factor_max", "overload_reset_fraction",
    "quick_stop_option_code", "fault_reaction_option_code", "noisy_fault_gain", "talker_id",
    "start_utc", "satellites_used", "hdop", "drive_node_id", "tractor_source_address",
    "draw_wire_source_address", "inclinometer_source_address", "terminal_source_address",
    "controller_source_address", "ground_speed_frame_id", "draw_wire_frame_id",
    "inclinometer_frame_id", "depth_setpoint_frame_id", "controller_status_frame_id",
}


def leaf_keys(cls: type, prefix: str = "") -> list[str]:
    keys = []
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        sub = hints[field.name]
        if isinstance(sub, type) and dataclasses.is_dataclass(sub):
            keys += leaf_keys(sub, f"{prefix}{field.name}.")
        else:
            keys.append(f"{prefix}{field.name}")
    return keys


def test_packaged_config_loads() -> None:
    cfg = load_rig_config()
    assert isinstance(cfg, SowingDepthRigConfig)
    assert cfg.cylinder.rod_speed_max_mm_per_s == 50.0
    assert cfg.cylinder.push_force_max_n == 9806.65
    assert cfg.arm.arm_length_mm == 320.0 and cfg.arm.roller_radius_mm == 140.0
    assert cfg.machine.rows == 12
    assert load_rig_config(default_rig_path()) == cfg


def test_every_key_names_its_unit() -> None:
    keys = leaf_keys(SowingDepthRigConfig)
    assert len(keys) > 140
    for key in keys:
        name = key.split(".")[-1]
        assert UNIT_SUFFIX.search(name) or name in DIMENSIONLESS, key


def test_every_key_in_the_toml_has_a_source_comment() -> None:
    for line in default_rig_path().read_text().splitlines():
        if "=" in line and not line.lstrip().startswith("#"):
            assert "#" in line, f"no source comment: {line!r}"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return path


def test_unknown_key_is_rejected_naming_file_and_key(tmp_path: Path) -> None:
    text = default_rig_path().read_text().replace(
        "ra_ohm = 0.39", "ra_ohm = 0.39\nra_ohms = 0.4")
    with pytest.raises(ConfigError) as info:
        load_rig_config(write(tmp_path, text))
    assert str(tmp_path / "rig.toml") in str(info.value)
    assert "[motor.ra_ohms]" in str(info.value)


def test_out_of_range_value_is_rejected_naming_the_section(tmp_path: Path) -> None:
    text = default_rig_path().read_text().replace(
        "software_position_limit_max_mm = 99.0", "software_position_limit_max_mm = 120.0")
    with pytest.raises(ConfigError, match="software_position_limit_max_mm exceeds"):
        load_rig_config(write(tmp_path, text))
    text = default_rig_path().read_text().replace("stroke_mm = 100.0", "stroke_mm = -1.0")
    with pytest.raises(ConfigError, match=r"\[cylinder\] stroke_mm must be > 0"):
        load_rig_config(write(tmp_path, text))


def test_wrong_type_and_missing_file(tmp_path: Path) -> None:
    text = default_rig_path().read_text().replace("rows = 12", 'rows = "twelve"')
    with pytest.raises(ConfigError, match=r"\[machine.rows\] expected an integer"):
        load_rig_config(write(tmp_path, text))
    with pytest.raises(ConfigError, match="file not found"):
        load_rig_config(tmp_path / "absent.toml")


def test_motor_constants_are_stated_in_si() -> None:
    motor = load_rig_config().motor
    assert motor.ke_v_s_per_rad == pytest.approx(6.1 / (1000 * 2 * 3.141592653589793 / 60))
    assert motor.kt_n_m_per_a == motor.ke_v_s_per_rad
    assert motor.ja_kg_m2 == pytest.approx(2.78e-4)


def test_every_key_is_documented_in_the_model_page() -> None:
    """Every parameter is in the rig's page of the documentation site (docs/models/)."""
    readme = (Path(__file__).resolve().parents[3] / "docs/models/sowing-depth.md").read_text()
    for key in leaf_keys(SowingDepthRigConfig):
        section, name = key.split(".")
        assert f"**[{section}]**" in readme, section
        assert f"| `{name}` |" in readme, key
