#include "fertilizer_rc400_adapter.h"

#include <math.h>
#include <string.h>

/* The database's units to the law's (dbc_adapter.py TO_LAW_UNITS): value_law = value x f.
 * Written as the Python build computes them, so the products are the same doubles. */
#define KGH_TO_GPS (1.0 / 3.6)
#define KMH_TO_MPS (1.0 / 3.6)
#define MM_TO_M 0.001
#define KGHA_TO_KGHA 1.0
#define MPS_TO_MPS 1.0

#define STATUS_EVERY 5           /* RC_Status: 500 ms at the 100 ms control period */
#define MAX_VALID_SPEED_MPS 64.255 /* J1939 "not available" decodes above it */
#define STALE_SLACK_STEPS 1e-9
#define STATUS_FLOW_MAX_KGH 2000.0 /* RC_Status TargetKgH / ActualKgH: [0|2000] kg/h */
#define COMMAND_MAX_MV 10000.0     /* DriveCommand SpeedRef: [0|10000] mV */

/* CiA 301 */
#define HEARTBEAT_BASE 0x700u
#define SDO_RX_BASE 0x600u
#define SDO_DOWNLOAD_EXPEDITED_4 0x23u
#define CONSUMER_HEARTBEAT_INDEX 0x1016u
#define CONSUMER_HEARTBEAT_MS 300u

enum { SPEED_HALL = 0, SPEED_WHEEL = 1, SPEED_GROUND = 2, SPEED_NONE = -1 };

void rc400_config_defaults(rc400_config_t *cfg, ppid_law_t law)
{
    ppid_defaults(&cfg->core, law);
    cfg->stale_after_s = 2.5;
    cfg->period_s = 0.1;
    cfg->ground_speed_first_s = 0.3;
}

size_t rc400_param_refs(rc400_config_t *cfg, param_ref_t refs[RC400_PARAM_COUNT])
{
    size_t n = ppid_param_refs(&cfg->core, refs);
    refs[n++] = (param_ref_t){"stale_after_s", &cfg->stale_after_s};
    refs[n++] = (param_ref_t){"period_s", &cfg->period_s};
    refs[n++] = (param_ref_t){"ground_speed_first_s", &cfg->ground_speed_first_s};
    return n;
}

