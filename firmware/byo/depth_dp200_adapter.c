#include "depth_dp200_adapter.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* The database's units to the law's (dbc_adapter.py TO_LAW_UNITS): value_law = value x f. */
#define CM_TO_MM 10.0
#define V_TO_MV 1000.0
#define UM_TO_MM 0.001
#define MPS_TO_MPS 1.0
#define MM_TO_MM 1.0

#define STATUS_EVERY 20    /* DP_Status: 200 ms at the 10 ms control period */
#define HEARTBEAT_EVERY 50 /* DP_Heartbeat: 500 ms */
#define DEPTH_FILTER 0.2   /* first-order filter gain per inclinometer report */
#define MAX_VALID_SPEED_MPS 64.255 /* J1939 "not available" decodes above it */
#define SLACK 1e-9

/* CiA 301 */
#define NMT_BOOT_UP 0
#define NMT_OPERATIONAL 5
#define NMT_START 0x01u
#define HEARTBEAT_BASE 0x700u
#define SDO_CONFIRMED 0x60u
#define SDO_ABORT 0x80u
#define NOT_VALID 0x80000000u
#define PDO_COUNT 3 /* RPDO1-3 and TPDO1-3 are invalidated first */
#define DRIVE_HEARTBEAT_MS 100u
/* CiA 402 */
#define MODE_PROFILE_VELOCITY 3u
#define CW_FAULT_RESET 0x80u
#define CW_NO_COMMAND 0x00u

enum { SRC_GBSD = 0, SRC_GNSS = 1 };
enum { ST_INITIALISING, ST_READY, ST_CONTROLLING, ST_MANUAL, ST_FAULT };

/* --- the drive's PDOs as the DP-200 maps them (dbc_adapter.py DP200_DRIVE_PDOS) ----------- */

typedef struct {
    bool tpdo;
    uint8_t number;
    uint32_t cob_id; /* the database message's id */
    uint8_t length;  /* the database message's length */
    uint8_t count;
    uint32_t objects[3]; /* index << 16 | sub-index << 8 | bits */
    uint8_t transmission_type;
    uint16_t event_timer_ms;
    uint16_t inhibit_100us;
} pdo_config_t;

static const pdo_config_t PDOS[] = {
    {false, 1, DEPTHPRO_DP200_DP_DRIVE_COMMAND_FRAME_ID, DEPTHPRO_DP200_DP_DRIVE_COMMAND_LENGTH,
     2, {0x60FF0020u, 0x60400010u, 0}, 1, 0, 0},
    {true, 1, DEPTHPRO_DP200_DP_DRIVE_FEEDBACK_FRAME_ID, DEPTHPRO_DP200_DP_DRIVE_FEEDBACK_LENGTH,
     3, {0x60640020u, 0x60410010u, 0x60610008u}, 1, 0, 0},
    {true, 3, DEPTHPRO_DP200_DP_DRIVE_DIAGNOSIS_FRAME_ID,
     DEPTHPRO_DP200_DP_DRIVE_DIAGNOSIS_LENGTH, 2, {0x603F0010u, 0x60780010u, 0}, 255, 100, 100},
};

/* The database's drive frames are what the mappings make (drive_config.py
 * check_against_database holds the Python build to the same): 11-bit ids, as many bytes as the
 * mapped bits. */
_Static_assert(DEPTHPRO_DP200_DP_DRIVE_COMMAND_LENGTH == (32 + 16) / 8, "RPDO1 mapping");
_Static_assert(DEPTHPRO_DP200_DP_DRIVE_FEEDBACK_LENGTH == (32 + 16 + 8) / 8, "TPDO1 mapping");
_Static_assert(DEPTHPRO_DP200_DP_DRIVE_DIAGNOSIS_LENGTH == (16 + 16) / 8, "TPDO3 mapping");
_Static_assert(!DEPTHPRO_DP200_DP_DRIVE_COMMAND_IS_EXTENDED &&
                   !DEPTHPRO_DP200_DP_DRIVE_FEEDBACK_IS_EXTENDED &&
                   !DEPTHPRO_DP200_DP_DRIVE_DIAGNOSIS_IS_EXTENDED,
               "a PDO has an 11-bit COB-ID");

static const dp200_write_t MODE_WRITE[1] = {{0x6060u, 0, MODE_PROFILE_VELOCITY, 1}};

