#include "depth_adapter.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "servo_cylinder_pdo.h"
#include "sowing_depth.h"

#define NMT_OPERATIONAL 0x05
#define NMT_BOOTUP 0x00
#define NMT_START 0x01
#define MODE_PROFILE_VELOCITY 3
#define STATUS_EVERY 10
#define HEARTBEAT_ID 0x701u /* node 1 */
#define INC_STATUS_OK 0
#define DS_ENABLE_ON 1
#define DS_MODE_MANUAL 0
#define DS_MODE_AUTOMATIC 1
#define DEPTH_FILTER 0.2 /* first-order filter gain per inclinometer frame */
#define J1939_SPEED_MAX_RAW 0xFAFFu
enum { DC_INITIALISING = 0, DC_READY = 1, DC_CONTROLLING = 2, DC_MANUAL = 3, DC_FAULT = 4 };
enum { SRC_GBSD = 0, SRC_GNSS = 1 };

void depth_config_defaults(depth_config_t *cfg)
{
    fpid_defaults(&cfg->core);
    cfg->min_speed_mps = 0.1;
    cfg->speed_timeout_s = 1.0;
    /* 20 reports of 10 ms with one X voltage: with the inclinometer's own noise (~1.7 mV,
     * 20 ms low-pass) two reports repeat a whole-mV value with p ~ 0.27 at standstill, 20
     * repeats (p ~ 2e-12) only a frozen output gives; each 10 ms the frozen depth is trusted
     * moves the roller (issue #16: 0.5 s left the depth up to ~2.2 mm off) */
    cfg->frozen_after_s = 0.2;
    rhold_defaults(&cfg->hold);
}

size_t depth_param_refs(depth_config_t *cfg, param_ref_t refs[DEPTH_PARAM_COUNT])
{
    size_t n = fpid_param_refs(&cfg->core, refs);
    refs[n++] = (param_ref_t){"min_speed_mps", &cfg->min_speed_mps};
    refs[n++] = (param_ref_t){"speed_timeout_s", &cfg->speed_timeout_s};
    refs[n++] = (param_ref_t){"frozen_after_s", &cfg->frozen_after_s};
    refs[n++] = (param_ref_t){"hold_time_constant_s", &cfg->hold.time_constant_s};
    refs[n++] = (param_ref_t){"hold_gain_per_s", &cfg->hold.gain_per_s};
    refs[n++] = (param_ref_t){"hold_speed_mm_s", &cfg->hold.speed_mm_s};
    return n;
}

int depth_config_check(const depth_config_t *cfg, char *err, size_t errlen)
{
    if (!(cfg->core.period_s > 0.0)) {
        snprintf(err, errlen, "period_s must be > 0");
        return -1;
    }
    if (!(cfg->core.v_max > 0.0)) {
        snprintf(err, errlen, "v_max must be > 0");
        return -1;
    }
    const char *why = NULL;
    if (rhold_check(&cfg->hold, &why) != 0) {
        snprintf(err, errlen, "%s", why);
        return -1;
    }
    if (!(cfg->hold.speed_mm_s <= cfg->core.v_max)) {
        snprintf(err, errlen, "hold_speed_mm_s must be <= v_max");
        return -1;
    }
    return 0;
}

/* Remember the order in which the speed sources first reported: of two equally fresh speeds
 * the one whose source reported first counts (the Python reference's rule). */
static void note_speed_source(depth_adapter_t *a, int source)
{
    for (int k = 0; k < a->speed_sources; k++) {
        if (a->speed_order[k] == source) {
            return;
        }
    }
    a->speed_order[a->speed_sources++] = (uint8_t)source;
}

