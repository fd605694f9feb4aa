#include "iso_fert.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fertilizer.h"
#include "iso_pool.h"

#define SYNC_ID 0x080u
#define FLOW_MODULE1_ID 0x181u
#define PGN_WHEEL_BASED_SPEED 0xFE48u
#define PGN_GROUND_BASED_SPEED 0xFE49u
#define MAX_VALID_SPEED_MPS 64.255 /* above: J1939 error / not available */
#define MG_PER_M2_PER_KG_HA 100.0
#define MAX_RATE_KG_HA 1000.0
#define MIN_REPORT_SPEED_MPS 0.05
#define RATE_CONTROL_FUNCTION 128u
#define DEVICE_CLASS_FERTILIZERS 5u
#define INDUSTRY_GROUP_AGRICULTURE 2u
#define SPEED_SLACK_S 1e-9
#define STALE_SLACK_S 1e-9 /* as apps/fertilizer_adapter.c's row validity */
#define ROW_RATE_MIN_SPEED_MPS 0.05
#define TIME_SLACK_S 1e-9
enum { GROUND = 0, WHEEL = 1 };

void iso_fert_config_defaults(iso_fert_config_t *cfg, ppid_law_t law)
{
    memset(cfg, 0, sizeof *cfg);
    fert_config_defaults(&cfg->fert, law);
    cfg->address = 0x81;
    cfg->identity_number = 0x0F27;
    cfg->width_m = 3.0;
    cfg->step_on_sync = true;
}

size_t iso_fert_param_refs(iso_fert_config_t *cfg, param_ref_t refs[ISO_FERT_PARAM_COUNT])
{
    /* not ground_speed_first_s: the implement always prefers PGN 65097 (iso_fert_ground_speed) */
    size_t n = fert_common_param_refs(&cfg->fert, refs);
    refs[n++] = (param_ref_t){"address", &cfg->address};
    refs[n++] = (param_ref_t){"identity_number", &cfg->identity_number};
    refs[n++] = (param_ref_t){"width_m", &cfg->width_m};
    return n;
}

static const char *const VT_DEFECTS[] = {"",
                                          "ignores-master",
                                          "no-alarm",
                                          "bad-pool",
                                          "no-reconnect",
                                          "meters-without-vt",
                                          "no-store",
                                          "slow-maintenance",
                                          "ignores-calibration"};

int iso_fert_vt_param(iso_fert_config_t *cfg, const char *key, const char *value,
                      const char **why)
{
    if (param_name_equal(key, "vt")) {
        if (strcmp(value, "yes") != 0 && strcmp(value, "no") != 0) {
            *why = "parameter 'vt' must be yes or no";
            return -1;
        }
        cfg->vt = strcmp(value, "yes") == 0;
        return 1;
    }
    if (param_name_equal(key, "vt_defect")) {
        for (size_t i = 0; i < sizeof VT_DEFECTS / sizeof VT_DEFECTS[0]; i++) {
            if (strcmp(value, VT_DEFECTS[i]) == 0) {
                cfg->vt_defect = (iso_vt_defect_t)i;
                return 1;
            }
        }
        *why = "parameter 'vt_defect' must be one of '', 'ignores-master', 'no-alarm', "
               "'bad-pool', 'no-reconnect', 'meters-without-vt', 'no-store', "
               "'slow-maintenance', 'ignores-calibration'";
        return -1;
    }
    return 0;
}

const char *iso_fert_check(const iso_fert_config_t *cfg)
{
    if (cfg->vt_defect != ISO_VT_DEFECT_NONE && !cfg->vt) {
        return "vt_defect needs the operator interface (vt=yes)";
    }
    if (!(cfg->address == floor(cfg->address) && cfg->address >= 0.0 && cfg->address <= 253.0)) {
        return "address must be an integer 0 .. 253";
    }
    if (!(cfg->identity_number == floor(cfg->identity_number) && cfg->identity_number >= 0.0 &&
          cfg->identity_number < 2097152.0)) {
        return "identity_number must be an integer below 2^21";
    }
    if (!(isfinite(cfg->width_m) && cfg->width_m > 0.0 && cfg->width_m <= 30.0)) {
        return "width_m must be within (0, 30] m";
    }
    if (cfg->fert.core.law == PPID_LAW_OPEN_LOOP) {
        return "the ISOBUS mode runs the closed-loop laws (physical, paper-literal), not "
               "open-loop";
    }
    return NULL;
}

