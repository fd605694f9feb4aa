#include "iso_depth.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sowing_depth.h"

#define SYNC_ID 0x080u
#define SEEDER_FUNCTION 128u
#define DEVICE_CLASS_PLANTERS 4u
#define INDUSTRY_GROUP_AGRICULTURE 2u
#define STATUS_SOURCE 0x80u /* DepthControllerStatus's source in the rig's DBC */
#define DS_ENABLE_ON 1u
#define DS_MODE_AUTOMATIC 1u

void iso_depth_config_defaults(iso_depth_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    depth_config_defaults(&cfg->depth);
    cfg->address = 0x82;
    cfg->identity_number = 0x0D42;
    cfg->default_depth_mm = 30.0;
    cfg->min_depth_mm = 10.0;
    cfg->max_depth_mm = 60.0;
    cfg->latency_ms = 1000.0;
    cfg->fixed_depth_mm = 0.0;
    cfg->step_on_sync = true;
}

size_t iso_depth_param_refs(iso_depth_config_t *cfg, param_ref_t refs[ISO_DEPTH_PARAM_COUNT])
{
    size_t n = depth_param_refs(&cfg->depth, refs);
    refs[n++] = (param_ref_t){"address", &cfg->address};
    refs[n++] = (param_ref_t){"identity_number", &cfg->identity_number};
    refs[n++] = (param_ref_t){"default_depth_mm", &cfg->default_depth_mm};
    refs[n++] = (param_ref_t){"min_depth_mm", &cfg->min_depth_mm};
    refs[n++] = (param_ref_t){"max_depth_mm", &cfg->max_depth_mm};
    refs[n++] = (param_ref_t){"latency_ms", &cfg->latency_ms};
    refs[n++] = (param_ref_t){"fixed_depth_mm", &cfg->fixed_depth_mm};
    return n;
}

int iso_depth_word_param(iso_depth_config_t *cfg, const char *key, const char *value,
                         const char **why)
{
    if (param_name_equal(key, "actual")) {
        if (strcmp(value, "sensed") != 0 && strcmp(value, "setpoint") != 0) {
            *why = "actual must be sensed or setpoint";
            return -1;
        }
        cfg->actual_setpoint = strcmp(value, "setpoint") == 0;
        return 1;
    }
    if (param_name_equal(key, "fallback")) {
        if (strcmp(value, "default") != 0 && strcmp(value, "hold") != 0) {
            *why = "fallback must be default or hold";
            return -1;
        }
        cfg->fallback_hold = strcmp(value, "hold") == 0;
        return 1;
    }
    return 0;
}

int iso_depth_check(const iso_depth_config_t *cfg, char *err, size_t errlen)
{
    const char *why = NULL;
    if (!(cfg->address == floor(cfg->address) && cfg->address >= 0.0 && cfg->address <= 253.0)) {
        why = "address must be an integer 0 .. 253";
    } else if (!(cfg->identity_number == floor(cfg->identity_number) &&
                 cfg->identity_number >= 0.0 && cfg->identity_number < 2097152.0)) {
        why = "identity_number must be an integer below 2^21";
    } else if (!(0.0 < cfg->min_depth_mm && cfg->min_depth_mm <= cfg->default_depth_mm &&
                 cfg->default_depth_mm <= cfg->max_depth_mm && cfg->max_depth_mm <= 100.0)) {
        why = "need 0 < min_depth_mm <= default_depth_mm <= max_depth_mm <= 100";
    } else if (!(isfinite(cfg->latency_ms) && cfg->latency_ms >= 0.0 &&
                 cfg->latency_ms <= 10000.0)) {
        why = "latency_ms must be within [0, 10000]";
    } else if (!(cfg->fixed_depth_mm == 0.0 || (cfg->min_depth_mm <= cfg->fixed_depth_mm &&
                                                 cfg->fixed_depth_mm <= cfg->max_depth_mm))) {
        why = "fixed_depth_mm must be 0 or within the depth range";
    }
    if (why != NULL) {
        snprintf(err, errlen, "%s", why);
        return -1;
    }
    return depth_config_check(&cfg->depth, err, errlen);
}

static uint64_t implement_name(uint32_t identity)
{
    return (uint64_t)identity | ((uint64_t)SEEDER_FUNCTION << 40) |
           ((uint64_t)DEVICE_CLASS_PLANTERS << 49) |
           ((uint64_t)INDUSTRY_GROUP_AGRICULTURE << 60) | ((uint64_t)1 << 63);
}

static double now_s(const iso_depth_t *c)
{
    /* the Python's now_s: steps done x period (the time of the next step) */
    return (double)c->adapter.steps * c->cfg.depth.core.period_s;
}

static bool connected(const iso_depth_t *c)
{
    return tcc_connected(&c->tc);
}

double iso_depth_target_mm(const iso_depth_t *c)
{
    if (c->cfg.fixed_depth_mm > 0.0) {
        return c->cfg.fixed_depth_mm;
    }
    if (c->has_tc_depth && (connected(c) || c->cfg.fallback_hold)) {
        return c->tc_depth_mm;
    }
    return c->cfg.default_depth_mm;
}

uint32_t iso_depth_steps(const iso_depth_t *c)
{
    return c->adapter.steps;
}

/* --- what the TC sets and reads -------------------------------------------------------------- */

static uint8_t on_setpoint(void *ctx, uint16_t element, uint16_t ddi, int32_t value)
{
    iso_depth_t *c = ctx;
    if (element != c->pool.boom || ddi != ISO_DDI_SETPOINT_SEEDING_DEPTH) {
        return ISO_ACK_DDI_NOT_SUPPORTED;
    }
    double mm = (double)value;
    if (!(c->cfg.min_depth_mm <= mm && mm <= c->cfg.max_depth_mm)) {
        return ISO_ACK_OUT_OF_RANGE;
    }
    c->has_tc_depth = true;
    c->tc_depth_mm = mm;
    return 0;
}

