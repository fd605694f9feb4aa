"""The fertilizer rig's configuration: frozen dataclasses loaded from ``rig.toml``.

Every parameter carries its unit in its name (``ke_v_per_krpm``, ``transport_delay_s``) and is
commented in the packaged ``rig.toml`` with its source: a figure of paper [F] or the physical
reasoning behind an estimate. :func:`load_rig_config` reads a file through
:func:`hil.config.load_toml`, so unknown keys, missing keys and wrong types are errors that name
the file and the key; range checks in ``__post_init__`` are reported the same way.

Example
-------
>>> cfg = load_rig_config()
>>> cfg.meter.rows, cfg.drive.gear_ratio
(4, 50.0)
>>> round(cfg.motor.kt_nm_per_a, 4)
0.0678
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hil.config import check_fraction as _fraction
from hil.config import check_non_negative as _non_negative
from hil.config import check_positive as _positive
from hil.config import load_toml
from hil.errors import ConfigError

DEFAULT_RIG_TOML = Path(__file__).with_name("rig.toml")
"""The packaged rig configuration."""

RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
"""Revolutions per minute in one radian per second."""





@dataclass(frozen=True)
class MotorConfig:
    """Dunkermotoren BG45X30SI: brushless DC motor with an integrated speed controller.

    The electrical parameters are those of paper [F] eq. (4) read in SI units; the torque
    constant is not a key because in SI units it equals the back-EMF constant.
    """

    supply_v: float
    ke_v_per_krpm: float
    armature_resistance_ohm: float
    rotor_inertia_kg_cm2: float
    load_inertia_at_motor_kg_cm2: float
    coulomb_friction_nm: float
    viscous_friction_nm_per_krpm: float
    current_limit_a: float
    continuous_current_a: float
    peak_current_time_s: float
    command_full_scale_v: float
    speed_at_full_command_rpm: float
    command_deadband_v: float
    speed_loop_bandwidth_hz: float
    speed_loop_damping: float
    setpoint_ramp_rpm_per_s: float

    def __post_init__(self) -> None:
        _positive(self, "supply_v", "ke_v_per_krpm", "armature_resistance_ohm",
                  "rotor_inertia_kg_cm2", "current_limit_a", "continuous_current_a",
                  "peak_current_time_s", "command_full_scale_v", "speed_at_full_command_rpm",
                  "speed_loop_bandwidth_hz", "speed_loop_damping", "setpoint_ramp_rpm_per_s")
        _non_negative(self, "load_inertia_at_motor_kg_cm2", "coulomb_friction_nm",
                      "viscous_friction_nm_per_krpm", "command_deadband_v")
        if self.continuous_current_a > self.current_limit_a:
            raise ValueError("continuous_current_a must not exceed current_limit_a")
        if self.command_deadband_v >= self.command_full_scale_v:
            raise ValueError("command_deadband_v must be below command_full_scale_v")

    @property
    def ke_v_s_per_rad(self) -> float:
        """Back-EMF constant in SI units (V·s/rad)."""
        return self.ke_v_per_krpm / 1000.0 * RPM_PER_RAD_S

    @property
    def kt_nm_per_a(self) -> float:
        """Torque constant (N·m/A); equal to :attr:`ke_v_s_per_rad` in SI units."""
        return self.ke_v_s_per_rad

    @property
    def inertia_kg_m2(self) -> float:
        """Rotor plus reflected load inertia at the motor shaft (kg·m²)."""
        return (self.rotor_inertia_kg_cm2 + self.load_inertia_at_motor_kg_cm2) * 1e-4

    @property
    def mechanical_time_constant_s(self) -> float:
        """``J·Ra/(Kt·Ke)``: the open-loop electromechanical time constant (s)."""
        return (self.inertia_kg_m2 * self.armature_resistance_ohm
                / (self.kt_nm_per_a * self.ke_v_s_per_rad))

    @property
    def no_load_speed_rpm(self) -> float:
        """Speed at which the back-EMF equals the supply voltage (rpm)."""
        return self.supply_v / self.ke_v_per_krpm * 1000.0

    @property
    def rpm_per_command_v(self) -> float:
        """Speed set per volt of command (rpm/V)."""
        return self.speed_at_full_command_rpm / self.command_full_scale_v


@dataclass(frozen=True)
class DriveConfig:
    """Chain and reducer between the motor and the meter shaft."""

    gear_ratio: float
    chain_ratio: float
    reducer_efficiency: float
    shaft_friction_nm: float

    def __post_init__(self) -> None:
        _positive(self, "gear_ratio", "chain_ratio")
        _non_negative(self, "shaft_friction_nm")
        if not 0 < self.reducer_efficiency <= 1:
            raise ValueError(
                f"reducer_efficiency must be in (0, 1], got {self.reducer_efficiency!r}")

    @property
    def total_ratio(self) -> float:
        """Motor revolutions per meter-shaft revolution."""
        return self.gear_ratio * self.chain_ratio


@dataclass(frozen=True)
class MeterConfig:
    """Fluted-roller (external groove wheel) meters, one per row, on one shaft."""

    rows: int
    flow_coeff_gps: float
    flow_exponent: float
    linear_below_rpm: float
    flutes: int
    pulsation_first_harmonic_frac: float
    pulsation_second_harmonic_frac: float
    flute_charge_sd_frac: float
    row_spread_sd_frac: float
    roller_torque_nm: float
    roller_torque_per_rpm_nm: float

    def __post_init__(self) -> None:
        _positive(self, "rows", "flow_coeff_gps", "flow_exponent", "linear_below_rpm", "flutes")
        _non_negative(self, "pulsation_first_harmonic_frac", "pulsation_second_harmonic_frac",
                      "flute_charge_sd_frac", "row_spread_sd_frac", "roller_torque_nm",
                      "roller_torque_per_rpm_nm")
        if self.pulsation_first_harmonic_frac + self.pulsation_second_harmonic_frac >= 1:
            raise ValueError("pulsation harmonics must sum below 1 (flow would turn negative)")
        if not 0 < self.flow_exponent <= 1:
            raise ValueError(f"flow_exponent must be in (0, 1], got {self.flow_exponent!r}")


@dataclass(frozen=True)
class FertilizerConfig:
    """Hopper content and the fertilizer's state relative to the meter's calibration."""

    density_offset_mean_frac: float
    density_offset_sd_frac: float
    density_drift_sd_frac: float
    density_drift_time_s: float
    hopper_capacity_kg: float
    hopper_initial_kg: float
    level_sensitivity_frac: float
    starvation_fill_frac: float

    def __post_init__(self) -> None:
        _positive(self, "density_drift_time_s", "hopper_capacity_kg")
        _non_negative(self, "density_offset_sd_frac", "density_drift_sd_frac",
                      "hopper_initial_kg")
        _fraction(self, "level_sensitivity_frac", "starvation_fill_frac")
        if not -0.5 < self.density_offset_mean_frac < 0.5:
            raise ValueError("density_offset_mean_frac must be within ±0.5")
        if self.hopper_initial_kg > self.hopper_capacity_kg:
            raise ValueError("hopper_initial_kg must not exceed hopper_capacity_kg")


@dataclass(frozen=True)
class TransportConfig:
    """Fertilizer tube: roller → flow sensor → tube exit."""

    meter_to_sensor_delay_s: float
    sensor_to_exit_delay_s: float
    dispersion_time_s: float

    def __post_init__(self) -> None:
        _positive(self, "meter_to_sensor_delay_s", "sensor_to_exit_delay_s")
        _non_negative(self, "dispersion_time_s")


@dataclass(frozen=True)
class FlowSensorConfig:
    """Capacitive flow detection module (STM32 + AD7746), one per row."""

    mode: Literal["block", "sliding"]
    window_s: float
    sliding_report_period_s: float
    conversion_time_ms: float
    baseline_samples: int
    calibration_k_g_per_pf: float
    calibration_b_g: float
    intercept: Literal["never", "per_window"]
    sensing_transit_s: float
    transit_jitter_sd_frac: float
    transit_jitter_time_s: float
    calibration_mismatch_sd_frac: float
    baseline_drift_sd_ff: float
    baseline_drift_time_s: float
    adc_noise_rms_af: float
    adc_lsb_af: float
    adc_range_pf: float
    vibration_noise_ff_per_mps2: float
    clock_error_sd_ppm: float
    flow_valid_max_gps: float

    def __post_init__(self) -> None:
        _positive(self, "window_s", "sliding_report_period_s", "conversion_time_ms",
                  "baseline_samples", "calibration_k_g_per_pf", "sensing_transit_s",
                  "transit_jitter_time_s", "baseline_drift_time_s", "adc_lsb_af",
                  "adc_range_pf", "flow_valid_max_gps")
        _non_negative(self, "transit_jitter_sd_frac", "calibration_mismatch_sd_frac",
                      "baseline_drift_sd_ff", "adc_noise_rms_af", "vibration_noise_ff_per_mps2",
                      "clock_error_sd_ppm")
        ratio = self.window_s / self.sliding_report_period_s
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError("window_s must be a whole multiple of sliding_report_period_s")
        if self.conversion_time_ms / 1000.0 > self.sliding_report_period_s:
            raise ValueError("conversion_time_ms must be shorter than sliding_report_period_s")

    @property
    def conversion_rate_hz(self) -> float:
        """AD7746 conversions per second."""
        return 1000.0 / self.conversion_time_ms

    @property
    def report_period_s(self) -> float:
        """Time between two reports in the configured mode (s)."""
        return self.window_s if self.mode == "block" else self.sliding_report_period_s

    @property
    def sensitivity_pf_per_g(self) -> float:
        """Capacitance change per gram held in the sensing zone for a perfectly calibrated module.

        Chosen so that the window sum ``Σ ΔC`` of a 1 s window, times the calibration slope
        ``k``, equals the grams that passed: ``k · f_conv · τ_transit · s = 1``.
        """
        return 1.0 / (self.calibration_k_g_per_pf * self.conversion_rate_hz
                      * self.sensing_transit_s)


@dataclass(frozen=True)
class GroundSpeedConfig:
    """Tractor speed, ground-wheel slip and the speed sources an implement sees."""

    speed_time_constant_s: float
    max_accel_mps2: float
    speed_variation_sd_frac: float
    speed_variation_time_s: float
    vibration_rms_mps2_per_mps: float
    vibration_freq_hz: float
    vibration_damping: float
    wheel_diameter_m: float
    pulses_per_rev: int
    pulse_spacing_error_sd_frac: float
    hall_average_window_s: float
    hall_timeout_s: float
    wheel_slip_mean_frac: float
    wheel_slip_sd_frac: float
    wheel_slip_time_s: float
    tractor_slip_mean_frac: float
    tractor_slip_sd_frac: float
    tractor_slip_time_s: float
    radar_bias_frac: float
    radar_noise_sd_frac: float
    radar_noise_time_s: float
    #: field distance calibration of the Hall node: it counts the nominal arc / (1 - this) of
    #: ground per pulse, as set by a calibration drive over a measured distance (it absorbs
    #: the mean ground-wheel skid); 0: uncalibrated
    hall_calibration_frac: float = 0.0

    def __post_init__(self) -> None:
        _positive(self, "speed_time_constant_s", "max_accel_mps2", "speed_variation_time_s",
                  "vibration_freq_hz", "vibration_damping", "wheel_diameter_m",
                  "pulses_per_rev", "hall_average_window_s", "hall_timeout_s",
                  "wheel_slip_time_s", "tractor_slip_time_s", "radar_noise_time_s")
        _non_negative(self, "speed_variation_sd_frac", "vibration_rms_mps2_per_mps",
                      "pulse_spacing_error_sd_frac", "wheel_slip_sd_frac",
                      "tractor_slip_sd_frac", "radar_noise_sd_frac")
        _fraction(self, "wheel_slip_mean_frac", "tractor_slip_mean_frac")
        if not 0.0 <= self.hall_calibration_frac < 0.2:
            raise ValueError("hall_calibration_frac must be within [0, 0.2)")
        if not -0.2 < self.radar_bias_frac < 0.2:
            raise ValueError("radar_bias_frac must be within ±0.2")
        if self.pulse_spacing_error_sd_frac >= 0.2:
            raise ValueError("pulse_spacing_error_sd_frac must be below 0.2")

    @property
    def metres_per_pulse(self) -> float:
        """Ground-wheel arc between two Hall pulses (m)."""
        return math.pi * self.wheel_diameter_m / self.pulses_per_rev

    @property
    def reported_metres_per_pulse(self) -> float:
        """Ground distance per pulse the Hall node counts (its calibrated value, m)."""
        return self.metres_per_pulse / (1.0 - self.hall_calibration_frac)


@dataclass(frozen=True)
class AnalogOutputConfig:
    """CAN analog output module C-3402 (CiA 401, 0-10 V) output stage."""

    full_scale_mv: int
    dac_bits: int
    gain_error_sd_frac: float
    offset_error_sd_mv: float
    error_value_mv: int

    def __post_init__(self) -> None:
        _positive(self, "full_scale_mv", "dac_bits")
        _non_negative(self, "gain_error_sd_frac", "offset_error_sd_mv")
        if not 0 <= self.error_value_mv <= self.full_scale_mv:
            raise ValueError("error_value_mv must be within 0..full_scale_mv")
        if self.full_scale_mv > 32767:
            raise ValueError("full_scale_mv must fit an INTEGER16 (<= 32767)")


@dataclass(frozen=True)
class BoomConfig:
    """Where the rows put the fertilizer: the furrow openers (field runs under a Task
    Controller judge the applied rate where it lands)."""

    width_m: float
    opener_offset_m: float

    def __post_init__(self) -> None:
        _positive(self, "width_m")
        if not -20.0 <= self.opener_offset_m <= 20.0:
            raise ValueError(f"opener_offset_m must be within +-20 m of the antenna, got "
                             f"{self.opener_offset_m!r}")


@dataclass(frozen=True)
class WiringConfig:
    """Node ids, addresses, frame periods and database files of the rig's CAN bus."""

    bitrate_bps: int
    dbc_file: str
    analog_output_eds_file: str
    dut_node_id: int
    analog_output_node_id: int
    analog_output_channel: int
    flow_module_node_ids: tuple[int, ...]
    ground_speed_node_id: int
    tractor_ecu_address: int
    tractor_priority: int
    ground_speed_period_ms: int
    tractor_speed_period_ms: int
    setpoint_period_ms: int
    analog_output_heartbeat_ms: int
    #: the binding of the rig quantities in force (:mod:`hil.contract.binding`); empty: the
    #: rig's own, ``<dbc_file stem>.binding.toml`` beside the DBC. A DUT profile's ``[wiring]
    #: binding`` sets it.
    binding_file: str = ""

    def __post_init__(self) -> None:
        _positive(self, "bitrate_bps", "ground_speed_period_ms", "tractor_speed_period_ms",
                  "setpoint_period_ms", "analog_output_heartbeat_ms")
        ids = [self.dut_node_id, self.analog_output_node_id, self.ground_speed_node_id,
               *self.flow_module_node_ids]
        for node_id in ids:
            if not 1 <= node_id <= 127:
                raise ValueError(f"CANopen node ids must be 1..127, got {node_id}")
        if len(set(ids)) != len(ids):
            raise ValueError(f"node ids must be distinct, got {ids}")
        if not 0 <= self.tractor_ecu_address <= 253:
            raise ValueError("tractor_ecu_address must be a J1939 address 0..253")
        if not 0 <= self.tractor_priority <= 7:
            raise ValueError("tractor_priority must be 0..7")
        if self.analog_output_channel not in (1, 2):
            raise ValueError("analog_output_channel must be 1 or 2")