static uint64_t implement_name(uint32_t identity)
{
    return (uint64_t)identity | ((uint64_t)RATE_CONTROL_FUNCTION << 40) |
           ((uint64_t)DEVICE_CLASS_FERTILIZERS << 49) |
           ((uint64_t)INDUSTRY_GROUP_AGRICULTURE << 60) | ((uint64_t)1 << 63);
}

/* --- the control inputs ---------------------------------------------------------------------- */

bool iso_fert_ground_speed(const iso_fert_t *c, double *mps, int *source)
{
    int order[2] = {GROUND, WHEEL};
    int count = 2;
    if (c->cfg.speed_wheel) {
        order[0] = WHEEL;
        count = 1;
    }
    for (int i = 0; i < count; i++) {
        int s = order[i];
        if (c->heard[s] &&
            c->clock_s - c->heard_s[s] <= ISO_FERT_SPEED_TIMEOUT_S + SPEED_SLACK_S) {
            *mps = c->heard_mps[s];
            if (source != NULL) {
                *source = s;
            }
            return true;
        }
    }
    return false;
}

static int active_rows(const iso_fert_t *c)
{
    int n = 0;
    for (int i = 0; i < FERT_ROWS; i++) {
        n += c->sections[i] ? 1 : 0;
    }
    return n;
}

bool iso_fert_metering(const iso_fert_t *c)
{
    double v;
    /* with its operator interface: only with its pool active on a VT and Master on */
    if (c->cfg.vt && c->cfg.vt_defect != ISO_VT_DEFECT_METERS_WITHOUT_VT &&
        !(vtc_connected(&c->vt) && c->master_on)) {
        return false;
    }
    return tcc_connected(&c->tc) && c->rate_kg_ha > 0.0 &&
           (c->work_state == -1 || c->work_state == 1) && active_rows(c) > 0 &&
           iso_fert_ground_speed(c, &v, NULL);
}

static double actual_rate_kg_ha(const iso_fert_t *c)
{
    double v;
    int rows = active_rows(c);
    const fert_step_info_t *m = &c->adapter.last;
    if (!iso_fert_ground_speed(c, &v, NULL) || v < MIN_REPORT_SPEED_MPS || !m->has_measurement ||
        rows == 0 || !iso_fert_metering(c)) {
        return 0.0;
    }
    double r = (double)rows;
    return fmax(0.0, m->measured_gps * r / (0.1 * r * c->row_width_m * v));
}

/* The rows that are off are forgotten: their flow no longer counts in the mean. */
static void switch_rows(iso_fert_t *c)
{
    for (int i = 0; i < FERT_ROWS; i++) {
        if (!c->sections[i]) {
            memset(&c->adapter.rows[i], 0, sizeof c->adapter.rows[i]);
        }
    }
}

static uint32_t pack_states(const iso_fert_t *c, bool metering_only)
{
    uint32_t v = 0;
    for (unsigned slot = 0; slot < 16; slot++) {
        uint32_t state = 3; /* not installed */
        if (slot < FERT_ROWS) {
            state = c->sections[slot] && (!metering_only || iso_fert_metering(c)) ? 1u : 0u;
        }
        v |= state << (2 * slot);
    }
    return v;
}

/* --- what the TC sets and reads -------------------------------------------------------------- */

static uint8_t on_setpoint(void *ctx, uint16_t element, uint16_t ddi, int32_t value)
{
    iso_fert_t *c = ctx;
    if (element != c->pool.boom) {
        return ISO_ACK_DDI_NOT_SUPPORTED;
    }
    if (ddi == ISO_DDI_SETPOINT_MASS_PER_AREA_RATE) {
        double rate = value / MG_PER_M2_PER_KG_HA;
        if (!(rate >= 0.0 && rate <= MAX_RATE_KG_HA)) {
            return ISO_ACK_OUT_OF_RANGE;
        }
        c->rate_kg_ha = rate;
    } else if (ddi == ISO_DDI_SETPOINT_CONDENSED_1_16) {
        uint32_t u = (uint32_t)value;
        for (unsigned i = 0; i < FERT_ROWS; i++) {
            c->sections[i] = ((u >> (2 * i)) & 0x3u) == 1u;
        }
    } else if (ddi == ISO_DDI_SETPOINT_WORK_STATE) {
        if (value < 0 || value > 3) {
            return ISO_ACK_VALUE_NOT_CONFORMING;
        }
        c->work_state = value;
    } else {
        return ISO_ACK_DDI_NOT_SUPPORTED;
    }
    switch_rows(c);
    return 0;
}

