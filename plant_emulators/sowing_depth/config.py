"""The sowing-depth rig's configuration: frozen dataclasses loaded from ``rig.toml``.

Every key carries its unit in its name; ``rig.toml`` says where each value comes from (a figure
of paper [D], a datasheet class, or physical reasoning). :func:`load_rig_config` reads the
packaged file by default and rejects unknown keys, naming the file and the key.

Example
-------
>>> cfg = load_rig_config()
>>> cfg.cylinder.rod_speed_max_mm_per_s
50.0
>>> cfg.machine.rows
12
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from hil.config import check_non_negative as _non_negative
from hil.config import check_positive as _positive
from hil.config import load_toml

__all__ = [
    "ArmConfig",
    "CylinderConfig",
    "DrawWireConfig",
    "DriveConfig",
    "GnssConfig",
    "InclinometerConfig",
    "MachineConfig",
    "MotorConfig",
    "OutlierConfig",
    "SoilConfig",
    "SowingDepthRigConfig",
    "TerrainConfig",
    "ThrowConfig",
    "WiringConfig",
    "load_rig_config",
]




@dataclass(frozen=True)
class MotorConfig:
    """The cylinder's integrated servo motor, as a DC-equivalent machine (SI derived below)."""

    ke_vrms_per_krpm: float
    ra_ohm: float
    ja_kg_cm2: float
    rated_torque_n_m: float
    rated_speed_rpm: float
    dc_bus_voltage_v: float
    velocity_loop_time_constant_ms: float

    def __post_init__(self) -> None:
        _positive(self, "ke_vrms_per_krpm", "ra_ohm", "ja_kg_cm2", "rated_torque_n_m",
                  "rated_speed_rpm", "dc_bus_voltage_v", "velocity_loop_time_constant_ms")

    @property
    def ke_v_s_per_rad(self) -> float:
        """Back-EMF constant in SI: V per krpm divided by 1000·2π/60 rad/s."""
        return self.ke_vrms_per_krpm / (1000.0 * 2.0 * math.pi / 60.0)

    @property
    def kt_n_m_per_a(self) -> float:
        """Torque constant of the DC-equivalent model: equal to Ke in SI (energy balance)."""
        return self.ke_v_s_per_rad

    @property
    def ja_kg_m2(self) -> float:
        """Rotor inertia in kg·m² (1 kg·cm² = 1e-4 kg·m²)."""
        return self.ja_kg_cm2 * 1e-4


@dataclass(frozen=True)
class CylinderConfig:
    """Belt, reducer, lead screw, rod: the servo electric cylinder's mechanics."""

    belt_ratio: float
    reducer_ratio: float
    screw_lead_mm: float
    transmission_efficiency: float
    transmission_inertia_kg_cm2: float
    moving_mass_kg: float
    stroke_mm: float
    rod_speed_max_mm_per_s: float
    push_force_max_n: float
    initial_rod_position_mm: float

    def __post_init__(self) -> None:
        _positive(self, "belt_ratio", "reducer_ratio", "screw_lead_mm",
                  "transmission_efficiency", "stroke_mm", "rod_speed_max_mm_per_s",
                  "push_force_max_n")
        _non_negative(self, "transmission_inertia_kg_cm2", "moving_mass_kg")
        if self.transmission_efficiency > 1.0:
            raise ValueError("transmission_efficiency must be <= 1")
        if not 0.0 <= self.initial_rod_position_mm <= self.stroke_mm:
            raise ValueError("initial_rod_position_mm must lie within the stroke")

    @property
    def rod_mm_per_motor_rev(self) -> float:
        """Rod travel per motor revolution (lead / (belt ratio · reducer ratio))."""
        return self.screw_lead_mm / (self.belt_ratio * self.reducer_ratio)