void depth_init(depth_adapter_t *a, const depth_config_t *cfg)
{
    memset(a, 0, sizeof *a);
    a->cfg = *cfg;
    a->node = DEPTH_DRIVE_NODE;
    a->drive_nmt = -1;
    a->target_mm = 30.0;
    fpid_reset(&a->core);
    rhold_reset(&a->hold);
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

hal_can_frame_t depth_bootup(void)
{
    hal_can_frame_t f = frame_of(HEARTBEAT_ID, false, 1);
    f.data[0] = NMT_BOOTUP;
    return f;
}

uint16_t depth_next_controlword(uint16_t sw)
{
    if (sw & 0x0008u) { /* Fault (or Fault reaction active) */
        return CW_FAULT_RESET;
    }
    if ((sw & 0x004Fu) == 0x0040u) { /* Switch on disabled */
        return CW_SHUTDOWN;
    }
    if ((sw & 0x006Fu) == 0x0021u) { /* Ready to switch on */
        return CW_SWITCH_ON;
    }
    if ((sw & 0x006Fu) == 0x0023u || (sw & 0x006Fu) == 0x0027u) { /* Switched on / Op. en. */
        return CW_ENABLE_OPERATION;
    }
    return CW_SHUTDOWN; /* Not ready to switch on, Quick stop active: back to the start */
}

static bool operation_enabled(const depth_adapter_t *a)
{
    return a->have_statusword && (a->statusword & 0x006Fu) == 0x0027u;
}

size_t depth_on_frame(depth_adapter_t *a, const hal_can_frame_t *f, double now_s,
                      hal_can_frame_t out[DEPTH_MAX_OUT])
{
    size_t n = 0;
    if (!f->extended) {
        if (f->id == 0x700u + a->node && f->len >= 1) {
            a->drive_nmt = f->data[0] & 0x7F;
            if (a->drive_nmt != NMT_OPERATIONAL) {
                a->mode_sent = false; /* write the mode again once it is back */
                out[n] = frame_of(0x000, false, 2);
                out[n].data[0] = NMT_START;
                out[n].data[1] = a->node;
                n++;
            }
        } else if (f->id == 0x180u + a->node) {
            struct servo_cylinder_pdo_tpdo1_t m;
            if (servo_cylinder_pdo_tpdo1_unpack(&m, f->data, f->len) >= 0) {
                a->statusword = m.statusword;
                a->have_statusword = true;
                a->position_mm = (double)m.position_actual_value / 100.0; /* 0.01 mm */
                a->have_position = true;
            }
        } else if (f->id == 0x280u + a->node) {
            struct servo_cylinder_pdo_tpdo2_t m;
            if (servo_cylinder_pdo_tpdo2_unpack(&m, f->data, f->len) >= 0) {
                a->statusword = m.statusword;
                a->have_statusword = true;
            }
        }
        return n;
    }
    switch (f->id) {
    case SOWING_DEPTH_INCLINOMETER_FRAME_ID: {
        struct sowing_depth_inclinometer_t m;
        if (sowing_depth_inclinometer_unpack(&m, f->data, f->len) < 0) {
            break;
        }
        a->depth_ok = m.inc_x_status == INC_STATUS_OK;
        if (!a->depth_ok) {
            break;
        }
        /* [D] eq. 13, then the first-order filter */
        double x_mv = sowing_depth_inclinometer_inc_x_voltage_decode(m.inc_x_voltage);
        if (!a->have_x || x_mv != a->last_x_mv) { /* 1 mV per count: exact in a double */
            a->have_x = true;
            a->last_x_mv = x_mv;
            a->x_changed_at_s = now_s;
            rhold_mark(&a->hold); /* a sign of life: the mean so far is trusted */
        }
        double depth = -0.065 * x_mv + 270.35;
        a->depth_mm = a->have_depth ? a->depth_mm + DEPTH_FILTER * (depth - a->depth_mm)
                                    : depth;
        a->have_depth = true;
        break;
    }
    case SOWING_DEPTH_DEPTH_SETPOINT_FRAME_ID: {
        struct sowing_depth_depth_setpoint_t m;
        if (sowing_depth_depth_setpoint_unpack(&m, f->data, f->len) < 0) {
            break;
        }
        a->have_setpoint = true;
        a->target_mm = sowing_depth_depth_setpoint_ds_target_depth_decode(m.ds_target_depth);
        a->ds_enable = m.ds_enable;
        a->ds_mode = m.ds_mode;
        break;
    }
    case SOWING_DEPTH_GBSD_FRAME_ID: {
        struct sowing_depth_gbsd_t m;
        if (sowing_depth_gbsd_unpack(&m, f->data, f->len) < 0) {
            break;
        }
        note_speed_source(a, SRC_GBSD);
        if (m.gbsd_ground_speed > J1939_SPEED_MAX_RAW) {
            a->have_speed[SRC_GBSD] = false;
            break;
        }
        a->have_speed[SRC_GBSD] = true;
        a->speed_mps[SRC_GBSD] = sowing_depth_gbsd_gbsd_ground_speed_decode(m.gbsd_ground_speed);
        a->speed_at_s[SRC_GBSD] = now_s;
        break;
    }
    default:
        break;
    }
    return n;
}

void depth_on_gnss(depth_adapter_t *a, bool valid, double speed_mps, double now_s)
{
    (void)now_s; /* stamped with the time of the step that applies it */
    a->gnss_pending = true;
    a->gnss_pending_valid = valid;
    a->gnss_pending_mps = speed_mps;
}

/* The GNSS reports since the last step, at the step's time (after the step's frames). */
static void apply_gnss(depth_adapter_t *a, double now_s)
{
    if (!a->gnss_pending) {
        return;
    }
    a->gnss_pending = false;
    note_speed_source(a, SRC_GNSS);
    a->have_speed[SRC_GNSS] = a->gnss_pending_valid;
    if (a->gnss_pending_valid) {
        a->speed_mps[SRC_GNSS] = a->gnss_pending_mps;
        a->speed_at_s[SRC_GNSS] = now_s;
    }
}

/* The fresher valid ground speed; false if none is fresh. */
static bool ground_speed(const depth_adapter_t *a, double now_s, double *mps)
{
    int best = -1;
    for (int k = 0; k < a->speed_sources; k++) {
        int i = a->speed_order[k];
        if (a->have_speed[i] && now_s - a->speed_at_s[i] <= a->cfg.speed_timeout_s + 1e-9 &&
            (best < 0 || a->speed_at_s[i] > a->speed_at_s[best])) {
            best = i;
        }
    }
    if (best < 0) {
        return false;
    }
    *mps = a->speed_mps[best];
    return true;
}

/* The X voltage has not changed for more than frozen_after_s (0 or less: never). */
static bool frozen(const depth_adapter_t *a, double now_s)
{
    double limit = a->cfg.frozen_after_s;
    return limit > 0.0 && a->have_x && now_s - a->x_changed_at_s > limit + 1e-9;
}

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

/* J1939: unused bits are sent as 1. The used bits are those a message with every signal at
 * its all-ones raw value sets. */
static void pad_status(uint8_t data[8])
{
    struct sowing_depth_depth_controller_status_t ones;
    uint8_t used[8];
    memset(&ones, 0xFF, sizeof ones);
    sowing_depth_depth_controller_status_pack(used, &ones, sizeof used);
    for (int i = 0; i < 8; i++) {
        data[i] = (uint8_t)(data[i] | (uint8_t)~used[i]);
    }
}

size_t depth_step(depth_adapter_t *a, double now_s, hal_can_frame_t out[DEPTH_MAX_OUT])
{
    apply_gnss(a, now_s);
    depth_step_info_t *info = &a->last;
    memset(info, 0, sizeof *info);
    size_t n = 0;

    /* CiA 402 enable sequence; fault reset acts on a rising edge of bit 7 */
    uint16_t cw = depth_next_controlword(a->have_statusword ? a->statusword : 0);
    if (cw == CW_FAULT_RESET && a->last_controlword == CW_FAULT_RESET) {
        cw = CW_DISABLE_VOLTAGE;
    }
    a->last_controlword = cw;

    double speed_mps = 0.0;
    info->speed_known = ground_speed(a, now_s, &speed_mps);
    info->frozen = frozen(a, now_s);
    info->valid = a->have_depth && a->depth_ok && !info->frozen && operation_enabled(a);
    info->enabled = a->have_setpoint && a->ds_enable == DS_ENABLE_ON &&
                    a->ds_mode == DS_MODE_AUTOMATIC && info->speed_known &&
                    speed_mps >= a->cfg.min_speed_mps;
    info->target_mm = a->target_mm;
    info->depth_mm = a->depth_mm;
    info->out = fpid_step(&a->cfg.core, &a->core, a->target_mm,
                          a->have_depth ? a->depth_mm : 0.0, info->valid, info->enabled);
    /* where the roller is held (roller_hold.h): track the mean rod position while regulating,
     * drive the rod back to it while the depth is invalid on a running machine, forget it when
     * control is switched off (the core commands 0: the roller stays where it is) */
    if (info->enabled && info->valid) {
        if (a->have_position) {
            rhold_track(&a->cfg.hold, &a->hold, a->position_mm, a->cfg.core.period_s);
        }
    } else if (!info->enabled) {
        rhold_reset(&a->hold);
    } else if (operation_enabled(a) && a->have_position && a->hold.has_target) {
        info->holding = true;
        info->out.speed_mm_s = rhold_speed(&a->cfg.hold, &a->hold, a->position_mm);
    }
    info->hold_target_mm = a->hold.target_mm;
    info->controlword = cw;
    /* 0.01 mm/s; round half to even as Python's round() */
    info->target_velocity = (int32_t)rint(info->out.speed_mm_s * 100.0);

    if (!a->mode_sent && a->drive_nmt == NMT_OPERATIONAL) {
        struct servo_cylinder_pdo_rpdo3_t m = {MODE_PROFILE_VELOCITY};
        out[n] = frame_of(0x400u + a->node, false, SERVO_CYLINDER_PDO_RPDO3_LENGTH);
        servo_cylinder_pdo_rpdo3_pack(out[n].data, &m, sizeof out[n].data);
        n++;
        a->mode_sent = true;
    }
    if (a->steps % STATUS_EVERY == 0) {
        bool drive_fault = a->have_statusword && (a->statusword & 0x0008u) != 0;
        struct sowing_depth_depth_controller_status_t st;
        memset(&st, 0, sizeof st);
        st.dc_measured_depth = sowing_depth_depth_controller_status_dc_measured_depth_encode(
            a->have_depth ? clamp(a->depth_mm, -100.0, 200.0) : 0.0);
        /* holding: the hold target, in whole 0.01 mm (half to even, as the Python build);
         * regulating in profile velocity mode there is no position command: 0 */
        st.dc_roller_position_command =
            info->holding
                ? sowing_depth_depth_controller_status_dc_roller_position_command_encode(
                      rint(clamp(a->hold.target_mm, 0.0, 100.0) * 100.0) / 100.0)
                : 0;
        if (drive_fault) {
            st.dc_state = DC_FAULT;
        } else if (a->have_setpoint && a->ds_mode == DS_MODE_MANUAL) {
            st.dc_state = DC_MANUAL;
        } else if (info->valid && info->enabled) {
            st.dc_state = DC_CONTROLLING;
        } else if (operation_enabled(a)) {
            st.dc_state = DC_READY;
        } else {
            st.dc_state = DC_INITIALISING;
        }
        st.dc_sensor_fault = (uint8_t)(!(a->have_depth && a->depth_ok) || info->frozen);
        st.dc_drive_fault = drive_fault ? 1u : 0u;
        st.dc_speed_lost = (uint8_t)!info->speed_known;
        st.dc_counter = (uint8_t)(a->status_counter++ & 0x0Fu);
        out[n] = frame_of(SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID, true,
                          SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_LENGTH);
        sowing_depth_depth_controller_status_pack(out[n].data, &st, sizeof out[n].data);
        pad_status(out[n].data);
        n++;

        out[n] = frame_of(HEARTBEAT_ID, false, 1);
        out[n].data[0] = NMT_OPERATIONAL;
        n++;
    }
    /* the command frame goes last: in lockstep it ends the step (the rig's SYNC barrier
     * waits for it), so the status and heartbeat go on the bus before it. A DUT that sends
     * its frames in another order ends each step with the step-end frame instead
     * (HAL_CAN_STEP_END_ID; docs/guide/clocks.md, "Where a step ends") */
    struct servo_cylinder_pdo_rpdo2_t pdo;
    memset(&pdo, 0, sizeof pdo);
    pdo.controlword = cw;
    pdo.target_velocity = info->target_velocity;
    out[n] = frame_of(0x300u + a->node, false, SERVO_CYLINDER_PDO_RPDO2_LENGTH);
    servo_cylinder_pdo_rpdo2_pack(out[n].data, &pdo, sizeof out[n].data);
    n++;
    a->steps++;
    return n;
}