static bool read_value(void *ctx, uint16_t element, uint16_t ddi, int64_t *value)
{
    iso_fert_t *c = ctx;
    if (element != c->pool.boom) {
        return false;
    }
    switch (ddi) {
    case ISO_DDI_ACTUAL_MASS_PER_AREA_RATE:
        *value = (int64_t)rint(actual_rate_kg_ha(c) * MG_PER_M2_PER_KG_HA);
        return true;
    case ISO_DDI_SETPOINT_MASS_PER_AREA_RATE:
        *value = (int64_t)rint(c->rate_kg_ha * MG_PER_M2_PER_KG_HA);
        return true;
    case ISO_DDI_ACTUAL_WORK_STATE:
        *value = iso_fert_metering(c) ? 1 : 0;
        return true;
    case ISO_DDI_ACTUAL_CONDENSED_1_16:
        *value = pack_states(c, true);
        return true;
    case ISO_DDI_SETPOINT_CONDENSED_1_16:
        *value = pack_states(c, false);
        return true;
    case ISO_DDI_SETPOINT_WORK_STATE:
        *value = c->work_state;
        return c->work_state >= 0;
    default:
        return false;
    }
}

static void on_connection(void *ctx, bool connected)
{
    iso_fert_t *c = ctx;
    (void)connected; /* a new connection starts from nothing: the TC sends its set-points again */
    c->rate_kg_ha = 0.0;
    c->work_state = -1;
    for (int i = 0; i < FERT_ROWS; i++) {
        c->sections[i] = true;
    }
    switch_rows(c);
}

static int write_pool(void *ctx, unsigned version, uint8_t *buf, size_t cap, size_t *size)
{
    iso_fert_t *c = ctx;
    iso_ddop_params_t p = {c->name, c->cfg.width_m, FERT_ROWS, ISO_FERT_LATENCY_MS,
                           c->cfg.ddop_broken, version};
    iso_ddop_info_t info;
    if (iso_meter_pool(&p, buf, cap, &info) != 0) {
        return -1;
    }
    *size = info.size;
    return 0;
}

static void on_speed(iso_fert_t *c, int source, const uint8_t *d, size_t len, double now_s)
{
    if (len != 8) {
        return;
    }
    double speed = (double)(uint16_t)(d[0] | (d[1] << 8)) * 0.001;
    if (speed >= 0.0 && speed <= MAX_VALID_SPEED_MPS) {
        c->heard[source] = true;
        c->heard_s[source] = now_s;
        c->heard_mps[source] = speed;
    }
}

static void deliver(void *ctx, uint32_t pgn, const uint8_t *data, size_t len, uint8_t source,
                    uint8_t destination, double now_s)
{
    iso_fert_t *c = ctx;
    if (pgn == ISO_PGN_VT_TO_ECU) {
        if (c->cfg.vt) {
            vtc_on_group(&c->vt, pgn, data, len, source, destination, now_s);
        }
    } else if (pgn == PGN_GROUND_BASED_SPEED) {
        on_speed(c, GROUND, data, len, now_s);
    } else if (pgn == PGN_WHEEL_BASED_SPEED) {
        on_speed(c, WHEEL, data, len, now_s);
    } else {
        tcc_on_group(&c->tc, pgn, data, len, source, destination, now_s);
    }
}

/* ControllerStatus's three scaled fields with Python's round (half to even), as the Python
 * controller encodes them (cantools / hil.rig.fastcodec: round((value - offset) / scale)).
 * The generated encoders use C's round() (half away from zero): the two differ when a value
 * falls exactly on half a step (the ideal meter's targets do, e.g. 25.005 g/s). The fix
 * belongs in apps/fertilizer_adapter.c (encode with rint, as it already does for 0x220);
 * until then this controller re-encodes the frame so that it matches the Python's. */
