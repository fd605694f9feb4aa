"""Rig configuration: loading, derived values, and errors that name the file and the key."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from hil.errors import ConfigError
from plant_emulators.fertilizer.config import DEFAULT_RIG_TOML, load_rig_config


def _write_variant(tmp_path: Path, old: str, new: str) -> Path:
    text = DEFAULT_RIG_TOML.read_text(encoding="utf-8")
    assert old in text, f"test setup: {old!r} not in rig.toml"
    path = tmp_path / "rig.toml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def test_packaged_config_loads_with_paper_values(rig_config):
    assert rig_config.drive.gear_ratio == 50.0
    assert rig_config.meter.rows == 4
    assert rig_config.motor.ke_v_per_krpm == 7.1
    assert rig_config.flow_sensor.calibration_k_g_per_pf == 18.655
    assert rig_config.flow_sensor.calibration_b_g == 0.4053
    assert rig_config.flow_sensor.baseline_samples == 200


def test_torque_constant_equals_back_emf_constant_in_si(rig_config):
    motor = rig_config.motor
    assert motor.ke_v_s_per_rad == pytest.approx(7.1e-3 * 60 / (2 * math.pi))
    assert motor.kt_nm_per_a == pytest.approx(0.0678, abs=1e-4)


def test_mechanical_time_constant_is_milliseconds_not_paper_0188_s(rig_config):
    tau = rig_config.motor.mechanical_time_constant_s
    assert 0.0005 < tau < 0.003


def test_database_paths_resolved_and_exist(rig_config):
    for name in (rig_config.wiring.dbc_file, rig_config.wiring.analog_output_eds_file):
        path = Path(name)
        assert path.is_absolute()
        assert path.is_file()


def test_every_value_in_rig_toml_says_where_it_comes_from():
    for number, line in enumerate(DEFAULT_RIG_TOML.read_text(encoding="utf-8").splitlines(), 1):
        stripped = line.strip()
        if not stripped or stripped.startswith(("#", "[")):
            continue
        if stripped.startswith(("dbc_file", "analog_output_eds_file")):
            continue
        assert "#" in stripped, f"rig.toml line {number} has no source comment: {line!r}"


def test_every_key_names_its_unit_or_is_dimensionless():
    dimensionless = {"rows", "flutes", "mode", "intercept", "gear_ratio", "chain_ratio",
                     "reducer_efficiency", "baseline_samples", "pulses_per_rev", "dac_bits",
                     "speed_loop_damping", "vibration_damping", "flow_exponent",
                     "dbc_file", "analog_output_eds_file", "analog_output_channel",
                     "flow_module_node_ids", "dut_node_id", "analog_output_node_id",
                     "ground_speed_node_id", "tractor_ecu_address", "tractor_priority",
                     "revolutions"}
    units = ("_v", "_ohm", "_kg_cm2", "_nm", "_a", "_s", "_rpm", "_hz", "_frac", "_gps",
             "_kg", "_ms", "_g_per_pf", "_g", "_ff", "_af", "_pf", "_ppm", "_mps2", "_m",
             "_mps", "_mv", "_bps", "_per_krpm", "_per_rpm", "_per_s", "_per_mps",
             "_per_mps2")
    for line in DEFAULT_RIG_TOML.read_text(encoding="utf-8").splitlines():
        match = re.match(r"^(\w+)\s*=", line)
        if not match:
            continue
        key = match.group(1)
        assert key in dimensionless or key.endswith(units), f"{key} does not name its unit"


def test_unknown_key_names_file_and_key(tmp_path):
    path = _write_variant(tmp_path, "gear_ratio = 50.0", "gear_ratio = 50.0\ngear_ration = 3")
    with pytest.raises(ConfigError) as info:
        load_rig_config(path)
    assert str(path) in str(info.value)
    assert "drive.gear_ration" in str(info.value)


def test_wrong_type_names_file_and_key(tmp_path):
    path = _write_variant(tmp_path, "flutes = 12", 'flutes = "twelve"')
    with pytest.raises(ConfigError, match=r"rig\.toml: \[meter\.flutes\]"):
        load_rig_config(path)


def test_out_of_range_value_names_file_section_and_field(tmp_path):
    path = _write_variant(tmp_path, "gear_ratio = 50.0", "gear_ratio = 0.0")
    with pytest.raises(ConfigError) as info:
        load_rig_config(path)
    message = str(info.value)
    assert str(path) in message and "[drive]" in message and "gear_ratio" in message


def test_missing_key_is_an_error(tmp_path):
    path = _write_variant(tmp_path, "flutes = 12", "")
    with pytest.raises(ConfigError, match=r"\[meter\.flutes\] missing required key"):
        load_rig_config(path)


def test_bad_literal_is_an_error(tmp_path):
    path = _write_variant(tmp_path, 'mode = "block"', 'mode = "blocky"')
    with pytest.raises(ConfigError, match=r"flow_sensor\.mode"):
        load_rig_config(path)


def test_rows_and_flow_module_ids_must_agree(tmp_path):
    path = _write_variant(tmp_path, "flow_module_node_ids = [1, 2, 3, 4]",
                          "flow_module_node_ids = [1, 2, 3]")
    with pytest.raises(ConfigError, match="flow_module_node_ids"):
        load_rig_config(path)


def test_duplicate_node_ids_are_an_error(tmp_path):
    path = _write_variant(tmp_path, "ground_speed_node_id = 5", "ground_speed_node_id = 4")
    with pytest.raises(ConfigError, match=r"\[wiring\] node ids must be distinct"):
        load_rig_config(path)


def test_missing_file_is_an_error(tmp_path):
    with pytest.raises(ConfigError, match="file not found"):
        load_rig_config(tmp_path / "nope.toml")