void rc400_init(rc400_adapter_t *a, const rc400_config_t *cfg)
{
    memset(a, 0, sizeof *a);
    a->cfg = *cfg;
    a->active_mode = -1;
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

static hal_can_frame_t heartbeat(uint8_t state)
{
    struct ratemaster_rc400_rc_heartbeat_t hb = {state};
    hal_can_frame_t f = frame_of(RATEMASTER_RC400_RC_HEARTBEAT_FRAME_ID,
                                 RATEMASTER_RC400_RC_HEARTBEAT_IS_EXTENDED,
                                 RATEMASTER_RC400_RC_HEARTBEAT_LENGTH);
    ratemaster_rc400_rc_heartbeat_pack(f.data, &hb, sizeof f.data);
    return f;
}

size_t rc400_boot_frames(hal_can_frame_t out[RC400_BOOT_FRAMES])
{
    out[0] = heartbeat(RATEMASTER_RC400_RC_HEARTBEAT_NMT_STATE_BOOT_UP_CHOICE);
    /* as a CANopen master at node 0x12: the drive module watches our heartbeat, so it stops
     * the motor when we fall silent (0x1016 sub 1 = node << 16 | time in ms) */
    struct ratemaster_rc400_drive_sdo_request_t sdo;
    memset(&sdo, 0, sizeof sdo);
    sdo.command = SDO_DOWNLOAD_EXPEDITED_4;
    sdo.index = CONSUMER_HEARTBEAT_INDEX;
    sdo.sub_index = 1;
    sdo.data = ((RATEMASTER_RC400_RC_HEARTBEAT_FRAME_ID - HEARTBEAT_BASE) << 16) |
               CONSUMER_HEARTBEAT_MS;
    out[1] = frame_of(RATEMASTER_RC400_DRIVE_SDO_REQUEST_FRAME_ID,
                      RATEMASTER_RC400_DRIVE_SDO_REQUEST_IS_EXTENDED,
                      RATEMASTER_RC400_DRIVE_SDO_REQUEST_LENGTH);
    ratemaster_rc400_drive_sdo_request_pack(out[1].data, &sdo, sizeof out[1].data);
    return RC400_BOOT_FRAMES;
}

/* The J1939 PGN of a 29-bit id (PDU1: the destination byte is not part of it). */
static uint32_t pgn_of(uint32_t id)
{
    uint32_t pgn = (id >> 8) & 0x3FFFFu;
    return ((pgn >> 8) & 0xFFu) < 240u ? (pgn & 0x3FF00u) : pgn;
}

static void set_speed(rc400_adapter_t *a, int source, double mps)
{
    bool valid = mps >= 0.0 && mps <= MAX_VALID_SPEED_MPS;
    a->speed_mps[source] = valid ? mps : 0.0;
    if (source == SPEED_GROUND) {
        a->ground_heard = valid;
        a->ground_at_step = a->steps;
    }
}

/* speeds.py GroundSpeedFirst.fresh: a valid radar speed heard within ground_speed_first_s */
static bool ground_fresh(const rc400_adapter_t *a)
{
    return a->cfg.ground_speed_first_s > 0.0 && a->ground_heard &&
           (double)(a->steps - a->ground_at_step) <=
               a->cfg.ground_speed_first_s / a->cfg.period_s + STALE_SLACK_STEPS;
}

/* One row of RH_RowFlow: the multiplexer selects which row's signals the frame carries. */
static void on_row_flow(rc400_adapter_t *a, const hal_can_frame_t *f)
{
    struct ratemaster_rc400_rh_row_flow_t m;
    memset(&m, 0, sizeof m);
    if (ratemaster_rc400_rh_row_flow_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    double flow_kgh;
    bool measuring, overrange;
    switch (m.row_no) { /* RowNo 0-3 = rows 1-4 (the binding's rows = [0, 1, 2, 3]) */
    case 0:
        flow_kgh = ratemaster_rc400_rh_row_flow_flow_kg_h_1_decode(m.flow_kg_h_1);
        measuring = m.state_1 == RATEMASTER_RC400_RH_ROW_FLOW_STATE_1_MEASURING_CHOICE;
        overrange = m.diag_1 == RATEMASTER_RC400_RH_ROW_FLOW_DIAG_1_CAP_OVERRANGE_CHOICE;
        break;
    case 1:
        flow_kgh = ratemaster_rc400_rh_row_flow_flow_kg_h_2_decode(m.flow_kg_h_2);
        measuring = m.state_2 == RATEMASTER_RC400_RH_ROW_FLOW_STATE_2_MEASURING_CHOICE;
        overrange = m.diag_2 == RATEMASTER_RC400_RH_ROW_FLOW_DIAG_2_CAP_OVERRANGE_CHOICE;
        break;
    case 2:
        flow_kgh = ratemaster_rc400_rh_row_flow_flow_kg_h_3_decode(m.flow_kg_h_3);
        measuring = m.state_3 == RATEMASTER_RC400_RH_ROW_FLOW_STATE_3_MEASURING_CHOICE;
        overrange = m.diag_3 == RATEMASTER_RC400_RH_ROW_FLOW_DIAG_3_CAP_OVERRANGE_CHOICE;
        break;
    case 3:
        flow_kgh = ratemaster_rc400_rh_row_flow_flow_kg_h_4_decode(m.flow_kg_h_4);
        measuring = m.state_4 == RATEMASTER_RC400_RH_ROW_FLOW_STATE_4_MEASURING_CHOICE;
        overrange = m.diag_4 == RATEMASTER_RC400_RH_ROW_FLOW_DIAG_4_CAP_OVERRANGE_CHOICE;
        break;
    default: /* a multiplexer value the database does not define */
        return;
    }
    a->rows[m.row_no] = (rc400_row_t){true, flow_kgh * KGH_TO_GPS, measuring, overrange,
                                      a->steps, true};
}

static void on_extended(rc400_adapter_t *a, const hal_can_frame_t *f)
{
    uint32_t pgn = pgn_of(f->id);
    if (pgn == pgn_of(RATEMASTER_RC400_WHEEL_BASED_SPEED_DIST_FRAME_ID)) {
        struct ratemaster_rc400_wheel_based_speed_dist_t m;
        if (ratemaster_rc400_wheel_based_speed_dist_unpack(&m, f->data, f->len) >= 0) {
            set_speed(a, SPEED_WHEEL,
                      ratemaster_rc400_wheel_based_speed_dist_wheel_based_machine_speed_decode(
                          m.wheel_based_machine_speed) * MPS_TO_MPS);
        }
    } else if (pgn == pgn_of(RATEMASTER_RC400_GROUND_BASED_SPEED_DIST_FRAME_ID)) {
        struct ratemaster_rc400_ground_based_speed_dist_t m;
        if (ratemaster_rc400_ground_based_speed_dist_unpack(&m, f->data, f->len) >= 0) {
            set_speed(a, SPEED_GROUND,
                      ratemaster_rc400_ground_based_speed_dist_ground_based_machine_speed_decode(
                          m.ground_based_machine_speed) * MPS_TO_MPS);
        }
    }
}

void rc400_on_frame(rc400_adapter_t *a, const hal_can_frame_t *f)
{
    if (f->extended) {
        on_extended(a, f);
        return;
    }
    switch (f->id) {
    case RATEMASTER_RC400_RC_COMMAND_FRAME_ID: {
        struct ratemaster_rc400_rc_command_t m;
        if (ratemaster_rc400_rc_command_unpack(&m, f->data, f->len) >= 0) {
            a->setpoint = m;
            a->has_setpoint = true;
        }
        break;
    }
    case RATEMASTER_RC400_RH_ROW_FLOW_FRAME_ID:
        on_row_flow(a, f);
        break;
    case RATEMASTER_RC400_WS_GROUND_SPEED_FRAME_ID: {
        struct ratemaster_rc400_ws_ground_speed_t m;
        if (ratemaster_rc400_ws_ground_speed_unpack(&m, f->data, f->len) >= 0) {
            set_speed(a, SPEED_HALL,
                      ratemaster_rc400_ws_ground_speed_speed_kmh_decode(m.speed_kmh) *
                          KMH_TO_MPS);
        }
        break;
    }
    default:
        break;
    }
}

static bool enabled(const rc400_adapter_t *a)
{
    return a->has_setpoint && a->setpoint.run == 1u;
}

rc400_mode_t rc400_mode(const rc400_adapter_t *a)
{
    if (!a->has_setpoint) {
        return RC400_MODE_BENCH;
    }
    switch (a->setpoint.program) {
    case RATEMASTER_RC400_RC_COMMAND_PROGRAM_SPEED_RELATED_CHOICE:
        return RC400_MODE_FIELD;
    case RATEMASTER_RC400_RC_COMMAND_PROGRAM_FIXED_SPEED_CHOICE:
        return RC400_MODE_CONSTANT;
    case RATEMASTER_RC400_RC_COMMAND_PROGRAM_FIXED_RATE_CHOICE:
    default: /* Off, or a value the database does not name */
        return RC400_MODE_BENCH;
    }
}

/* The RC-400's program number of a mode (the status reports the program it runs). */
static uint8_t program_of(rc400_mode_t mode)
{
    switch (mode) {
    case RC400_MODE_FIELD:
        return RATEMASTER_RC400_RC_STATUS_PROGRAM_ACTIVE_SPEED_RELATED_CHOICE;
    case RC400_MODE_CONSTANT:
        return RATEMASTER_RC400_RC_STATUS_PROGRAM_ACTIVE_FIXED_SPEED_CHOICE;
    case RC400_MODE_BENCH:
    default:
        return RATEMASTER_RC400_RC_STATUS_PROGRAM_ACTIVE_FIXED_RATE_CHOICE;
    }
}

static int speed_source(uint8_t speed_src)
{
    switch (speed_src) {
    case RATEMASTER_RC400_RC_COMMAND_SPEED_SRC_WHEEL_SENSOR_CHOICE:
        return SPEED_HALL;
    case RATEMASTER_RC400_RC_COMMAND_SPEED_SRC_TRACTOR_WHEEL_CHOICE:
        return SPEED_WHEEL;
    case RATEMASTER_RC400_RC_COMMAND_SPEED_SRC_RADAR_CHOICE:
        return SPEED_GROUND;
    default: /* None */
        return SPEED_NONE;
    }
}

double rc400_target_gps(const rc400_adapter_t *a)
{
    if (!enabled(a)) {
        return 0.0;
    }
    const struct ratemaster_rc400_rc_command_t *s = &a->setpoint;
    if (rc400_mode(a) == RC400_MODE_FIELD) { /* eq. (1) Q = 0.1 M D v, shared by the rows */
        int source = speed_source(s->speed_src);
        double speed = source == SPEED_NONE ? 0.0
                       : a->speed_mps[ground_fresh(a) ? SPEED_GROUND : source];
        double rows = s->sections > 1u ? (double)s->sections : 1.0;
        double rate = ratemaster_rc400_rc_command_rate_kg_ha_decode(s->rate_kg_ha) *
                      KGHA_TO_KGHA;
        double width = ratemaster_rc400_rc_command_width_mm_decode(s->width_mm) * MM_TO_M;
        return 0.1 * rate * width * speed / rows;
    }
    return ratemaster_rc400_rc_command_target_kg_h_decode(s->target_kg_h) * KGH_TO_GPS;
}

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

/* The rows' mean flow, whether any is valid, whether a valid one reported since the last step
 * (rows in ascending order, as the Python build sums them); clears the fresh flags. A row that
 * passes its own checks and disagrees with the others is left out (core/cross_row.h). */
static void measure(rc400_adapter_t *a, double target, rc400_step_info_t *info)
{
    double stale_steps = a->cfg.stale_after_s / a->cfg.period_s;
    double flows[RC400_ROWS];
    bool passed[RC400_ROWS];
    bool excluded[RC400_ROWS];
    bool fresh_row[RC400_ROWS];
    /* rows 1..Sections meter once a command has come (the others' clutches are out and their
     * modules read 0), all before one: the Python build's active_rows() */
    int active = RC400_ROWS;
    if (a->has_setpoint) {
        active = a->setpoint.sections > 1u ? (int)a->setpoint.sections : 1;
    }
    for (int i = 0; i < RC400_ROWS; i++) {
        rc400_row_t *r = &a->rows[i];
        flows[i] = r->flow_gps;
        fresh_row[i] = r->fresh;
        passed[i] = i < active && r->seen && r->measuring && !r->overrange &&
                    (double)(a->steps - r->at_step) <= stale_steps + STALE_SLACK_STEPS &&
                    r->flow_gps <= 3.0 * target + 5.0;
        r->fresh = false;
    }
    xrow_step(&a->xrow, RC400_ROWS, flows, passed, excluded);
    info->has_measurement = xrow_kept_mean(RC400_ROWS, flows, passed, excluded, fresh_row,
                                           &info->measured_gps, &info->new_report);
}

static uint16_t millivolts(double volts)
{
    /* round half to even (rint in the default rounding mode), as Python's round() */
    return (uint16_t)rint(clamp(volts * 1000.0, 0.0, COMMAND_MAX_MV));
}

/* cantools' Python encoder (the Python build's) rounds (value - offset) / scale half to even;
 * the generated encoders round half away from zero. A mean of the rows' flows, which come in
 * steps of the same scale, often falls on exactly half a step, so the status flows are
 * rounded as Python does, with the scale (and zero offset) the generated decoder applies. */
static uint16_t status_flow_raw(double (*decode)(uint16_t), double kgh)
{
    return (uint16_t)rint((kgh - decode(0)) / decode(1));
}

static hal_can_frame_t status_frame(const rc400_adapter_t *a, const rc400_step_info_t *info)
{
    struct ratemaster_rc400_rc_status_t st;
    memset(&st, 0, sizeof st);
    double measured = info->has_measurement ? info->measured_gps : 0.0;
    st.target_kg_h = status_flow_raw(ratemaster_rc400_rc_status_target_kg_h_decode,
                                     clamp(info->target_gps / KGH_TO_GPS, 0.0,
                                           STATUS_FLOW_MAX_KGH));
    st.actual_kg_h = status_flow_raw(ratemaster_rc400_rc_status_actual_kg_h_decode,
                                     clamp(measured / KGH_TO_GPS, 0.0, STATUS_FLOW_MAX_KGH));
    st.drive_mv = millivolts(info->out.volts);
    st.loop = info->out.segment; /* 0 Idle, 1 Fine, 2 Medium, 3 Coarse: the core's segments */
    st.program_active = program_of(info->mode);
    st.running = enabled(a) ? 1u : 0u;
    st.flow_alarm = info->alarm ? 1u : 0u;
    st.seq = (uint8_t)(a->steps & 0xFFu);
    hal_can_frame_t f = frame_of(RATEMASTER_RC400_RC_STATUS_FRAME_ID,
                                 RATEMASTER_RC400_RC_STATUS_IS_EXTENDED,
                                 RATEMASTER_RC400_RC_STATUS_LENGTH);
    ratemaster_rc400_rc_status_pack(f.data, &st, sizeof f.data);
    return f;
}

size_t rc400_step(rc400_adapter_t *a, hal_can_frame_t out[RC400_MAX_OUT])
{
    rc400_step_info_t *info = &a->last;
    memset(info, 0, sizeof *info);
    info->target_gps = rc400_target_gps(a);
    info->mode = rc400_mode(a);
    if ((int)info->mode != a->active_mode) {
        ppid_reset(&a->core); /* a new program starts the law from a clean state */
        a->active_mode = (int)info->mode;
    }
    measure(a, info->target_gps, info);
    ppid_law_t law = info->mode == RC400_MODE_CONSTANT ? PPID_LAW_OPEN_LOOP : a->cfg.core.law;
    info->law = law;
    ppid_params_t params = a->cfg.core;
    params.law = law;
    info->out = ppid_step(&params, &a->core, info->target_gps, info->measured_gps,
                          info->has_measurement, info->new_report);
    info->alarm = law != PPID_LAW_OPEN_LOOP && enabled(a) && !info->has_measurement;

    size_t n = 0;
    if (a->steps % STATUS_EVERY == 0) {
        out[n++] = status_frame(a, info);
    }
    out[n++] = heartbeat(RATEMASTER_RC400_RC_HEARTBEAT_NMT_STATE_OPERATIONAL_CHOICE);
    /* the drive command last: in lockstep it ends the step (the rig's SYNC barrier waits for
     * it), so the status and heartbeat are on the bus before it */
    struct ratemaster_rc400_drive_command_t cmd = {(int16_t)millivolts(info->out.volts)};
    out[n] = frame_of(RATEMASTER_RC400_DRIVE_COMMAND_FRAME_ID,
                      RATEMASTER_RC400_DRIVE_COMMAND_IS_EXTENDED,
                      RATEMASTER_RC400_DRIVE_COMMAND_LENGTH);
    ratemaster_rc400_drive_command_pack(out[n].data, &cmd, sizeof out[n].data);
    n++;
    a->steps++;
    return n;
}