@dataclass(frozen=True)
class CalibrationTestConfig:
    """The operator's calibration ("rotation") test of a fertilizer lot, before the runs.

    The meter turns ``revolutions`` times at ``shaft_speed_rpm`` with the tubes off, the
    product is weighed on a scale that reads to ``scale_resolution_kg`` within
    ``scale_error_kg``, and the terminal sends the grams per revolution of one row
    (``MeterCalibration``) every ``frame_period_ms``. A run whose lot is the one the
    controllers' own calibration was made on (``calibrated_lot_frac``, the nominal rig's)
    needs no test; :mod:`plant_emulators.fertilizer.calibration_test` computes it.
    """

    calibrated_lot_frac: float = -0.035
    revolutions: int = 50
    shaft_speed_rpm: float = 20.0
    scale_resolution_kg: float = 0.1
    scale_error_kg: float = 0.1
    frame_period_ms: int = 1000

    def __post_init__(self) -> None:
        _positive(self, "revolutions", "shaft_speed_rpm", "scale_resolution_kg",
                  "frame_period_ms")
        _non_negative(self, "scale_error_kg")
        if not -0.5 < self.calibrated_lot_frac < 0.5:
            raise ValueError("calibrated_lot_frac must be within ±0.5")


@dataclass(frozen=True)
class FertilizerRigConfig:
    """The whole fertilizer rig: physics, sensors and wiring."""

    motor: MotorConfig
    drive: DriveConfig
    meter: MeterConfig
    fertilizer: FertilizerConfig
    transport: TransportConfig
    flow_sensor: FlowSensorConfig
    ground_speed: GroundSpeedConfig
    analog_output: AnalogOutputConfig
    wiring: WiringConfig
    boom: BoomConfig
    calibration_test: CalibrationTestConfig = CalibrationTestConfig()

    def __post_init__(self) -> None:
        if len(self.wiring.flow_module_node_ids) != self.meter.rows:
            raise ValueError(
                f"wiring.flow_module_node_ids has {len(self.wiring.flow_module_node_ids)} "
                f"entries for {self.meter.rows} meter rows")


