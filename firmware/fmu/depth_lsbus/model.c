/* The sowing-depth firmware (firmware/apps/depth_adapter.c and its core, unchanged) as an
 * FMI-LS-BUS CAN node, looped as agrihil-depth-fw is in lockstep (firmware/apps/app.c and
 * depth_main.c): the boot-up frame at start, one control step per SYNC with the adapter clock
 * at steps x period, the adapter's answers to a frame sent at once, and, when the string
 * parameter agrihil_gnss_port names a serial port (the rig's AGRIHIL_GNSS_PORT), the GNSS
 * receiver's NMEA read before each frame is handled. Parameters kp0, ki0, kd0 as --param. */
#include <string.h>

#include "model.h"
#include "params.h"

#define SYNC_ID 0x080u
#define GNSS_BAUD 115200

static const char *const PARAM_NAMES[N_PARAMS] = {"kp0", "ki0", "kd0"};

static void start(ModelInstance *comp)
{
    if (M(started)) {
        return;
    }
    M(started) = true;
    depth_config_t cfg;
    depth_config_defaults(&cfg);
    param_ref_t refs[DEPTH_PARAM_COUNT];
    size_t n = depth_param_refs(&cfg, refs);
    for (size_t p = 0; p < N_PARAMS; p++) {
        if (!M(param_given)[p]) {
            continue;
        }
        bool found = false;
        for (size_t i = 0; i < n; i++) {
            if (param_name_equal(refs[i].name, PARAM_NAMES[p])) {
                *refs[i].value = M(param)[p];
                found = true;
            }
        }
        if (!found) {
            logError(comp, "parameter %s: the depth controller has none", PARAM_NAMES[p]);
            M(failed) = true;
            return;
        }
    }
    char err[128];
    if (depth_config_check(&cfg, err, sizeof err) != 0) {
        logError(comp, "%s", err);
        M(failed) = true;
        return;
    }
    depth_init(&M(adapter), &cfg);
    nmea_init(&M(nmea));
    if (M(gnss_port)[0] != '\0') {
        if (hal_serial_open(&M(gnss), M(gnss_port), GNSS_BAUD) != 0) {
            logError(comp, "GNSS (agrihil_gnss_port): %s", M(gnss).error);
            M(failed) = true;
            return;
        }
        M(gnss_open) = true;
    }
    hal_can_frame_t boot = depth_bootup();
    lsbus_node_transmit(&M(node), &boot);
}

Status setStartValues(ModelInstance *comp)
{
    memset(&comp->modelData, 0, sizeof comp->modelData);
    lsbus_node_init(&M(node));
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

static double now_s(ModelInstance *comp)
{
    return (double)M(steps) * M(adapter).cfg.core.period_s;
}

static void poll_gnss(ModelInstance *comp)
{
    if (!M(gnss_open)) {
        return;
    }
    char buf[256];
    for (;;) {
        long n = hal_serial_read(&M(gnss), buf, sizeof buf);
        if (n < 0) {
            logError(comp, "GNSS: %s; going on without it", M(gnss).error);
            hal_serial_close(&M(gnss));
            M(gnss_open) = false;
            return;
        }
        if (n == 0) {
            return;
        }
        for (long i = 0; i < n; i++) {
            double mps;
            nmea_result_t r = nmea_feed(&M(nmea), buf[i], &mps);
            if (r == NMEA_SPEED) {
                depth_on_gnss(&M(adapter), true, mps, now_s(comp));
            } else if (r == NMEA_NO_FIX) {
                depth_on_gnss(&M(adapter), false, 0.0, now_s(comp));
            }
        }
    }
}

static void on_frame(void *ctx, const hal_can_frame_t *f)
{
    ModelInstance *comp = (ModelInstance *)ctx;
    poll_gnss(comp);
    hal_can_frame_t out[DEPTH_MAX_OUT];
    size_t n;
    if (!f->extended && f->id == SYNC_ID) {
        n = depth_step(&M(adapter), now_s(comp), out);
        M(steps)++;
    } else {
        n = depth_on_frame(&M(adapter), f, now_s(comp), out);
    }
    for (size_t i = 0; i < n; i++) {
        if (!lsbus_node_transmit(&M(node), &out[i])) {
            logError(comp, "Tx_Data full: frame 0x%X not sent", (unsigned)out[i].id);
        }
    }
}

Status eventUpdate(ModelInstance *comp)
{
    start(comp);
    if (M(failed)) {
        return Error;
    }
    if (!lsbus_node_read(&M(node), on_frame, comp)) {
        logError(comp, "Rx_Data holds a malformed operation");
        return Error;
    }
    comp->valuesOfContinuousStatesChanged = false;
    comp->nominalsOfContinuousStatesChanged = false;
    comp->newDiscreteStatesNeeded = false;
    comp->terminateSimulation = false;
    comp->nextEventTimeDefined = false;
    return OK;
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr == vr_time) {
        values[(*index)++] = comp->time;
        return OK;
    }
    if (vr >= vr_kp0 && vr < vr_kp0 + N_PARAMS) {
        values[(*index)++] = M(param)[vr - vr_kp0];
        return OK;
    }
    logError(comp, "Get Float64 is not allowed for value reference %u.", (unsigned)vr);
    return Error;
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr < vr_kp0 || vr >= vr_kp0 + N_PARAMS || M(started)) {
        logError(comp, "Set Float64 is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    M(param)[vr - vr_kp0] = values[(*index)++];
    M(param_given)[vr - vr_kp0] = true;
    return OK;
}

Status setBoolean(ModelInstance *comp, ValueReference vr, const bool values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr != vr_bus_notifications) {
        logError(comp, "Set Boolean is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    M(node).notifications = values[(*index)++];
    return OK;
}

Status setString(ModelInstance *comp, ValueReference vr, const char *const values[],
                 size_t nValues, size_t *index)
{
    ASSERT_NVALUES(1);
    const char *text = values[(*index)++];
    if (vr != vr_gnss_port || M(started) || text == NULL || strlen(text) >= PORT_TEXT) {
        logError(comp, "Set String is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    strcpy(M(gnss_port), text);
    return OK;
}

Status getBinary(ModelInstance *comp, ValueReference vr, size_t sizes[], const char *values[],
                 size_t nValues, size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr != vr_tx_data) {
        logError(comp, "Get Binary is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    start(comp);
    size_t len = 0;
    const uint8_t *data = lsbus_node_tx(&M(node), &len);
    sizes[*index] = len;
    values[*index] = (const char *)data;
    (*index)++;
    return OK;
}

Status setBinary(ModelInstance *comp, ValueReference vr, const size_t size[],
                 const char *const values[], size_t nValues, size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr != vr_rx_data ||
        !lsbus_node_set_rx(&M(node), (const uint8_t *)values[*index], size[*index])) {
        logError(comp, "Set Binary is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    (*index)++;
    return OK;
}

Status activateClock(ModelInstance *comp, ValueReference vr)
{
    if (vr != vr_rx_clock) {
        logError(comp, "Activate Clock is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    M(node).rx_clock = true;
    return OK;
}

Status getClock(ModelInstance *comp, ValueReference vr, bool *value)
{
    if (vr != vr_tx_clock) {
        logError(comp, "Get Clock is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    start(comp);
    *value = lsbus_node_take_tx_clock(&M(node));
    return M(failed) ? Error : OK;
}
