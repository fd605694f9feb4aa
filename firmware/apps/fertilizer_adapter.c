#include "fertilizer_adapter.h"

#include <math.h>
#include <string.h>

#include "fertilizer.h"

#define NMT_OPERATIONAL 0x05
#define NMT_BOOTUP 0x00
#define STATUS_EVERY 10
#define J1939_SPEED_MAX_RAW 0xFAFFu /* above: error / not available */
#define STALE_SLACK_S 1e-9          /* k steps of T summed in double may exceed k*T by an ulp */

void fert_config_defaults(fert_config_t *cfg, ppid_law_t law)
{
    ppid_defaults(&cfg->core, law);
    cfg->stale_after_s = 2.5;
    cfg->period_s = 0.1;
    cfg->ground_speed_first_s = 0.3;
    cfg->use_calibration = 1.0;
}

size_t fert_common_param_refs(fert_config_t *cfg, param_ref_t refs[FERT_COMMON_PARAM_COUNT])
{
    size_t n = ppid_param_refs(&cfg->core, refs);
    refs[n++] = (param_ref_t){"stale_after_s", &cfg->stale_after_s};
    refs[n++] = (param_ref_t){"period_s", &cfg->period_s};
    return n;
}

size_t fert_param_refs(fert_config_t *cfg, param_ref_t refs[FERT_PARAM_COUNT])
{
    size_t n = fert_common_param_refs(cfg, refs);
    refs[n++] = (param_ref_t){"ground_speed_first_s", &cfg->ground_speed_first_s};
    refs[n++] = (param_ref_t){"use_calibration", &cfg->use_calibration};
    return n;
}

void fert_init(fert_adapter_t *a, const fert_config_t *cfg)
{
    memset(a, 0, sizeof *a);
    a->cfg = *cfg;
    a->active_mode = -1;
    a->rows_follow_setpoint = true;
    ppid_reset(&a->core);
    xrow_init(&a->xrow, cfg->period_s);
}

static hal_can_frame_t frame_of(uint32_t id, bool extended, uint8_t len)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.extended = extended;
    f.len = len;
    return f;
}

hal_can_frame_t fert_bootup(void)
{
    hal_can_frame_t f = frame_of(FERTILIZER_CONTROLLER_HEARTBEAT_FRAME_ID, false,
                                 FERTILIZER_CONTROLLER_HEARTBEAT_LENGTH);
    f.data[0] = NMT_BOOTUP;
    return f;
}