def load_rig_config(path: str | Path | None = None, *,
                    overrides: Mapping[str, Any] | None = None,
                    source: str = "") -> FertilizerRigConfig:
    """Load a fertilizer rig configuration.

    Parameters
    ----------
    path : str or Path, optional
        A TOML file with the sections of :class:`FertilizerRigConfig`. Defaults to the
        packaged ``rig.toml``.
    overrides : mapping, optional
        Nested tables that replace the file's values (a DUT profile's ``[rig]``); ``source``
        names where they come from in errors.

    Returns
    -------
    FertilizerRigConfig
        The validated configuration. The database file names of ``[wiring]`` are resolved
        relative to the TOML file and returned as absolute paths.

    Raises
    ------
    hil.errors.ConfigError
        When the file is missing or invalid; the message names the file and the key.
    """
    path = Path(path) if path is not None else DEFAULT_RIG_TOML
    _refuse_dbc_override(overrides, source)
    cfg = load_toml(path, FertilizerRigConfig, overrides=overrides, source=source)
    base = path.resolve().parent
    dbc = (base / cfg.wiring.dbc_file).resolve()
    binding = Path(cfg.wiring.binding_file) if cfg.wiring.binding_file \
        else dbc.with_name(dbc.stem + ".binding.toml")
    wiring = dataclasses.replace(
        cfg.wiring,
        dbc_file=str(dbc),
        analog_output_eds_file=str((base / cfg.wiring.analog_output_eds_file).resolve()),
        binding_file=str(binding if binding.is_absolute() else (base / binding).resolve()),
    )
    return dataclasses.replace(cfg, wiring=wiring)


def _refuse_dbc_override(overrides: Mapping[str, Any] | None, source: str) -> None:
    """``[rig] wiring.dbc_file`` was a partial path to another database (ids still tied to the
    node ids): the DUT's database is bound with ``[wiring] database`` and ``binding``."""
    wiring = (overrides or {}).get("wiring")
    if isinstance(wiring, Mapping) and "dbc_file" in wiring:
        raise ConfigError(
            "the rig's own DBC cannot be replaced: name your controller's database in the "
            "profile's [wiring] database = FILE and bind it with [wiring] binding = FILE "
            "(`hil profile bind DATABASE --rig fertilizer -o FILE` writes a start; see "
            "docs/guide/binding.md)", path=source or None, key="rig.wiring.dbc_file")