@dataclass(frozen=True)
class DriveConfig:
    """Power-on defaults of the CiA 402 drive's objects, in physical units."""

    boot_time_ms: float
    position_loop_gain_per_s: float
    profile_velocity_mm_per_s: float
    profile_acceleration_mm_per_s2: float
    profile_deceleration_mm_per_s2: float
    quick_stop_deceleration_mm_per_s2: float
    following_error_window_mm: float
    following_error_timeout_ms: float
    position_window_mm: float
    position_window_time_ms: float
    velocity_window_mm_per_s: float
    velocity_window_time_ms: float
    velocity_threshold_mm_per_s: float
    velocity_threshold_time_ms: float
    software_position_limit_min_mm: float
    software_position_limit_max_mm: float
    overload_time_ms: float
    overload_reset_fraction: float
    quick_stop_option_code: Literal[0, 1, 2, 5, 6]
    fault_reaction_option_code: Literal[0, 1, 2]

    def __post_init__(self) -> None:
        _positive(self, "position_loop_gain_per_s", "profile_velocity_mm_per_s",
                  "profile_acceleration_mm_per_s2", "profile_deceleration_mm_per_s2",
                  "quick_stop_deceleration_mm_per_s2", "following_error_window_mm",
                  "position_window_mm", "velocity_window_mm_per_s", "overload_time_ms")
        _non_negative(self, "boot_time_ms", "following_error_timeout_ms",
                      "position_window_time_ms", "velocity_window_time_ms",
                      "velocity_threshold_mm_per_s", "velocity_threshold_time_ms")
        if self.software_position_limit_min_mm >= self.software_position_limit_max_mm:
            raise ValueError("software_position_limit_min_mm must be below the max")
        if not 0.0 <= self.overload_reset_fraction < 1.0:
            raise ValueError("overload_reset_fraction must be in [0, 1)")


@dataclass(frozen=True)
class MachineConfig:
    """Planter geometry: rows, linkage, where the tractor and the rollers sit."""

    rows: int
    row_spacing_mm: float
    roller_travel_per_rod_mm: float
    seedbed_depth_at_rod_zero_mm: float
    tractor_rear_axle_ahead_of_seed_m: float
    tractor_wheelbase_m: float
    post_press_roller_behind_seed_m: float
    truth_cell_length_mm: float
    soil_stiffness_n_per_mm: float
    soil_damping_n_s_per_mm: float
    roller_weight_n: float

    def __post_init__(self) -> None:
        if self.rows < 1:
            raise ValueError("rows must be >= 1")
        _positive(self, "row_spacing_mm", "roller_travel_per_rod_mm",
                  "tractor_rear_axle_ahead_of_seed_m", "tractor_wheelbase_m",
                  "truth_cell_length_mm")
        _non_negative(self, "post_press_roller_behind_seed_m", "soil_stiffness_n_per_mm",
                      "soil_damping_n_s_per_mm", "roller_weight_n")


@dataclass(frozen=True)
class ThrowConfig:
    """Covering soil: throw efficiency versus speed, soil sensitivity, per-row spread."""

    efficiency_max: float
    low_speed_loss: float
    low_speed_scale_m_per_s: float
    moisture_gain_per_percent: float
    compaction_gain_per_n_per_cm2: float
    noise_sd_mm: float
    noise_correlation_length_m: float
    noise_low_speed_gain: float
    noise_speed_gain_per_m_per_s: float
    row_offset_sd_mm: float
    lateral_tilt_sd_deg: float
    lateral_tilt_correlation_length_m: float

    def __post_init__(self) -> None:
        _positive(self, "efficiency_max", "low_speed_scale_m_per_s",
                  "noise_correlation_length_m", "lateral_tilt_correlation_length_m")
        _non_negative(self, "low_speed_loss", "noise_sd_mm", "noise_low_speed_gain",
                      "noise_speed_gain_per_m_per_s", "row_offset_sd_mm",
                      "lateral_tilt_sd_deg")
        if self.low_speed_loss >= 1.0:
            raise ValueError("low_speed_loss must be < 1")


@dataclass(frozen=True)
class TerrainConfig:
    """Longitudinal ground profile (a gradient plus two smooth bands) and the tractor's roll."""

    field_slope_deg: float
    long_wave_sd_mm: float
    long_wave_correlation_length_m: float
    short_wave_sd_mm: float
    short_wave_correlation_length_m: float
    roll_sd_deg: float
    roll_correlation_length_m: float

    def __post_init__(self) -> None:
        _non_negative(self, "long_wave_sd_mm", "short_wave_sd_mm", "roll_sd_deg")
        if not -15.0 < self.field_slope_deg < 15.0:
            raise ValueError("field_slope_deg must lie within ±15°")
        _positive(self, "long_wave_correlation_length_m", "short_wave_correlation_length_m",
                  "roll_correlation_length_m")


@dataclass(frozen=True)
class SoilConfig:
    """Soil state along the field: moisture, compaction and stubble as AR(1) processes."""

    moisture_mean_percent: float
    moisture_sd_percent: float
    moisture_correlation_length_m: float
    compaction_mean_n_per_cm2: float
    compaction_sd_n_per_cm2: float
    compaction_correlation_length_m: float
    stubble_sd_relative: float
    stubble_correlation_length_m: float

    def __post_init__(self) -> None:
        _positive(self, "moisture_mean_percent", "moisture_correlation_length_m",
                  "compaction_mean_n_per_cm2", "compaction_correlation_length_m",
                  "stubble_correlation_length_m")
        _non_negative(self, "moisture_sd_percent", "compaction_sd_n_per_cm2",
                      "stubble_sd_relative")