static size_t add(dp200_write_t *w, size_t n, uint16_t index, uint8_t sub, uint32_t value,
                  uint8_t size)
{
    w[n] = (dp200_write_t){index, sub, value, size};
    return n + 1;
}

/* drive_config.py configuration_writes: invalidate, map each PDO, then the heartbeat time. */
static size_t configuration_writes(dp200_write_t w[DP200_CONFIG_WRITES], uint8_t node)
{
    size_t n = 0;
    for (int tpdo = 0; tpdo < 2; tpdo++) {
        for (uint16_t k = 0; k < PDO_COUNT; k++) {
            uint16_t com = (uint16_t)((tpdo ? 0x1800u : 0x1400u) + k);
            uint32_t cob = (tpdo ? 0x180u : 0x200u) + 0x100u * k + node;
            n = add(w, n, com, 1, NOT_VALID | cob, 4);
        }
    }
    for (size_t p = 0; p < sizeof PDOS / sizeof PDOS[0]; p++) {
        const pdo_config_t *c = &PDOS[p];
        uint16_t com = (uint16_t)((c->tpdo ? 0x1800u : 0x1400u) + c->number - 1u);
        uint16_t map = (uint16_t)(com + 0x200u);
        n = add(w, n, map, 0, 0, 1);
        for (uint8_t i = 0; i < c->count; i++) {
            n = add(w, n, map, (uint8_t)(i + 1u), c->objects[i], 4);
        }
        n = add(w, n, map, 0, c->count, 1);
        n = add(w, n, com, 2, c->transmission_type, 1);
        if (c->tpdo) {
            n = add(w, n, com, 3, c->inhibit_100us, 2);
            n = add(w, n, com, 5, c->event_timer_ms, 2);
        }
        n = add(w, n, com, 1, c->cob_id, 4);
    }
    return add(w, n, 0x1017u, 0, DRIVE_HEARTBEAT_MS, 2);
}

/* --- Python's rounding ------------------------------------------------------------------- */

double dp200_py_round(double x, int places)
{
    static const double POW10[10] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
    if (!isfinite(x) || places < 0 || places > 9) {
        return x;
    }
    double scale = POW10[places];
    double y = x * scale;            /* the product, rounded */
    double err = fma(x, scale, -y);  /* and exactly what the rounding lost */
    double k = rint(y);              /* half to even */
    if (fabs(y - trunc(y)) == 0.5 && err != 0.0) {
        /* y is a tie only because the product was rounded: the exact value is not */
        k = err > 0.0 ? floor(y) + 1.0 : floor(y);
        if (y < 0.0) {
            k = err > 0.0 ? ceil(y) : ceil(y) - 1.0;
        }
    }
    return k / scale;
}

/* dbc_adapter.py _decimals: decimal places that represent every multiple of step. */
static int decimals(double step)
{
    for (int places = 0; places < 10; places++) {
        if (fabs(dp200_py_round(step, places) - step) < 1e-12 * fmax(1.0, step)) {
            return places;
        }
    }
    return 10;
}

/* dbc_adapter.py _Reader: a signal's value (decoded by the generated code) in the law's unit,
 * rounded to the signal's resolution there. scale = decode(1) - decode(0). */
static double law_value(double decoded, double scale, double factor)
{
    double value = dp200_py_round(decoded, decimals(fabs(scale)));
    return factor == 1.0 ? value : dp200_py_round(value * factor, decimals(fabs(scale) * factor));
}

/* dbc_adapter.py _raw: the raw count of value (in the signal's unit). */
static double raw_of(double value, double scale)
{
    double per_unit = 1.0 / scale;
    if (fabs(per_unit - rint(per_unit)) < 1e-9) {
        return rint(value * rint(per_unit));
    }
    return rint(value / scale);
}

/* --- set-up -------------------------------------------------------------------------------- */

void dp200_config_defaults(dp200_config_t *cfg)
{
    fpid_defaults(&cfg->core);
    cfg->min_speed_mps = 0.1;
    cfg->speed_timeout_s = 1.0;
    cfg->frozen_after_s = 0.2; /* as the reference (apps/depth_adapter.c says why) */
    rhold_defaults(&cfg->hold);
    cfg->sdo_timeout_s = 0.5;
}