static void on_flow(fert_adapter_t *a, int row, const hal_can_frame_t *f, double now_s)
{
    /* the four modules share one layout */
    struct fertilizer_flow_module1_t m;
    if (fertilizer_flow_module1_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    fert_row_t *r = &a->rows[row];
    r->seen = true;
    r->flow_gps = fertilizer_flow_module1_flow_decode(m.flow);
    r->baseline_ready = m.baseline_ready != 0;
    r->overrange = m.adc_overrange != 0;
    r->at_s = now_s;
    r->reported = true;
}

static void on_speed(fert_adapter_t *a, int source, uint16_t raw, double value, double now_s)
{
    /* J1939 error / not available decode above the valid range: no speed */
    bool valid = !(source > 0 && raw > J1939_SPEED_MAX_RAW);
    a->speed[source] = (fert_speed_t){valid, valid ? value : 0.0};
    if (source == 2) {
        a->ground_at_s = now_s;
    }
}

/* speeds.py GroundSpeedFirst.fresh: a valid PGN 65097 speed heard within ground_speed_first_s */
static bool ground_fresh(const fert_adapter_t *a, double now_s)
{
    return a->cfg.ground_speed_first_s > 0.0 && a->speed[2].seen &&
           now_s - a->ground_at_s <= a->cfg.ground_speed_first_s + STALE_SLACK_S;
}

#define FF_COEFF_MAX 100.0 /* the core's own bound on ff_coeff: above it no fluted roller */

double fert_ff_coeff_from_test(double grams_per_rev, double shaft_rpm, double ff_exponent,
                               double ff_linear_below_rpm)
{
    if (!(grams_per_rev > 0.0 && shaft_rpm > 0.0)) {
        return 0.0;
    }
    double n_ref = shaft_rpm > ff_linear_below_rpm ? shaft_rpm : ff_linear_below_rpm;
    double coeff = grams_per_rev / 60.0 * pow(n_ref, 1.0 - ff_exponent);
    return coeff > 0.0 && coeff <= FF_COEFF_MAX ? coeff : 0.0;
}

static void on_calibration(fert_adapter_t *a, const hal_can_frame_t *f)
{
    struct fertilizer_meter_calibration_t m;
    if (a->cfg.use_calibration == 0.0 ||
        fertilizer_meter_calibration_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    ppid_params_t *p = &a->cfg.core;
    double coeff = fert_ff_coeff_from_test(
        fertilizer_meter_calibration_grams_per_rev_decode(m.grams_per_rev),
        fertilizer_meter_calibration_test_shaft_speed_decode(m.test_shaft_speed), p->ff_exponent,
        p->ff_linear_below_rpm);
    if (coeff > 0.0) {
        p->ff_coeff = coeff;
    }
}

void fert_on_frame(fert_adapter_t *a, const hal_can_frame_t *f, double now_s)
{
    if (f->extended) {
        if (f->id == FERTILIZER_WHEEL_BASED_SPEED_DIST_FRAME_ID) {
            struct fertilizer_wheel_based_speed_dist_t m;
            if (fertilizer_wheel_based_speed_dist_unpack(&m, f->data, f->len) >= 0) {
                on_speed(a, 1, m.wheel_based_machine_speed,
                         fertilizer_wheel_based_speed_dist_wheel_based_machine_speed_decode(
                             m.wheel_based_machine_speed), now_s);
            }
        } else if (f->id == FERTILIZER_GROUND_BASED_SPEED_DIST_FRAME_ID) {
            struct fertilizer_ground_based_speed_dist_t m;
            if (fertilizer_ground_based_speed_dist_unpack(&m, f->data, f->len) >= 0) {
                on_speed(a, 2, m.ground_based_machine_speed,
                         fertilizer_ground_based_speed_dist_ground_based_machine_speed_decode(
                             m.ground_based_machine_speed), now_s);
            }
        }
        return;
    }
    switch (f->id) {
    case FERTILIZER_FERT_SETPOINT_FRAME_ID: {
        struct fertilizer_fert_setpoint_t m;
        if (fertilizer_fert_setpoint_unpack(&m, f->data, f->len) < 0) {
            return;
        }
        fert_setpoint_t *s = &a->setpoint;
        s->seen = true;
        s->mode = m.mode;
        s->enable = m.enable != 0;
        s->target_rate = fertilizer_fert_setpoint_target_rate_decode(m.target_rate);
        s->working_width = fertilizer_fert_setpoint_working_width_decode(m.working_width);
        s->target_flow = fertilizer_fert_setpoint_target_flow_decode(m.target_flow);
        s->speed_source = m.speed_source;
        s->active_rows = m.active_rows;
        break;
    }
    case FERTILIZER_FLOW_MODULE1_FRAME_ID:
    case FERTILIZER_FLOW_MODULE2_FRAME_ID:
    case FERTILIZER_FLOW_MODULE3_FRAME_ID:
    case FERTILIZER_FLOW_MODULE4_FRAME_ID:
        on_flow(a, (int)(f->id - FERTILIZER_FLOW_MODULE1_FRAME_ID), f, now_s);
        break;
    case FERTILIZER_METER_CALIBRATION_FRAME_ID:
        on_calibration(a, f);
        break;
    case FERTILIZER_GROUND_WHEEL_SPEED_FRAME_ID: {
        struct fertilizer_ground_wheel_speed_t m;
        if (fertilizer_ground_wheel_speed_unpack(&m, f->data, f->len) >= 0) {
            on_speed(a, 0, m.wheel_speed,
                     fertilizer_ground_wheel_speed_wheel_speed_decode(m.wheel_speed), now_s);
        }
        break;
    }
    default:
        break;
    }
}

/* Per-row target flow (g/s) from the setpoint, 0 when disabled or not computable. */
static double target_gps(const fert_adapter_t *a, double now_s)
{
    const fert_setpoint_t *s = &a->setpoint;
    if (!s->seen || !s->enable) {
        return 0.0;
    }
    switch (s->mode) {
    case 0: { /* field: eq. (1) Q = 0.1 M D v, shared by the active rows */
        if (s->speed_source > 2) {
            return 0.0;
        }
        const fert_speed_t *v = ground_fresh(a, now_s) ? &a->speed[2] : &a->speed[s->speed_source];
        if (!v->seen) {
            return 0.0;
        }
        double rows = s->active_rows > 0 ? (double)s->active_rows : 1.0;
        return 0.1 * s->target_rate * s->working_width * v->mps / rows;
    }
    case 1: /* bench */
    case 2: /* constant speed: open loop at the flow-map speed for TargetFlow */
        return s->target_flow;
    default:
        return 0.0;
    }
}

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

size_t fert_step(fert_adapter_t *a, double now_s, hal_can_frame_t out[FERT_MAX_OUT])
{
    fert_step_info_t *info = &a->last;
    memset(info, 0, sizeof *info);
    double q = target_gps(a, now_s);
    info->target_gps = q;

    /* valid rows: baseline acquired, in range, fresh, plausible (Flow <= 3 Q + 5), and in
     * agreement with the other valid rows (core/cross_row.h) */
    double flows[FERT_ROWS];
    bool passed[FERT_ROWS];
    bool excluded[FERT_ROWS];
    bool reported[FERT_ROWS];
    /* rows 1..ActiveRows meter; the others' clutches are out (their modules read 0) */
    int active = a->rows_follow_setpoint && a->setpoint.seen && a->setpoint.active_rows > 0
                     ? (int)a->setpoint.active_rows
                     : FERT_ROWS;
    for (int i = 0; i < FERT_ROWS; i++) {
        fert_row_t *r = &a->rows[i];
        flows[i] = r->flow_gps;
        reported[i] = r->reported;
        passed[i] = i < active && r->seen && r->baseline_ready && !r->overrange &&
                    now_s - r->at_s <= a->cfg.stale_after_s + STALE_SLACK_S &&
                    r->flow_gps <= 3.0 * q + 5.0;
        r->reported = false;
    }
    xrow_step(&a->xrow, FERT_ROWS, flows, passed, excluded);
    info->has_measurement = xrow_kept_mean(FERT_ROWS, flows, passed, excluded, reported,
                                           &info->measured_gps, &info->new_report);

    int mode = a->setpoint.seen ? a->setpoint.mode : 1;
    if (mode != a->active_mode) {
        ppid_reset(&a->core); /* a new terminal mode starts the law from a clean state */
        a->active_mode = mode;
    }
    ppid_law_t law = mode == 2 ? PPID_LAW_OPEN_LOOP : a->cfg.core.law;
    info->law = law;
    ppid_params_t params = a->cfg.core;
    params.law = law;
    info->out = ppid_step(&params, &a->core, q, info->measured_gps, info->has_measurement,
                          info->new_report);
    info->sensor_fault = a->setpoint.seen && a->setpoint.enable && law != PPID_LAW_OPEN_LOOP &&
                         !info->has_measurement;

    size_t n = 0;

    if (a->steps % STATUS_EVERY == 0) {
        struct fertilizer_controller_status_t st;
        memset(&st, 0, sizeof st);
        /* the generated encoders round halves away from zero; Python's cantools rounds them
         * to even (round()): rint in the default rounding mode, on the same quotient, gives
         * the Python build's frames when a value lands on a half step */
        st.target_flow = (uint16_t)rint(clamp(q, 0.0, 250.0) / 0.01);
        st.measured_flow = (uint16_t)rint(clamp(info->measured_gps, 0.0, 250.0) / 0.01);
        st.command_voltage = (uint16_t)rint(clamp(info->out.volts, 0.0, 10.0) / 0.001);
        st.pid_segment = info->out.segment;
        st.active_mode = (uint8_t)(mode & 0x3);
        st.enabled = a->setpoint.enable ? 1u : 0u;
        st.sensor_fault = info->sensor_fault ? 1u : 0u;
        st.counter = (uint8_t)(a->steps & 0xFFu);
        out[n] = frame_of(FERTILIZER_CONTROLLER_STATUS_FRAME_ID, false,
                          FERTILIZER_CONTROLLER_STATUS_LENGTH);
        fertilizer_controller_status_pack(out[n].data, &st, sizeof out[n].data);
        n++;
    }

    struct fertilizer_controller_heartbeat_t hb = {NMT_OPERATIONAL};
    out[n] = frame_of(FERTILIZER_CONTROLLER_HEARTBEAT_FRAME_ID, false,
                      FERTILIZER_CONTROLLER_HEARTBEAT_LENGTH);
    fertilizer_controller_heartbeat_pack(out[n].data, &hb, sizeof out[n].data);
    n++;

    /* the command frame goes last: in lockstep it ends the step (the rig's SYNC barrier
     * waits for it), so the status and heartbeat go on the bus before it. A DUT that sends
     * its frames in another order ends each step with the step-end frame instead
     * (HAL_CAN_STEP_END_ID; docs/guide/clocks.md, "Where a step ends") */
    struct fertilizer_analog_output_command_t cmd = {0, 0};
    /* round half to even (rint in the default rounding mode), as Python's round() */
    cmd.ch1_output = (int16_t)rint(clamp(info->out.volts, 0.0, 10.0) * 1000.0);
    out[n] = frame_of(FERTILIZER_ANALOG_OUTPUT_COMMAND_FRAME_ID, false,
                      FERTILIZER_ANALOG_OUTPUT_COMMAND_LENGTH);
    fertilizer_analog_output_command_pack(out[n].data, &cmd, sizeof out[n].data);
    n++;
    a->steps++;
    return n;
}
