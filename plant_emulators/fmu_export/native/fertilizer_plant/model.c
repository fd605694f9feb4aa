/* The fertilizer plant FMU: plant_core.c stepped once per FIXED_SOLVER_STEP.
 *
 * The constants are computed here from rig.toml's parameters with the Python model's
 * expressions in its order (plant_emulators/fertilizer/physics.py: _drive_constants,
 * _meter_constants, _bind_dt; config.py's derived values), so a plant built from the same
 * parameters and draws steps through the same doubles as the rig's native engine. The
 * per-step noise (flute charges, density wander) comes from the FMU's own generator seeded by
 * `seed` (xoshiro256** and Marsaglia's polar method), not from numpy's: with those noises on,
 * the FMU is the same physics with another noise realisation.
 *
 * Stepping is lazy: the skeleton's doStep counts fixed steps (comp->nSteps); the plant catches
 * up before any input is set and before any output is read, with the inputs it had. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"
#include "start_values.h"

#define R(vr) (M(real)[(vr) - vr_command_v])

static const double PI = 3.141592653589793;

static uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static uint64_t next_u64(uint64_t s[4])
{
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

static double uniform01(uint64_t s[4])
{
    return (double)(next_u64(s) >> 11) * 0x1.0p-53;
}

/* NormalBlock refill: standard normals by the polar method, in pairs. */
static int refill(void *ctx, double *block, size_t n)
{
    uint64_t *s = (uint64_t *)ctx;
    for (size_t i = 0; i < n; i += 2) {
        double u, v, q;
        do {
            u = 2.0 * uniform01(s) - 1.0;
            v = 2.0 * uniform01(s) - 1.0;
            q = u * u + v * v;
        } while (q >= 1.0 || q == 0.0);
        const double f = sqrt(-2.0 * log(q) / q);
        block[i] = u * f;
        if (i + 1 < n) {
            block[i + 1] = v * f;
        }
    }
    return 0;
}