static void python_rounded_status(hal_can_frame_t *f, const fert_step_info_t *info)
{
    struct fertilizer_controller_status_t st;
    if (fertilizer_controller_status_unpack(&st, f->data, f->len) < 0) {
        return;
    }
    double q = fmin(fmax(info->target_gps, 0.0), 250.0);
    double m = fmin(fmax(info->measured_gps, 0.0), 250.0);
    double v = fmin(fmax(info->out.volts, 0.0), 10.0);
    st.target_flow = (uint16_t)rint(q / 0.01);
    st.measured_flow = (uint16_t)rint(m / 0.01);
    st.command_voltage = (uint16_t)rint(v / 0.001);
    fertilizer_controller_status_pack(f->data, &st, sizeof f->data);
}

/* --- the operator (isobus_vt.py) ----------------------------------------------------------- */

static void on_key(void *ctx, uint16_t object_id, uint16_t parent_id, uint8_t key_code,
                   uint8_t activation, bool button)
{
    iso_fert_t *c = ctx;
    (void)parent_id;
    (void)key_code;
    (void)button;
    if (activation != ISO_VT_KEY_RELEASED) {
        return;
    }
    if (object_id == ISO_POOL_KEY_MASTER) {
        c->master_on = !c->master_on || c->cfg.vt_defect == ISO_VT_DEFECT_IGNORES_MASTER;
        vtc_change_string_value(&c->vt, ISO_POOL_MASTER_VAR,
                                (const uint8_t *)(c->master_on ? "ON " : "OFF"), 3);
    } else if (object_id == ISO_POOL_KEY_CALIBRATION) {
        vtc_change_active_mask(&c->vt, ISO_POOL_WORKING_SET, ISO_POOL_CALIBRATION);
    } else if (object_id == ISO_POOL_KEY_BACK || object_id == ISO_POOL_KEY_ACK) {
        c->alarm_row = 0;
        vtc_change_active_mask(&c->vt, ISO_POOL_WORKING_SET, ISO_POOL_RUN);
    }
}

/* the calibration test entered on the VT: the feedforward map's coefficient from then on (the
 * MeterCalibration frame's expression); a test without a usable coefficient changes nothing */
static void on_number(void *ctx, uint16_t object_id, uint32_t value)
{
    iso_fert_t *c = ctx;
    double grams = c->cal_grams, rpm = c->cal_rpm;
    if (object_id == ISO_POOL_CAL_GRAMS_IN) {
        grams = (double)value / 10.0;
    } else if (object_id == ISO_POOL_CAL_RPM_IN) {
        rpm = (double)value / 10.0;
    } else {
        return;
    }
    c->cal_grams = grams;
    c->cal_rpm = rpm;
    if (c->cfg.vt_defect == ISO_VT_DEFECT_IGNORES_CALIBRATION) {
        return; /* shown on the VT, not used */
    }
    ppid_params_t *p = &c->adapter.cfg.core;
    double coeff = fert_ff_coeff_from_test(grams, rpm, p->ff_exponent, p->ff_linear_below_rpm);
    if (coeff > 0.0) {
        p->ff_coeff = coeff;
    }
}

/* IsobusFlowController.target_gps: 0.1 M (D_active) v / active rows, 0 when not metering */
static double target_gps(const iso_fert_t *c)
{
    double v;
    if (!iso_fert_ground_speed(c, &v, NULL) || !iso_fert_metering(c)) {
        return 0.0;
    }
    double rows = (double)active_rows(c);
    return 0.1 * c->rate_kg_ha * (rows * c->row_width_m) * v / rows;
}

static double row_rate_kg_ha(const iso_fert_t *c, int i)
{
    double v;
    const fert_row_t *r = &c->adapter.rows[i];
    if (!iso_fert_ground_speed(c, &v, NULL) || v < ROW_RATE_MIN_SPEED_MPS || !r->seen ||
        !iso_fert_metering(c)) {
        return 0.0;
    }
    return fmax(0.0, r->flow_gps / (0.1 * c->row_width_m * v));
}

