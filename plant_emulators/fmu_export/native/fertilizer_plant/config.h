/* agrihil's fertilizer plant (plant_emulators/fertilizer/native/plant_core.c, unchanged) as a
 * co-simulation FMU (FMI 2.0 or 3.0, the Reference-FMUs skeleton).
 *
 * Value references: the order below is the FMU's; plant_emulators/fmu_export/variables.py
 * gives each its name, unit, causality and description (and checks this list against it). */
#ifndef config_h
#define config_h

#include <stdbool.h>
#include <stdint.h>

#include "plant_core.h"

#define MODEL_IDENTIFIER agrihil_fertilizer_plant
#define INSTANTIATION_TOKEN "{a9c3e1d0-5f1e-4b6a-9a71-agrihilfert01}"

#define CO_SIMULATION

#define GET_FLOAT64
#define SET_FLOAT64
#define GET_INT32
#define SET_INT32
#define EVENT_UPDATE

/* the rig's physics step (rig.toml: the fertilizer rig steps its plant every 1 ms) */
#define FIXED_SOLVER_STEP 0.001
#define DEFAULT_STOP_TIME 60

#define ROWS 4

typedef enum {
    vr_time = 0,
    /* inputs */
    vr_command_v,
    /* outputs */
    vr_motor_speed_rpm, vr_shaft_speed_rpm, vr_motor_current_a, vr_delivered_total_g,
    vr_flow_at_meter_mean_gps, vr_metered_total_g,
    vr_flow_at_meter_1_gps, vr_flow_at_meter_2_gps, vr_flow_at_meter_3_gps,
    vr_flow_at_meter_4_gps,
    vr_flow_at_sensor_1_gps, vr_flow_at_sensor_2_gps, vr_flow_at_sensor_3_gps,
    vr_flow_at_sensor_4_gps,
    vr_delivered_1_g, vr_delivered_2_g, vr_delivered_3_g, vr_delivered_4_g,
    vr_sensor_passed_1_g, vr_sensor_passed_2_g, vr_sensor_passed_3_g, vr_sensor_passed_4_g,
    /* parameters: rig.toml's, by section */
    vr_first_parameter,
    vr_motor_supply_v = vr_first_parameter, vr_motor_ke_v_per_krpm,
    vr_motor_armature_resistance_ohm, vr_motor_rotor_inertia_kg_cm2,
    vr_motor_load_inertia_at_motor_kg_cm2, vr_motor_coulomb_friction_nm,
    vr_motor_viscous_friction_nm_per_krpm, vr_motor_current_limit_a,
    vr_motor_continuous_current_a, vr_motor_peak_current_time_s, vr_motor_command_full_scale_v,
    vr_motor_speed_at_full_command_rpm, vr_motor_command_deadband_v,
    vr_motor_speed_loop_bandwidth_hz, vr_motor_speed_loop_damping,
    vr_motor_setpoint_ramp_rpm_per_s,
    vr_drive_gear_ratio, vr_drive_chain_ratio, vr_drive_reducer_efficiency,
    vr_drive_shaft_friction_nm,
    vr_meter_flow_coeff_gps, vr_meter_flow_exponent, vr_meter_linear_below_rpm,
    vr_meter_pulsation_first_harmonic_frac, vr_meter_pulsation_second_harmonic_frac,
    vr_meter_flute_charge_sd_frac, vr_meter_roller_torque_nm, vr_meter_roller_torque_per_rpm_nm,
    vr_fertilizer_density_drift_sd_frac, vr_fertilizer_density_drift_time_s,
    vr_fertilizer_hopper_capacity_kg, vr_fertilizer_hopper_initial_kg,
    vr_fertilizer_level_sensitivity_frac, vr_fertilizer_starvation_fill_frac,
    vr_transport_meter_to_sensor_delay_s, vr_transport_sensor_to_exit_delay_s,
    vr_transport_dispersion_time_s,
    /* parameters: the run's draws (the rig draws them from the run's seed) */
    vr_run_row_gain_1, vr_run_row_gain_2, vr_run_row_gain_3, vr_run_row_gain_4,
    vr_run_flute_offset_1, vr_run_flute_offset_2, vr_run_flute_offset_3,
    vr_run_flute_offset_4,
    vr_run_density_offset_frac, vr_run_density_wander,
    vr_end_of_reals,
    /* integer parameters */
    vr_meter_flutes = vr_end_of_reals,
    vr_seed
} ValueReference;

#define N_REALS (vr_end_of_reals - vr_command_v)

typedef struct {
    double real[N_REALS];        /* by value reference - vr_command_v */
    int32_t flutes;
    int32_t seed;
    /* the plant and its noise */
    PlantCore pc;
    NormalBlock z;
    double z_values[256];
    uint64_t rng[4];
    int ready;
    long long steps;
    double w_per_v, ratio;
} ModelData;

#endif