@dataclass(frozen=True)
class OutlierConfig:
    """Seed-level outliers along each row: clods (deep) and three shallow mechanisms."""

    reference_speed_m_per_s: float
    clod_rate_per_m: float
    clod_speed_weight: float
    clod_compaction_gain_per_n_per_cm2: float
    clod_moisture_gain_per_percent: float
    clod_length_min_mm: float
    clod_length_max_mm: float
    clod_extra_depth_min_mm: float
    clod_extra_depth_max_mm: float
    bounce_rate_per_m: float
    bounce_speed_exponent: float
    bounce_length_min_mm: float
    bounce_length_max_mm: float
    stubble_rate_per_m: float
    stubble_length_min_mm: float
    stubble_length_max_mm: float
    poor_throw_rate_per_m: float
    poor_throw_speed_scale_m_per_s: float
    poor_throw_length_min_mm: float
    poor_throw_length_max_mm: float
    shallow_depth_factor_min: float
    shallow_depth_factor_max: float

    def __post_init__(self) -> None:
        _positive(self, "reference_speed_m_per_s", "poor_throw_speed_scale_m_per_s")
        _non_negative(self, "clod_rate_per_m", "clod_speed_weight", "bounce_rate_per_m",
                      "bounce_speed_exponent", "stubble_rate_per_m", "poor_throw_rate_per_m",
                      "shallow_depth_factor_min")
        for kind in ("clod", "bounce", "stubble", "poor_throw"):
            lo = getattr(self, f"{kind}_length_min_mm")
            hi = getattr(self, f"{kind}_length_max_mm")
            if not 0 < lo <= hi:
                raise ValueError(f"{kind}_length_min_mm must be > 0 and <= the max")
        if not 0 <= self.clod_extra_depth_min_mm <= self.clod_extra_depth_max_mm:
            raise ValueError("clod_extra_depth_min_mm must be >= 0 and <= the max")
        if not self.shallow_depth_factor_min <= self.shallow_depth_factor_max <= 1.0:
            raise ValueError("shallow_depth_factor_min <= shallow_depth_factor_max <= 1")


@dataclass(frozen=True)
class ArmConfig:
    """Post-sowing press roller arm that carries the inclinometer."""

    arm_length_mm: float
    roller_radius_mm: float
    pivot_height_above_seedbed_mm: float
    inclinometer_mount_offset_deg: float

    def __post_init__(self) -> None:
        _positive(self, "arm_length_mm", "roller_radius_mm", "pivot_height_above_seedbed_mm")


@dataclass(frozen=True)
class InclinometerConfig:
    """LVT525H dual-axis inclinometer with its 0-5 V outputs read by an ADC in mV."""

    range_deg: float
    resolution_deg: float
    accuracy_deg: float
    noise_sd_deg: float
    vibration_noise_sd_deg_per_m_per_s: float
    response_time_constant_ms: float
    output_min_mv: float
    output_max_mv: float
    adc_resolution_mv: float
    noisy_fault_gain: float

    def __post_init__(self) -> None:
        _positive(self, "range_deg", "resolution_deg", "adc_resolution_mv", "noisy_fault_gain")
        _non_negative(self, "accuracy_deg", "noise_sd_deg",
                      "vibration_noise_sd_deg_per_m_per_s", "response_time_constant_ms")
        if self.output_min_mv >= self.output_max_mv:
            raise ValueError("output_min_mv must be below output_max_mv")

    @property
    def mv_per_deg(self) -> float:
        """Output slope: the voltage span over the angle span (2·range)."""
        return (self.output_max_mv - self.output_min_mv) / (2.0 * self.range_deg)

    @property
    def zero_mv(self) -> float:
        """Output at 0°, the middle of the span."""
        return 0.5 * (self.output_min_mv + self.output_max_mv)


@dataclass(frozen=True)
class DrawWireConfig:
    """Draw-wire displacement sensor on the pre-sowing press roller carrier."""

    range_mm: float
    resolution_mm: float
    linearity_error_mm: float
    noise_sd_mm: float

    def __post_init__(self) -> None:
        _positive(self, "range_mm", "resolution_mm")
        _non_negative(self, "linearity_error_mm", "noise_sd_mm")