size_t dp200_param_refs(dp200_config_t *cfg, param_ref_t refs[DP200_PARAM_COUNT])
{
    size_t n = fpid_param_refs(&cfg->core, refs);
    refs[n++] = (param_ref_t){"min_speed_mps", &cfg->min_speed_mps};
    refs[n++] = (param_ref_t){"speed_timeout_s", &cfg->speed_timeout_s};
    refs[n++] = (param_ref_t){"frozen_after_s", &cfg->frozen_after_s};
    refs[n++] = (param_ref_t){"hold_time_constant_s", &cfg->hold.time_constant_s};
    refs[n++] = (param_ref_t){"hold_gain_per_s", &cfg->hold.gain_per_s};
    refs[n++] = (param_ref_t){"hold_speed_mm_s", &cfg->hold.speed_mm_s};
    refs[n++] = (param_ref_t){"sdo_timeout_s", &cfg->sdo_timeout_s};
    return n;
}

int dp200_config_check(const dp200_config_t *cfg, char *err, size_t errlen)
{
    const char *why = NULL;
    if (!(cfg->core.period_s > 0.0)) {
        why = "period_s must be > 0";
    } else if (!(cfg->core.v_max > 0.0)) {
        why = "v_max must be > 0";
    } else if (rhold_check(&cfg->hold, &why) != 0) {
        /* why is set */
    } else if (!(cfg->hold.speed_mm_s <= cfg->core.v_max)) {
        why = "hold_speed_mm_s must be <= v_max";
    } else if (!(cfg->sdo_timeout_s > 0.0)) {
        why = "sdo_timeout_s must be > 0";
    }
    if (why != NULL) {
        snprintf(err, errlen, "%s", why);
        return -1;
    }
    return 0;
}

void dp200_init(dp200_adapter_t *a, const dp200_config_t *cfg)
{
    memset(a, 0, sizeof *a);
    a->cfg = *cfg;
    a->drive_node = (uint8_t)(DEPTHPRO_DP200_DP_DRIVE_HEARTBEAT_FRAME_ID - HEARTBEAT_BASE);
    a->drive_nmt = -1;
    a->law.target_mm = 30.0;
    fpid_reset(&a->law.core);
    rhold_reset(&a->law.hold);
    (void)configuration_writes(a->configuration, a->drive_node);
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
    struct depthpro_dp200_dp_heartbeat_t hb = {state};
    hal_can_frame_t f = frame_of(DEPTHPRO_DP200_DP_HEARTBEAT_FRAME_ID,
                                 DEPTHPRO_DP200_DP_HEARTBEAT_IS_EXTENDED,
                                 DEPTHPRO_DP200_DP_HEARTBEAT_LENGTH);
    depthpro_dp200_dp_heartbeat_pack(f.data, &hb, sizeof f.data);
    return f;
}

hal_can_frame_t dp200_bootup(void)
{
    return heartbeat(DEPTHPRO_DP200_DP_HEARTBEAT_NMT_STATE_BOOT_UP_CHOICE);
}

const char *dp200_error(const dp200_adapter_t *a)
{
    return a->has_error ? a->error : NULL;
}

/* --- SDO client (CiA 301 expedited download) --------------------------------------------- */

const char *dp200_abort_text(uint32_t code)
{
    static const struct {
        uint32_t code;
        const char *text;
    } TABLE[] = {
        {0x05030000u, "toggle bit not alternated"},
        {0x05040000u, "SDO protocol timed out"},
        {0x05040001u, "command specifier not valid or unknown"},
        {0x05040005u, "out of memory"},
        {0x06010000u, "unsupported access to an object"},
        {0x06010001u, "attempt to read a write only object"},
        {0x06010002u, "attempt to write a read only object"},
        {0x06020000u, "object does not exist in the object dictionary"},
        {0x06040041u, "object cannot be mapped to the PDO"},
        {0x06040042u, "the number and length of the objects to be mapped would exceed PDO "
                      "length"},
        {0x06040043u, "general parameter incompatibility"},
        {0x06040047u, "general internal incompatibility in the device"},
        {0x06060000u, "access failed due to a hardware error"},
        {0x06070010u, "data type does not match, length of service parameter does not match"},
        {0x06070012u, "data type does not match, length of service parameter too high"},
        {0x06070013u, "data type does not match, length of service parameter too low"},
        {0x06090011u, "sub-index does not exist"},
        {0x06090030u, "invalid value for parameter"},
        {0x06090031u, "value of parameter written too high"},
        {0x06090032u, "value of parameter written too low"},
        {0x08000000u, "general error"},
        {0x08000020u, "data cannot be transferred or stored to the application"},
        {0x08000021u, "data cannot be transferred or stored because of local control"},
        {0x08000022u, "data cannot be transferred or stored because of the present device "
                      "state"},
    };
    for (size_t i = 0; i < sizeof TABLE / sizeof TABLE[0]; i++) {
        if (TABLE[i].code == code) {
            return TABLE[i].text;
        }
    }
    return "unknown abort code";
}