/* the Run mask's values, those that changed */
static void refresh(iso_fert_t *c)
{
    for (int k = 0; k <= FERT_ROWS; k++) {
        double value = k == 0 ? c->rate_kg_ha * 10 : row_rate_kg_ha(c, k - 1) * 10;
        int64_t shown = (int64_t)rint(value);
        if (!c->shown_set[k] || c->shown[k] != shown) {
            c->shown_set[k] = true;
            c->shown[k] = shown;
            unsigned var = k == 0 ? ISO_POOL_RATE_VAR : ISO_POOL_ROW_VAR_1 + (unsigned)k - 1u;
            vtc_change_numeric_value(&c->vt, (uint16_t)var, (uint32_t)shown);
        }
    }
}

/* rows.py FlowRows.valid at the step just run */
static bool row_valid(const iso_fert_t *c, const fert_row_t *r, double target)
{
    return r->baseline_ready && !r->overrange &&
           c->clock_s - r->at_s <= c->cfg.fert.stale_after_s + STALE_SLACK_S &&
           r->flow_gps <= 3.0 * target + 5.0;
}

/* a row switched on whose flow is lost (no valid report, or left out by the cross-row check)
 * for ISO_FERT_ALARM_AFTER_S while metering raises the Alarm mask; once per loss */
static void watch_rows(iso_fert_t *c)
{
    double target = target_gps(c);
    bool metering = iso_fert_metering(c) && target > 0.0;
    double now = c->clock_s;
    for (int i = 0; i < FERT_ROWS; i++) {
        const fert_row_t *r = &c->adapter.rows[i];
        bool lost = metering && c->sections[i] &&
                    (!r->seen || !row_valid(c, r, target) || c->adapter.xrow.out[i]);
        if (!lost) {
            c->lost[i] = false;
            c->alarmed[i] = false;
            continue;
        }
        if (!c->lost[i]) {
            c->lost[i] = true;
            c->lost_since[i] = now;
        }
        if (now - c->lost_since[i] >= ISO_FERT_ALARM_AFTER_S - TIME_SLACK_S && !c->alarmed[i] &&
            c->cfg.vt_defect != ISO_VT_DEFECT_NO_ALARM) {
            c->alarmed[i] = true;
            c->alarm_row = i + 1;
            char text[ISO_POOL_ALARM_TEXT_LENGTH + 1];
            memset(text, ' ', sizeof text);
            int n = snprintf(text, sizeof text, "Row %d: flow lost", i + 1);
            if (n >= 0 && (size_t)n < sizeof text) {
                text[n] = ' '; /* padded with spaces, as str.ljust */
            }
            vtc_change_string_value(&c->vt, ISO_POOL_ALARM_VAR, (const uint8_t *)text,
                                    ISO_POOL_ALARM_TEXT_LENGTH);
            vtc_change_active_mask(&c->vt, ISO_POOL_WORKING_SET, ISO_POOL_ALARM);
        }
    }
}

/* --- set-up and frames ------------------------------------------------------------------------- */

int iso_fert_init(iso_fert_t *c, const iso_fert_config_t *cfg)
{
    memset(c, 0, sizeof *c);
    c->cfg = *cfg;
    fert_init(&c->adapter, &cfg->fert);
    c->adapter.rows_follow_setpoint = false; /* the sections say which rows' modules count */
    c->name = implement_name((uint32_t)cfg->identity_number);
    c->row_width_m = cfg->width_m / FERT_ROWS;
    c->work_state = -1;
    for (int i = 0; i < FERT_ROWS; i++) {
        c->sections[i] = true;
    }
    /* the pool's table (and a check that it fits TP) from the version 4 bytes */
    static uint8_t scratch[ISO_DDOP_MAX_BYTES];
    iso_ddop_params_t p = {c->name, cfg->width_m, FERT_ROWS, ISO_FERT_LATENCY_MS,
                           cfg->ddop_broken, 4};
    if (iso_meter_pool(&p, scratch, sizeof scratch, &c->pool) != 0) {
        return -1;
    }
    iso_net_init(&c->net, c->name, (uint8_t)cfg->address, deliver, c);
    tcc_implement_t impl = {c, on_setpoint, read_value, on_connection};
    tcc_init(&c->tc, &c->net, &c->pool, impl, write_pool);
    if (cfg->vt) {
        static uint8_t vt_pool[ISO_POOL_MAX_BYTES];
        size_t size = 0;
        vtc_implement_t hooks = {c, on_key, on_number};
        if (iso_vt_pool(FERT_ROWS, cfg->vt_defect == ISO_VT_DEFECT_BAD_POOL, vt_pool,
                        sizeof vt_pool, &size) != 0 ||
            vtc_init(&c->vt, &c->net, vt_pool, size,
                     cfg->vt_defect == ISO_VT_DEFECT_NO_STORE ? NULL : ISO_POOL_VERSION_LABEL,
                     hooks) != 0) {
            return -1;
        }
        c->cal_rpm = 21.0;
        c->maintenance_due = INFINITY;
    }
    return 0;
}