static bool read_value(void *ctx, uint16_t element, uint16_t ddi, int64_t *value)
{
    iso_depth_t *c = ctx;
    if (element != c->pool.boom) {
        return false;
    }
    if (ddi == ISO_DDI_SETPOINT_SEEDING_DEPTH ||
        (ddi == ISO_DDI_ACTUAL_SEEDING_DEPTH && c->cfg.actual_setpoint)) {
        *value = (int64_t)rint(c->target_mm);
        return true;
    }
    if (ddi == ISO_DDI_ACTUAL_SEEDING_DEPTH) {
        const depth_adapter_t *a = &c->adapter;
        *value = a->have_depth && a->depth_ok ? (int64_t)rint(a->depth_mm) : 0;
        return true;
    }
    return false;
}

static void on_connection(void *ctx, bool is_connected)
{
    iso_depth_t *c = ctx;
    (void)is_connected; /* lost or new: no set-point until the TC sends one (the default
                         * meanwhile); fallback=hold keeps the last one, the must-fail's defect */
    if (!c->cfg.fallback_hold) {
        c->has_tc_depth = false;
    }
}

static iso_depth_ddop_params_t pool_params(const iso_depth_t *c, unsigned version)
{
    iso_depth_ddop_params_t p = {c->name,
                                 ISO_DEPTH_WIDTH_M,
                                 ISO_DEPTH_OFFSET_X_MM,
                                 c->cfg.latency_ms,
                                 c->cfg.default_depth_mm,
                                 c->cfg.min_depth_mm,
                                 c->cfg.max_depth_mm,
                                 version};
    return p;
}

static int write_pool(void *ctx, unsigned version, uint8_t *buf, size_t cap, size_t *size)
{
    iso_depth_ddop_params_t p = pool_params(ctx, version);
    iso_ddop_info_t info;
    if (iso_depth_pool(&p, buf, cap, &info) != 0) {
        return -1;
    }
    *size = info.size;
    return 0;
}

static void deliver(void *ctx, uint32_t pgn, const uint8_t *data, size_t len, uint8_t source,
                    uint8_t destination, double t)
{
    iso_depth_t *c = ctx;
    tcc_on_group(&c->tc, pgn, data, len, source, destination, t);
}

/* --- set-up and frames ------------------------------------------------------------------------- */

int iso_depth_init(iso_depth_t *c, const iso_depth_config_t *cfg)
{
    memset(c, 0, sizeof *c);
    c->cfg = *cfg;
    depth_init(&c->adapter, &cfg->depth);
    c->name = implement_name((uint32_t)cfg->identity_number);
    c->target_mm = cfg->default_depth_mm;
    /* the implement works automatically: the adapter's terminal is always on + automatic */
    c->adapter.have_setpoint = true;
    c->adapter.ds_enable = DS_ENABLE_ON;
    c->adapter.ds_mode = DS_MODE_AUTOMATIC;
    c->adapter.target_mm = c->target_mm;
    /* the pool's table (and a check that it fits TP) from the version 4 bytes */
    static uint8_t scratch[ISO_DDOP_MAX_BYTES];
    iso_depth_ddop_params_t p = pool_params(c, 4);
    if (iso_depth_pool(&p, scratch, sizeof scratch, &c->pool) != 0) {
        return -1;
    }
    iso_net_init(&c->net, c->name, (uint8_t)cfg->address, deliver, c);
    tcc_implement_t impl = {c, on_setpoint, read_value, on_connection};
    tcc_init(&c->tc, &c->net, &c->pool, impl, write_pool);
    return 0;
}

hal_can_frame_t iso_depth_bootup(void)
{
    return depth_bootup();
}

void iso_depth_on_gnss(iso_depth_t *c, bool valid, double speed_mps)
{
    depth_on_gnss(&c->adapter, valid, speed_mps, now_s(c));
}

size_t iso_depth_step(iso_depth_t *c)
{
    double t = now_s(c);
    iso_net_poll(&c->net, t);
    tcc_tick(&c->tc, t);
    /* the network's answers since the last step, then what is due */
    size_t n = c->net.nout;
    memcpy(c->out, c->net.out, n * sizeof c->out[0]);
    c->net.nout = 0;
    c->target_mm = iso_depth_target_mm(c);
    c->adapter.target_mm = c->target_mm;
    hal_can_frame_t own[DEPTH_MAX_OUT];
    size_t m = depth_step(&c->adapter, t, own);
    int address = iso_net_address(&c->net);
    for (size_t i = 0; i < m; i++) {
        if (own[i].extended && (own[i].id & 0xFFu) == STATUS_SOURCE) {
            /* the status from the claimed address, and none before the claim (ISO 11783-5:
             * nothing but the claim before it) */
            if (address == ISO_NO_ADDRESS) {
                continue;
            }
            own[i].id = (own[i].id & ~0xFFu) | (uint32_t)address;
        }
        c->out[n++] = own[i];
    }
    c->nout = n;
    return n;
}

size_t iso_depth_on_frame(iso_depth_t *c, const hal_can_frame_t *f)
{
    c->nout = 0;
    if (f->extended) {
        iso_net_on_frame(&c->net, f, now_s(c));
        if (f->id == SOWING_DEPTH_DEPTH_SETPOINT_FRAME_ID) {
            return 0; /* the terminal's set-point: not listened to in ISOBUS mode */
        }
    } else if (f->id == SYNC_ID) {
        return c->cfg.step_on_sync ? iso_depth_step(c) : 0;
    }
    c->nout = depth_on_frame(&c->adapter, f, now_s(c), c->out);
    return c->nout;
}