static void batch_start(dp200_adapter_t *a, dp200_sdo_batch_t *b, const dp200_write_t *writes,
                        size_t count)
{
    *b = (dp200_sdo_batch_t){true, writes, count, 0, false, a->law.steps};
}

static bool batch_pending(const dp200_sdo_batch_t *b)
{
    return b->active && b->confirmed < b->count && !b->failed;
}

static bool batch_done(const dp200_sdo_batch_t *b)
{
    return b->active && b->confirmed >= b->count && !b->failed;
}

/* Every request of the batch, in order (CiA 301: ccs 1, e = s = 1, n = 4 - size). */
static size_t batch_frames(const dp200_sdo_batch_t *b, hal_can_frame_t *out)
{
    for (size_t i = 0; i < b->count; i++) {
        const dp200_write_t *w = &b->writes[i];
        struct depthpro_dp200_dp_drive_sdo_request_t m;
        memset(&m, 0, sizeof m);
        m.command = w->size == 1 ? 0x2Fu : w->size == 2 ? 0x2Bu : 0x23u;
        m.index = w->index;
        m.sub_index = w->subindex;
        m.data = w->size >= 4 ? w->value : w->value & ((1u << (8u * w->size)) - 1u);
        out[i] = frame_of(DEPTHPRO_DP200_DP_DRIVE_SDO_REQUEST_FRAME_ID,
                          DEPTHPRO_DP200_DP_DRIVE_SDO_REQUEST_IS_EXTENDED,
                          DEPTHPRO_DP200_DP_DRIVE_SDO_REQUEST_LENGTH);
        depthpro_dp200_dp_drive_sdo_request_pack(out[i].data, &m, sizeof out[i].data);
    }
    return b->count;
}

static void fail(dp200_adapter_t *a, dp200_sdo_batch_t *b)
{
    b->failed = true;
    a->has_error = true;
}

/* The node's next answer: the confirmation of the next write, or an error. */
static void batch_answer(dp200_adapter_t *a, dp200_sdo_batch_t *b,
                         const struct depthpro_dp200_dp_drive_sdo_response_t *m)
{
    if (!batch_pending(b)) {
        return;
    }
    const dp200_write_t *w = &b->writes[b->confirmed];
    if (m->index != w->index || m->sub_index != w->subindex) {
        snprintf(a->error, sizeof a->error, "0x%04X:%02X: answered for 0x%04X:%02X",
                 (unsigned)w->index, (unsigned)w->subindex, (unsigned)m->index,
                 (unsigned)m->sub_index);
        fail(a, b);
    } else if (m->command == SDO_ABORT) {
        snprintf(a->error, sizeof a->error,
                 "0x%04X:%02X = 0x%X refused (SDO abort 0x%08X: %s)", (unsigned)w->index,
                 (unsigned)w->subindex, (unsigned)w->value, (unsigned)m->data,
                 dp200_abort_text(m->data));
        fail(a, b);
    } else if (m->command == SDO_CONFIRMED) {
        b->confirmed++;
    } else {
        snprintf(a->error, sizeof a->error, "0x%04X:%02X: unexpected answer 0x%02X",
                 (unsigned)w->index, (unsigned)w->subindex, (unsigned)m->command);
        fail(a, b);
    }
}

/* This build's timeout: a batch still pending sdo_timeout_s after it was sent. */
static void check_timeout(dp200_adapter_t *a, dp200_sdo_batch_t *b)
{
    if (a->has_error || !batch_pending(b)) {
        return;
    }
    double waited_s = (double)(a->law.steps - b->sent_step) * a->cfg.core.period_s;
    if (waited_s > a->cfg.sdo_timeout_s + SLACK) {
        const dp200_write_t *w = &b->writes[b->confirmed];
        snprintf(a->error, sizeof a->error,
                 "0x%04X:%02X = 0x%X: no answer from the drive (node %u) within %g s "
                 "(SDO timeout; %zu of %zu writes confirmed)",
                 (unsigned)w->index, (unsigned)w->subindex, (unsigned)w->value,
                 (unsigned)a->drive_node, a->cfg.sdo_timeout_s, b->confirmed, b->count);
        fail(a, b);
    }
}