@dataclass(frozen=True)
class GnssConfig:
    """BeiDou/GNSS speed module: NMEA 0183 output over a serial port."""

    talker_id: Literal["GN", "BD", "GB", "GP"]
    output_rate_hz: float
    start_utc: str
    start_latitude_deg: float
    start_longitude_deg: float
    heading_deg: float
    altitude_m: float
    geoid_separation_m: float
    satellites_used: int
    hdop: float
    speed_noise_sd_m_per_s: float
    position_noise_sd_m: float

    def __post_init__(self) -> None:
        _positive(self, "output_rate_hz", "hdop")
        _non_negative(self, "speed_noise_sd_m_per_s", "position_noise_sd_m")
        if not -90.0 < self.start_latitude_deg < 90.0:
            raise ValueError("start_latitude_deg must lie in (-90, 90)")
        if not -180.0 <= self.start_longitude_deg <= 180.0:
            raise ValueError("start_longitude_deg must lie in [-180, 180]")
        if not 0 <= self.satellites_used <= 99:
            raise ValueError("satellites_used must lie in 0..99")


@dataclass(frozen=True)
class WiringConfig:
    """Bus, node ids, frame ids (29-bit J1939 style) and periods of the rig's CAN interface."""

    bitrate_bit_per_s: int
    drive_node_id: int
    sync_period_ms: float
    drive_heartbeat_period_ms: int
    tractor_source_address: int
    draw_wire_source_address: int
    inclinometer_source_address: int
    terminal_source_address: int
    controller_source_address: int
    ground_speed_frame_id: int
    ground_speed_period_ms: float
    draw_wire_frame_id: int
    draw_wire_period_ms: float
    inclinometer_frame_id: int
    inclinometer_period_ms: float
    depth_setpoint_frame_id: int
    depth_setpoint_period_ms: float
    controller_status_frame_id: int
    controller_status_period_ms: float

    def __post_init__(self) -> None:
        if not 1 <= self.drive_node_id <= 127:
            raise ValueError("drive_node_id must lie in 1..127")
        for name in ("tractor_source_address", "draw_wire_source_address",
                     "inclinometer_source_address", "terminal_source_address",
                     "controller_source_address"):
            if not 0 <= getattr(self, name) <= 253:
                raise ValueError(f"{name} must lie in 0..253")
        for name in ("ground_speed", "draw_wire", "inclinometer", "depth_setpoint",
                     "controller_status"):
            frame_id = getattr(self, f"{name}_frame_id")
            if not 0x800 <= frame_id <= 0x1FFFFFFF:
                raise ValueError(f"{name}_frame_id must be a 29-bit identifier")
            if not getattr(self, f"{name}_period_ms") > 0:
                raise ValueError(f"{name}_period_ms must be > 0")
        _positive(self, "bitrate_bit_per_s", "sync_period_ms")
        _non_negative(self, "drive_heartbeat_period_ms")


@dataclass(frozen=True)
class SowingDepthRigConfig:
    """Everything the sowing-depth rig needs, one section per part."""

    motor: MotorConfig
    cylinder: CylinderConfig
    drive: DriveConfig
    machine: MachineConfig
    throw: ThrowConfig
    terrain: TerrainConfig
    soil: SoilConfig
    outliers: OutlierConfig
    arm: ArmConfig
    inclinometer: InclinometerConfig
    draw_wire: DrawWireConfig
    gnss: GnssConfig
    wiring: WiringConfig

    def __post_init__(self) -> None:
        if self.drive.software_position_limit_max_mm > self.cylinder.stroke_mm:
            raise ValueError("drive.software_position_limit_max_mm exceeds cylinder.stroke_mm")
        if self.drive.software_position_limit_min_mm < 0.0:
            raise ValueError("drive.software_position_limit_min_mm must be >= 0")
        if self.drive.profile_velocity_mm_per_s > self.cylinder.rod_speed_max_mm_per_s:
            raise ValueError("drive.profile_velocity_mm_per_s exceeds the rod speed limit")


def default_rig_path() -> Path:
    """Path of the packaged ``rig.toml``."""
    return Path(str(resources.files(__package__).joinpath("rig.toml")))


def load_rig_config(path: str | Path | None = None, *,
                    overrides: Mapping[str, Any] | None = None,
                    source: str = "") -> SowingDepthRigConfig:
    """Load a sowing-depth rig config (the packaged ``rig.toml`` when ``path`` is None).

    Parameters
    ----------
    path : str or Path, optional
        A TOML file with every section of :class:`SowingDepthRigConfig`.

    Returns
    -------
    SowingDepthRigConfig

    Raises
    ------
    hil.errors.ConfigError
        On a missing file, invalid TOML, an unknown or missing key, a wrong type or an
        out-of-range value; the message names the file and the key.
    """
    return load_toml(default_rig_path() if path is None else path, SowingDepthRigConfig,
                     overrides=overrides, source=source)
