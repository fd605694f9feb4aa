/* The fertilizer firmware (firmware/apps/fertilizer_adapter.c and its core, unchanged) as an
 * FMI-LS-BUS CAN node: its frames cross Rx_Data / Tx_Data instead of a socket.
 *
 * The loop is agrihil-fertilizer-fw's in lockstep (firmware/apps/app.c): the boot-up frame at
 * start, one control step per received SYNC (0x080) with the adapter clock at steps x period,
 * every other frame handed to the adapter stamped with that clock. Parameters: mode (the law:
 * physical, paper-literal, open-loop) and ff_coeff, as the firmware's --param. */
#include <math.h>
#include <string.h>

#include "model.h"
#include "params.h"

#define SYNC_ID 0x080u

static void start(ModelInstance *comp)
{
    if (M(started)) {
        return;
    }
    ppid_law_t law = PPID_LAW_PHYSICAL;
    if (M(mode)[0] != '\0' && !ppid_law_parse(M(mode), &law)) {
        logError(comp, "parameter mode = '%s': not a law (physical, paper-literal, open-loop)",
                 M(mode));
        M(failed) = true;
        return;
    }
    fert_config_t cfg;
    fert_config_defaults(&cfg, law);
    if (M(ff_coeff_given)) {
        param_ref_t refs[FERT_PARAM_COUNT];
        size_t n = fert_param_refs(&cfg, refs);
        bool found = false;
        for (size_t i = 0; i < n; i++) {
            if (param_name_equal(refs[i].name, "ff_coeff")) {
                *refs[i].value = M(ff_coeff);
                found = true;
            }
        }
        if (!found) {
            logError(comp, "parameter ff_coeff: the %s law has none", ppid_law_name(law));
            M(failed) = true;
            return;
        }
    }
    fert_init(&M(adapter), &cfg);
    hal_can_frame_t boot = fert_bootup();
    lsbus_node_transmit(&M(node), &boot);
    M(started) = true;
}

Status setStartValues(ModelInstance *comp)
{
    lsbus_node_init(&M(node));
    M(started) = false;
    M(steps) = 0;
    M(mode)[0] = '\0';
    M(ff_coeff) = 0.0;
    M(ff_coeff_given) = false;
    M(failed) = false;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

static void on_frame(void *ctx, const hal_can_frame_t *f)
{
    ModelInstance *comp = (ModelInstance *)ctx;
    const double now_s = (double)M(steps) * M(adapter).cfg.period_s;
    if (!f->extended && f->id == SYNC_ID) {
        hal_can_frame_t out[FERT_MAX_OUT];
        size_t n = fert_step(&M(adapter), now_s, out);
        M(steps)++;
        for (size_t i = 0; i < n; i++) {
            if (!lsbus_node_transmit(&M(node), &out[i])) {
                logError(comp, "Tx_Data full: frame 0x%X not sent", (unsigned)out[i].id);
            }
        }
    } else {
        fert_on_frame(&M(adapter), f, now_s);
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
    switch (vr) {
    case vr_time:
        values[(*index)++] = comp->time;
        return OK;
    case vr_ff_coeff:
        values[(*index)++] = M(ff_coeff);
        return OK;
    default:
        logError(comp, "Get Float64 is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr != vr_ff_coeff || M(started)) {
        logError(comp, "Set Float64 is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    M(ff_coeff) = values[(*index)++];
    M(ff_coeff_given) = true;
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
    if (vr != vr_mode || M(started) || text == NULL || strlen(text) >= MODE_TEXT) {
        logError(comp, "Set String is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    strcpy(M(mode), text);
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
    if (vr != vr_rx_data) {
        logError(comp, "Set Binary is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    if (!lsbus_node_set_rx(&M(node), (const uint8_t *)values[*index], size[*index])) {
        logError(comp, "Rx_Data of %zu bytes does not fit %d.", size[*index],
                 LSBUS_NODE_BUFFER);
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