/* dbc_adapter.py _on_drive_heartbeat: configure the drive when it booted or is not
 * Operational (the next step starts it once every write is confirmed). */
static size_t on_drive_heartbeat(dp200_adapter_t *a, int state, hal_can_frame_t *out)
{
    a->drive_nmt = state;
    bool pending = batch_pending(&a->sdo);
    if (state != NMT_OPERATIONAL) {
        a->mode_sdo.active = false; /* selected again once the drive is started */
    }
    if (a->has_error && state != NMT_BOOT_UP) {
        return 0; /* refused: the drive stays stopped until it reboots */
    }
    if (state == NMT_BOOT_UP || (state != NMT_OPERATIONAL && !pending)) {
        a->configured = false;
        a->has_error = false;
        a->error[0] = '\0';
        batch_start(a, &a->sdo, a->configuration, DP200_CONFIG_WRITES);
        return batch_frames(&a->sdo, out);
    }
    if (state == NMT_OPERATIONAL && !pending) {
        a->configured = true;
    }
    return 0;
}

static void on_sdo_response(dp200_adapter_t *a, const hal_can_frame_t *f)
{
    struct depthpro_dp200_dp_drive_sdo_response_t m;
    if (depthpro_dp200_dp_drive_sdo_response_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    dp200_sdo_batch_t *b = batch_pending(&a->sdo) ? &a->sdo : &a->mode_sdo;
    if (b->active) {
        batch_answer(a, b, &m);
    }
}

/* --- the law's inputs (depth_law.py) -------------------------------------------------------- */

static double now_s(const dp200_adapter_t *a)
{
    return (double)a->law.steps * a->cfg.core.period_s;
}

static void speed_update(dp200_adapter_t *a, int source, bool valid, double mps)
{
    dp200_law_t *l = &a->law;
    bool known = false;
    for (int i = 0; i < l->sources; i++) {
        known = known || l->source_order[i] == source;
    }
    if (!known) {
        l->source_order[l->sources++] = source;
    }
    l->speed_valid[source] = valid;
    l->speed_mps[source] = valid ? mps : 0.0;
    l->speed_at_s[source] = now_s(a);
}

/* ground_speed.py SpeedSources.speed: the most recent valid speed within the timeout (the
 * first reported wins a tie); false if none. */
static bool known_speed(const dp200_adapter_t *a, double *mps)
{
    const dp200_law_t *l = &a->law;
    int best = -1;
    for (int i = 0; i < l->sources; i++) {
        int s = l->source_order[i];
        if (!l->speed_valid[s] || now_s(a) - l->speed_at_s[s] > a->cfg.speed_timeout_s + SLACK) {
            continue;
        }
        if (best < 0 || l->speed_at_s[s] > l->speed_at_s[best]) {
            best = s;
        }
    }
    if (best >= 0) {
        *mps = l->speed_mps[best];
    }
    return best >= 0;
}

void dp200_on_gnss(dp200_adapter_t *a, bool valid, double speed_mps)
{
    speed_update(a, SRC_GNSS, valid, speed_mps);
}

static void on_sensor_hub(dp200_adapter_t *a, const hal_can_frame_t *f)
{
    struct depthpro_dp200_dp_sensor_hub_t m;
    memset(&m, 0, sizeof m);
    if (depthpro_dp200_dp_sensor_hub_unpack(&m, f->data, f->len) < 0 ||
        m.channel != DEPTHPRO_DP200_DP_SENSOR_HUB_CHANNEL_ARM_INCLINOMETER_CHOICE) {
        return; /* the draw-wire channel is not the law's; other values are not defined */
    }
    dp200_law_t *l = &a->law;
    l->depth_ok = m.tilt_x_state == DEPTHPRO_DP200_DP_SENSOR_HUB_TILT_X_STATE_VALID_CHOICE;
    if (!l->depth_ok) {
        return;
    }
    double scale = depthpro_dp200_dp_sensor_hub_arm_tilt_x_decode(1) -
                   depthpro_dp200_dp_sensor_hub_arm_tilt_x_decode(0);
    double x_mv = law_value(depthpro_dp200_dp_sensor_hub_arm_tilt_x_decode(m.arm_tilt_x), scale,
                            V_TO_MV);
    if (!l->have_x || x_mv != l->last_x_mv) {
        l->have_x = true;
        l->last_x_mv = x_mv;
        l->x_changed_at_s = now_s(a);
        rhold_mark(&l->hold); /* a sign of life: the mean so far is trusted */
    }
    double depth = -0.065 * x_mv + 270.35; /* [D] eq. 13 */
    l->depth_mm = l->have_depth ? l->depth_mm + DEPTH_FILTER * (depth - l->depth_mm) : depth;
    l->have_depth = true;
}

static void on_setpoint(dp200_adapter_t *a, const hal_can_frame_t *f)
{
    struct depthpro_dp200_dp_setpoint_t m;
    if (depthpro_dp200_dp_setpoint_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    dp200_law_t *l = &a->law;
    double scale = depthpro_dp200_dp_setpoint_target_depth_decode(1) -
                   depthpro_dp200_dp_setpoint_target_depth_decode(0);
    l->target_mm = law_value(depthpro_dp200_dp_setpoint_target_depth_decode(m.target_depth),
                             scale, CM_TO_MM);
    l->terminal_on = m.enable == DEPTHPRO_DP200_DP_SETPOINT_ENABLE_ON_CHOICE;
    l->automatic = m.mode == DEPTHPRO_DP200_DP_SETPOINT_MODE_AUTO_DEPTH_CHOICE;
    l->manual = m.mode == DEPTHPRO_DP200_DP_SETPOINT_MODE_MANUAL_CHOICE;
}

static void on_ground_speed(dp200_adapter_t *a, const hal_can_frame_t *f)
{
    struct depthpro_dp200_gbsd_t m;
    if (depthpro_dp200_gbsd_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    double scale = depthpro_dp200_gbsd_ground_based_machine_speed_decode(1) -
                   depthpro_dp200_gbsd_ground_based_machine_speed_decode(0);
    double mps = law_value(
        depthpro_dp200_gbsd_ground_based_machine_speed_decode(m.ground_based_machine_speed),
        scale, MPS_TO_MPS);
    speed_update(a, SRC_GBSD, mps >= 0.0 && mps <= MAX_VALID_SPEED_MPS, mps);
}

static void on_feedback(dp200_adapter_t *a, const hal_can_frame_t *f)
{
    struct depthpro_dp200_dp_drive_feedback_t m;
    if (depthpro_dp200_dp_drive_feedback_unpack(&m, f->data, f->len) < 0) {
        return;
    }
    double scale = depthpro_dp200_dp_drive_feedback_position_actual_decode(1) -
                   depthpro_dp200_dp_drive_feedback_position_actual_decode(0);
    a->law.statusword = m.statusword;
    a->law.position_mm = law_value(
        depthpro_dp200_dp_drive_feedback_position_actual_decode(m.position_actual), scale,
        MM_TO_MM);
    a->law.have_position = true;
}

size_t dp200_on_frame(dp200_adapter_t *a, const hal_can_frame_t *f,
                      hal_can_frame_t out[DP200_MAX_OUT])
{
    if (f->extended) {
        if (f->id == DEPTHPRO_DP200_GBSD_FRAME_ID) {
            on_ground_speed(a, f);
        }
        return 0;
    }
    switch (f->id) {
    case DEPTHPRO_DP200_DP_DRIVE_SDO_RESPONSE_FRAME_ID:
        on_sdo_response(a, f);
        break;
    case DEPTHPRO_DP200_DP_DRIVE_HEARTBEAT_FRAME_ID: {
        struct depthpro_dp200_dp_drive_heartbeat_t m;
        if (depthpro_dp200_dp_drive_heartbeat_unpack(&m, f->data, f->len) >= 0) {
            return on_drive_heartbeat(a, m.nmt_state & 0x7F, out);
        }
        break;
    }
    case DEPTHPRO_DP200_DP_SENSOR_HUB_FRAME_ID:
        on_sensor_hub(a, f);
        break;
    case DEPTHPRO_DP200_DP_SETPOINT_FRAME_ID:
        on_setpoint(a, f);
        break;
    case DEPTHPRO_DP200_DP_DRIVE_FEEDBACK_FRAME_ID:
        on_feedback(a, f);
        break;
    case DEPTHPRO_DP200_DP_DRIVE_DIAGNOSIS_FRAME_ID: {
        struct depthpro_dp200_dp_drive_diagnosis_t m;
        if (depthpro_dp200_dp_drive_diagnosis_unpack(&m, f->data, f->len) >= 0) {
            a->drive_error = m.error_code;
        }
        break;
    }
    default:
        break;
    }
    return 0;
}

/* --- the control step ------------------------------------------------------------------- */

static bool is_fault(uint16_t sw)
{
    return (sw & 0x0008u) != 0;
}

static bool is_operation_enabled(uint16_t sw)
{
    return (sw & 0x006Fu) == 0x0027u;
}

/* cia402_master.py next_controlword */
static uint16_t next_controlword(uint16_t sw, uint16_t last)
{
    if (is_fault(sw)) {
        return last == CW_FAULT_RESET ? CW_NO_COMMAND : CW_FAULT_RESET;
    }
    if ((sw & 0x004Fu) == 0x0040u) {
        return 0x06u; /* shutdown */
    }
    if ((sw & 0x006Fu) == 0x0021u) {
        return 0x07u; /* switch on */
    }
    if ((sw & 0x006Fu) == 0x0023u || (sw & 0x006Fu) == 0x0027u) {
        return 0x0Fu; /* enable operation */
    }
    return 0x06u;
}

/* dbc_adapter.py _drive_management: the NMT start once the configuration is confirmed, then
 * (once the drive reports Operational) the mode. */
static size_t drive_management(dp200_adapter_t *a, hal_can_frame_t *out)
{
    if (a->has_error) {
        return 0;
    }
    if (batch_done(&a->sdo) && !a->configured) {
        a->configured = true;
        if (a->drive_nmt != NMT_OPERATIONAL) {
            struct depthpro_dp200_dp_nmt_t m = {NMT_START, a->drive_node};
            out[0] = frame_of(DEPTHPRO_DP200_DP_NMT_FRAME_ID, DEPTHPRO_DP200_DP_NMT_IS_EXTENDED,
                              DEPTHPRO_DP200_DP_NMT_LENGTH);
            depthpro_dp200_dp_nmt_pack(out[0].data, &m, sizeof out[0].data);
            return 1;
        }
    }
    if (a->configured && a->drive_nmt == NMT_OPERATIONAL && !a->mode_sdo.active) {
        /* profile velocity, once per start of the drive: no PDO of ours maps 0x6060 */
        batch_start(a, &a->mode_sdo, MODE_WRITE, 1);
        return batch_frames(&a->mode_sdo, out);
    }
    return 0;
}

/* depth_law.py DepthLaw.step */
static void law_step(dp200_adapter_t *a, dp200_step_info_t *info)
{
    dp200_law_t *l = &a->law;
    const dp200_config_t *c = &a->cfg;
    uint16_t cw = next_controlword(l->statusword, l->last_controlword);
    l->last_controlword = cw;
    double limit = c->frozen_after_s;
    bool frozen = limit > 0.0 && l->have_x && now_s(a) - l->x_changed_at_s > limit + SLACK;
    bool drive_on = is_operation_enabled(l->statusword);
    bool valid = l->have_depth && l->depth_ok && !frozen && drive_on;
    double speed = 0.0;
    bool enabled = l->terminal_on && l->automatic && known_speed(a, &speed) &&
                   speed >= c->min_speed_mps;
    fpid_output_t out = fpid_step(&c->core, &l->core, l->target_mm,
                                  l->have_depth ? l->depth_mm : 0.0, valid, enabled);
    double speed_mm_s = out.speed_mm_s;
    l->holding = false;
    if (enabled && valid) {
        if (l->have_position) {
            rhold_track(&c->hold, &l->hold, l->position_mm, c->core.period_s);
        }
    } else if (!enabled) {
        rhold_reset(&l->hold);
    } else if (drive_on && l->have_position && l->hold.has_target) {
        l->holding = true;
        speed_mm_s = rhold_speed(&c->hold, &l->hold, l->position_mm);
    }
    *info = (dp200_step_info_t){cw, speed_mm_s, valid, enabled, frozen, 0};
}

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

/* depth_law.py DepthLaw.status and dbc_adapter.py _status_frame */
static hal_can_frame_t status_frame(const dp200_adapter_t *a, const dp200_step_info_t *info)
{
    const dp200_law_t *l = &a->law;
    int state;
    if (a->has_error || is_fault(l->statusword)) {
        state = ST_FAULT; /* a refused configuration is a fault */
    } else if (l->manual) {
        state = ST_MANUAL;
    } else if (info->valid && info->enabled) {
        state = ST_CONTROLLING;
    } else if (is_operation_enabled(l->statusword)) {
        state = ST_READY;
    } else {
        state = ST_INITIALISING;
    }
    static const uint8_t STATE_RAW[] = {
        DEPTHPRO_DP200_DP_STATUS_STATE_INIT_CHOICE,
        DEPTHPRO_DP200_DP_STATUS_STATE_STANDBY_CHOICE,
        DEPTHPRO_DP200_DP_STATUS_STATE_REGULATING_CHOICE,
        DEPTHPRO_DP200_DP_STATUS_STATE_MANUAL_CHOICE,
        DEPTHPRO_DP200_DP_STATUS_STATE_FAULT_CHOICE,
    };
    double depth_mm = dp200_py_round(l->have_depth ? clamp(l->depth_mm, -100.0, 200.0) : 0.0, 1);
    /* holding: the hold target in whole 0.01 mm (half to even); regulating in profile
     * velocity mode there is no position command: 0 */
    double command_mm = 0.0;
    if (l->holding && l->hold.has_target) {
        command_mm = rint(clamp(l->hold.target_mm, 0.0, 100.0) * 100.0) / 100.0;
    }
    double speed = 0.0;
    struct depthpro_dp200_dp_status_t st;
    memset(&st, 0, sizeof st);
    st.depth_cm = (int16_t)raw_of(depth_mm / CM_TO_MM,
                                  depthpro_dp200_dp_status_depth_cm_decode(1) -
                                      depthpro_dp200_dp_status_depth_cm_decode(0));
    st.roller_cmd = (uint16_t)raw_of(command_mm / UM_TO_MM,
                                     depthpro_dp200_dp_status_roller_cmd_decode(1) -
                                         depthpro_dp200_dp_status_roller_cmd_decode(0));
    st.state = STATE_RAW[state];
    st.sensor_fault = (uint8_t)(!l->have_depth || !l->depth_ok || info->frozen);
    st.drive_fault = (uint8_t)(is_fault(l->statusword) ? 1u : 0u);
    st.no_speed = (uint8_t)(known_speed(a, &speed) ? 0u : 1u);
    st.seq = (uint8_t)((l->steps / STATUS_EVERY) % 16u);
    st.drive_error = a->drive_error;
    hal_can_frame_t f = frame_of(DEPTHPRO_DP200_DP_STATUS_FRAME_ID,
                                 DEPTHPRO_DP200_DP_STATUS_IS_EXTENDED,
                                 DEPTHPRO_DP200_DP_STATUS_LENGTH);
    depthpro_dp200_dp_status_pack(f.data, &st, sizeof f.data);
    return f;
}

size_t dp200_step(dp200_adapter_t *a, hal_can_frame_t out[DP200_MAX_OUT])
{
    check_timeout(a, &a->sdo);
    check_timeout(a, &a->mode_sdo);
    size_t n = drive_management(a, out);
    dp200_step_info_t *info = &a->last;
    law_step(a, info);
    if (a->law.steps % STATUS_EVERY == 0) {
        out[n++] = status_frame(a, info);
    }
    if (a->law.steps % HEARTBEAT_EVERY == 0) {
        out[n++] = heartbeat(DEPTHPRO_DP200_DP_HEARTBEAT_NMT_STATE_OPERATIONAL_CHOICE);
    }
    /* the command last: in lockstep it closes the step */
    double scale = depthpro_dp200_dp_drive_command_target_velocity_decode(1) -
                   depthpro_dp200_dp_drive_command_target_velocity_decode(0);
    info->target_velocity = (int32_t)raw_of(info->speed_mm_s, scale);
    struct depthpro_dp200_dp_drive_command_t cmd = {info->target_velocity, info->controlword};
    out[n] = frame_of(DEPTHPRO_DP200_DP_DRIVE_COMMAND_FRAME_ID,
                      DEPTHPRO_DP200_DP_DRIVE_COMMAND_IS_EXTENDED,
                      DEPTHPRO_DP200_DP_DRIVE_COMMAND_LENGTH);
    depthpro_dp200_dp_drive_command_pack(out[n].data, &cmd, sizeof out[n].data);
    n++;
    a->law.steps++;
    return n;
}