hal_can_frame_t iso_fert_bootup(void)
{
    return fert_bootup();
}

static size_t take_network_frames(iso_fert_t *c)
{
    size_t n = c->net.nout;
    memcpy(c->out, c->net.out, n * sizeof c->out[0]);
    c->net.nout = 0;
    return n;
}

size_t iso_fert_step(iso_fert_t *c)
{
    if (c->cfg.vt_defect == ISO_VT_DEFECT_NO_RECONNECT && c->vt.has_connected_s) {
        vtc_forget_status(&c->vt); /* never notices the VT is gone */
    }
    c->clock_s = (double)c->steps * c->cfg.fert.period_s;
    iso_net_poll(&c->net, c->clock_s);
    tcc_tick(&c->tc, c->clock_s);
    if (c->cfg.vt) {
        vtc_tick(&c->vt, c->clock_s);
    }
    size_t n = take_network_frames(c); /* the replies since the last step, then the due ones */
    /* the adapter's field mode with the TC's rate, the active rows' width and the speed */
    fert_setpoint_t *sp = &c->adapter.setpoint;
    double v = 0.0;
    bool has_speed = iso_fert_ground_speed(c, &v, NULL);
    int rows = active_rows(c);
    sp->seen = true;
    sp->mode = 0;
    sp->enable = iso_fert_metering(c);
    sp->target_rate = c->rate_kg_ha;
    sp->working_width = (double)rows * c->row_width_m;
    sp->target_flow = 0.0;
    sp->speed_source = 2;
    sp->active_rows = (uint8_t)rows;
    c->adapter.speed[2] = (fert_speed_t){has_speed, has_speed ? v : 0.0};
    size_t first = n;
    n += fert_step(&c->adapter, c->clock_s, c->out + n);
    for (size_t i = first; i < n; i++) {
        if (!c->out[i].extended && c->out[i].id == FERTILIZER_CONTROLLER_STATUS_FRAME_ID) {
            python_rounded_status(&c->out[i], &c->adapter.last);
        }
    }
    c->steps++;
    if (c->cfg.vt_defect == ISO_VT_DEFECT_SLOW_MAINTENANCE) {
        /* each maintenance message's next one a second later than due (every 2 s) */
        double due = c->vt.next_maintenance_s;
        if (isfinite(due) && due != c->maintenance_due) {
            c->vt.next_maintenance_s = due + 1.0;
            c->maintenance_due = c->vt.next_maintenance_s;
        }
    }
    if (c->cfg.vt && vtc_connected(&c->vt)) {
        /* what the operator sees: queued now, sent from the next step on */
        watch_rows(c);
        if (c->clock_s >= c->next_display_s - TIME_SLACK_S) {
            c->next_display_s = c->clock_s + ISO_FERT_DISPLAY_PERIOD_S;
            refresh(c);
        }
    }
    c->nout = n;
    return n;
}

size_t iso_fert_on_frame(iso_fert_t *c, const hal_can_frame_t *f)
{
    c->nout = 0;
    if (f->extended) {
        /* what the network answers waits in its outbox for the next step, as a firmware's
         * 100 ms task sends (the Python controller does the same) */
        iso_net_on_frame(&c->net, f, c->clock_s);
        return 0;
    }
    if (f->id == SYNC_ID) {
        return c->cfg.step_on_sync ? iso_fert_step(c) : 0;
    }
    if (f->id >= FLOW_MODULE1_ID && f->id < FLOW_MODULE1_ID + FERT_ROWS &&
        c->sections[f->id - FLOW_MODULE1_ID]) {
        /* stamped with the next step's time: the adapter counts staleness in steps */
        fert_on_frame(&c->adapter, f, (double)c->steps * c->cfg.fert.period_s);
    }
    return 0;
}