Status setStartValues(ModelInstance *comp)
{
    static const double reals[N_REALS] = START_REALS;
    memcpy(M(real), reals, sizeof reals);
    M(flutes) = START_FLUTES;
    M(seed) = START_SEED;
    M(ready) = 0;
    M(steps) = 0;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

/* physics.py's _implicit_step */
static void implicit_step(double dt, double kt, double di, double bl, double inv_j, double t0,
                          double *den, double *dwf)
{
    *den = 1.0 - dt * (kt * di - bl) * inv_j;
    *dwf = dt * t0 * inv_j / *den;
}

/* FertilizerPlant.__init__, _bind_dt and the constants, from the parameters. */
static Status start(ModelInstance *comp)
{
    const double rpm_per_rad_s = 60.0 / (2.0 * PI);
    const double dt = FIXED_SOLVER_STEP;
    /* config.py's derived motor values */
    const double ke = R(vr_motor_ke_v_per_krpm) / 1000.0 * rpm_per_rad_s;
    const double kt = ke;
    const double ra = R(vr_motor_armature_resistance_ohm);
    const double inertia = (R(vr_motor_rotor_inertia_kg_cm2)
                            + R(vr_motor_load_inertia_at_motor_kg_cm2)) * 1e-4;
    const double rpm_per_command_v = R(vr_motor_speed_at_full_command_rpm)
                                     / R(vr_motor_command_full_scale_v);
    const double inv_j = 1.0 / inertia;
    const double wn = 2.0 * PI * R(vr_motor_speed_loop_bandwidth_hz);
    const double kp = 2.0 * R(vr_motor_speed_loop_damping) * wn * inertia / kt;
    const double ki = wn * wn * inertia / kt;
    M(w_per_v) = rpm_per_command_v / rpm_per_rad_s;
    const double ratio = R(vr_drive_gear_ratio) * R(vr_drive_chain_ratio);
    M(ratio) = ratio;
    const double shaft_rpm_per_rad_s = rpm_per_rad_s / ratio;
    const double to_motor = 1.0 / (ratio * R(vr_drive_reducer_efficiency));
    const double load_t0 = (((double)ROWS * R(vr_meter_roller_torque_nm)
                             + R(vr_drive_shaft_friction_nm)) * to_motor
                            + R(vr_motor_coulomb_friction_nm));
    const double load_b = ((double)ROWS * R(vr_meter_roller_torque_per_rpm_nm)
                           * shaft_rpm_per_rad_s * to_motor
                           + R(vr_motor_viscous_friction_nm_per_krpm) / 1000.0 * rpm_per_rad_s);
    const double budget = ((pow(R(vr_motor_current_limit_a), 2.0)
                            - pow(R(vr_motor_continuous_current_a), 2.0))
                           * R(vr_motor_peak_current_time_s));
    const double i_cont = R(vr_motor_continuous_current_a);
    const double ke_ra = ke / ra;
    PcDrive d = {ke, kt, ra, inv_j, kp, ki * dt, R(vr_motor_supply_v), R(vr_motor_current_limit_a),
                 i_cont, i_cont * i_cont, budget,
                 R(vr_motor_setpoint_ramp_rpm_per_s) / rpm_per_rad_s * dt, load_b,
                 0, 0, 0, 0, 0, 0};
    implicit_step(dt, kt, -ke_ra, load_b, inv_j, load_t0, &d.den_emf, &d.dwf_emf);
    implicit_step(dt, kt, 0.0, load_b, inv_j, load_t0, &d.den_lim, &d.dwf_lim);
    implicit_step(dt, kt, -kp, load_b, inv_j, load_t0, &d.den_pi, &d.dwf_pi);
    /* _meter_constants */
    const double coeff = R(vr_meter_flow_coeff_gps), expo = R(vr_meter_flow_exponent);
    const double knee = R(vr_meter_linear_below_rpm);
    const double flutes = (double)M(flutes);
    const double lsens = R(vr_fertilizer_level_sensitivity_frac);
    const double starve = R(vr_fertilizer_starvation_fill_frac);
    double slow = nearbyint(0.01 / dt);
    const long slow_steps = slow < 1.0 ? 1 : (long)slow;
    const double ou_a = exp(-((double)slow_steps * dt) / R(vr_fertilizer_density_drift_time_s));
    const double ou_b = R(vr_fertilizer_density_drift_sd_frac) * sqrt(1.0 - ou_a * ou_a);
    PcMeter m = {rpm_per_rad_s / ratio, dt / (2.0 * PI * ratio), coeff, expo, knee,
                 coeff * pow(knee, expo - 1.0), flutes, 2.0 * PI * flutes,
                 R(vr_meter_pulsation_first_harmonic_frac),
                 R(vr_meter_pulsation_second_harmonic_frac),
                 1.0 / (R(vr_fertilizer_hopper_capacity_kg) * 1000.0), lsens, starve,
                 1.0 - lsens * (1.0 - starve), starve > 0.0 ? 1.0 / starve : 0.0,
                 slow_steps, ou_a, ou_b};
    /* _bind_dt: delays in whole steps (Python's round: half to even, as nearbyint) */
    double to_sensor = nearbyint(R(vr_transport_meter_to_sensor_delay_s) / dt);
    double to_exit = nearbyint(R(vr_transport_sensor_to_exit_delay_s) / dt);
    const double tau_d = R(vr_transport_dispersion_time_s);
    const double alpha = tau_d > 0.0 ? 1.0 - exp(-dt / tau_d) : 1.0;
    /* the run's draws */
    double gain[ROWS], offsets[ROWS], cos_off[ROWS], sin_off[ROWS];
    for (int r = 0; r < ROWS; r++) {
        gain[r] = R(vr_run_row_gain_1 + r);
        offsets[r] = R(vr_run_flute_offset_1 + r);
        cos_off[r] = cos(2.0 * PI * offsets[r]);
        sin_off[r] = sin(2.0 * PI * offsets[r]);
    }
    uint64_t x = (uint64_t)(uint32_t)M(seed);
    for (int i = 0; i < 4; i++) {
        M(rng)[i] = splitmix64(&x);
    }
    M(z) = (NormalBlock){M(z_values), sizeof M(z_values) / sizeof M(z_values)[0],
                         sizeof M(z_values) / sizeof M(z_values)[0], refill, M(rng), 0};
    if (pc_init(&M(pc), ROWS, R(vr_meter_flute_charge_sd_frac),
                1.0 + R(vr_run_density_offset_frac), gain, offsets, cos_off, sin_off,
                R(vr_fertilizer_hopper_initial_kg) * 1000.0, R(vr_run_density_wander),
                &M(z)) != 0) {
        logError(comp, "the plant cannot be built (out of memory)");
        return Error;
    }
    if (pc_bind(&M(pc), dt, &d, &m, alpha, to_sensor < 1.0 ? 1 : (long)to_sensor,
                to_exit < 1.0 ? 1 : (long)to_exit) != 0) {
        logError(comp, "the plant refuses its delays or runs out of memory");
        pc_free(&M(pc));
        return Error;
    }
    M(ready) = 1;
    return OK;
}

/* Catch the plant up with the skeleton's fixed steps, the inputs held. */
static Status sync(ModelInstance *comp)
{
    if (comp->nSteps <= (uint64_t)M(steps)) {
        return OK;
    }
    if (!M(ready)) {
        Status s = start(comp);
        if (s != OK) {
            return s;
        }
    }
    const long long n = (long long)comp->nSteps - M(steps);
    const double full = R(vr_motor_command_full_scale_v);
    double v_cmd = R(vr_command_v);
    v_cmd = v_cmd < 0.0 ? 0.0 : (v_cmd > full ? full : v_cmd);
    const double w_target = v_cmd > R(vr_motor_command_deadband_v) ? v_cmd * M(w_per_v) : 0.0;
    if (pc_advance(&M(pc), n, w_target, 0, 1.0 + R(vr_run_density_offset_frac)) != 0) {
        logError(comp, "the plant's noise generator failed");
        return Error;
    }
    M(steps) = (long long)comp->nSteps;
    return OK;
}

Status eventUpdate(ModelInstance *comp)
{
    comp->valuesOfContinuousStatesChanged = false;
    comp->nominalsOfContinuousStatesChanged = false;
    comp->terminateSimulation = false;
    comp->nextEventTimeDefined = false;
    return sync(comp);
}

static double output(ModelInstance *comp, ValueReference vr)
{
    const double rpm_per_rad_s = 60.0 / (2.0 * PI);
    if (!M(ready)) {
        return 0.0;                 /* at rest before the first step */
    }
    const PlantCore *pc = &M(pc);
    switch (vr) {
    case vr_motor_speed_rpm:
        return pc->w * rpm_per_rad_s;
    case vr_shaft_speed_rpm:
        return pc->w * rpm_per_rad_s / M(ratio);
    case vr_motor_current_a:
        return pc->cur;
    case vr_delivered_total_g: {
        double sum = 0.0;
        for (int r = 0; r < ROWS; r++) {
            sum += pc->delivered[r] * pc->dt;
        }
        return sum;
    }
    case vr_metered_total_g: {
        double sum = 0.0;
        for (int r = 0; r < ROWS; r++) {
            sum += pc->metered[r] * pc->dt;
        }
        return sum;
    }
    case vr_flow_at_meter_mean_gps: {
        double sum = 0.0;
        for (int r = 0; r < ROWS; r++) {
            sum += pc->flow_at_meter[r];
        }
        return sum / ROWS;
    }
    default:
        break;
    }
    if (vr >= vr_flow_at_meter_1_gps && vr <= vr_flow_at_meter_4_gps) {
        return pc->flow_at_meter[vr - vr_flow_at_meter_1_gps];
    }
    if (vr >= vr_flow_at_sensor_1_gps && vr <= vr_flow_at_sensor_4_gps) {
        return pc->flow_at_sensor[vr - vr_flow_at_sensor_1_gps];
    }
    if (vr >= vr_delivered_1_g && vr <= vr_delivered_4_g) {
        return pc->delivered[vr - vr_delivered_1_g] * pc->dt;
    }
    return pc->passed[vr - vr_sensor_passed_1_g] * pc->dt;
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    Status s = sync(comp);
    if (s != OK) {
        return s;
    }
    if (vr == vr_time) {
        values[(*index)++] = comp->time;
    } else if (vr >= vr_command_v && vr < vr_end_of_reals) {
        values[(*index)++] = (vr == vr_command_v || vr >= vr_first_parameter) ? R(vr)
                                                                               : output(comp, vr);
    } else {
        logError(comp, "Get Float64 is not allowed for value reference %u.", vr);
        return Error;
    }
    return OK;
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    Status s = sync(comp);          /* the steps so far ran with the input they had */
    if (s != OK) {
        return s;
    }
    if (vr == vr_command_v || (vr >= vr_first_parameter && vr < vr_end_of_reals)) {
        if (vr != vr_command_v && M(ready)) {
            logError(comp, "parameter %u is fixed once the plant has started", vr);
            return Error;
        }
        R(vr) = values[(*index)++];
        return OK;
    }
    logError(comp, "Set Float64 is not allowed for value reference %u.", vr);
    return Error;
}

Status getInt32(ModelInstance *comp, ValueReference vr, int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr == vr_meter_flutes) {
        values[(*index)++] = M(flutes);
    } else if (vr == vr_seed) {
        values[(*index)++] = M(seed);
    } else {
        logError(comp, "Get Int32 is not allowed for value reference %u.", vr);
        return Error;
    }
    return OK;
}

Status setInt32(ModelInstance *comp, ValueReference vr, const int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    if (M(ready)) {
        logError(comp, "parameter %u is fixed once the plant has started", vr);
        return Error;
    }
    if (vr == vr_meter_flutes && values[*index] >= 1) {
        M(flutes) = values[(*index)++];
    } else if (vr == vr_seed) {
        M(seed) = values[(*index)++];
    } else {
        logError(comp, "Set Int32 is not allowed for value reference %u (flutes >= 1).", vr);
        return Error;
    }
    return OK;
}
