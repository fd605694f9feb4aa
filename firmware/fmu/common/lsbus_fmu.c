/* The common LS-BUS CAN node FMU: the skeleton's model functions for the CAN terminal, the
 * clocks, the time, Can_BusNotifications and the model's parameter table, around the model's
 * hooks (common/lsbus_fmu.h). */
#include "lsbus_fmu.h"

#include <string.h>

static const lsbus_param_t *param_of(ValueReference vr, lsbus_param_kind_t kind, size_t *index)
{
    for (size_t i = 0; i < lsbus_model_param_count; i++) {
        if (lsbus_model_params[i].vr == vr && lsbus_model_params[i].kind == kind) {
            *index = i;
            return &lsbus_model_params[i];
        }
    }
    return NULL;
}

static void *value_of(ModelInstance *comp, const lsbus_param_t *p)
{
    return (char *)&comp->modelData + p->offset;
}

bool lsbus_fmu_given(const ModelInstance *comp, ValueReference vr)
{
    for (size_t i = 0; i < lsbus_model_param_count && i < 32; i++) {
        if (lsbus_model_params[i].vr == vr) {
            return (M(given) >> i) & 1u;
        }
    }
    return false;
}

void lsbus_fmu_send(ModelInstance *comp, const hal_can_frame_t *frames, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (!lsbus_node_transmit(&M(node), &frames[i])) {
            logError(comp, "Tx_Data full: frame 0x%X not sent", (unsigned)frames[i].id);
        }
    }
}

#ifndef AGRIHIL_FMU_STANDALONE
bool lsbus_fmu_apply_float64(ModelInstance *comp, const param_ref_t *refs, size_t n,
                             const char *owner)
{
    for (size_t p = 0; p < lsbus_model_param_count; p++) {
        const lsbus_param_t *param = &lsbus_model_params[p];
        if (param->kind != LSBUS_PARAM_FLOAT64 || !lsbus_fmu_given(comp, param->vr)) {
            continue;
        }
        bool found = false;
        for (size_t i = 0; i < n; i++) {
            if (param_name_equal(refs[i].name, param->name)) {
                memcpy(refs[i].value, value_of(comp, param), sizeof(double));
                found = true;
            }
        }
        if (!found) {
            logError(comp, "parameter %s: %s has none", param->name, owner);
            return false;
        }
    }
    return true;
}
#endif

/* the node starts once its parameters are fixed: at its first event, or when the importer
 * first reads Tx_Data or Tx_Clock (the boot-up frame goes out at time 0) */
static void start(ModelInstance *comp)
{
    if (M(started)) {
        return;
    }
    M(started) = true;
    if (!lsbus_model_start(comp)) {
        M(failed) = true;
    }
}

Status setStartValues(ModelInstance *comp)
{
    memset(&comp->modelData, 0, sizeof comp->modelData);
    lsbus_node_init(&M(node));
    lsbus_model_defaults(comp);
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

static void on_frame(void *ctx, const hal_can_frame_t *f)
{
    lsbus_model_on_frame((ModelInstance *)ctx, f);
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
#ifdef LSBUS_FMU_TIMED_TX_CLOCK
    if (M(tx_tick)) {
        M(tx_tick) = false;
        lsbus_model_on_tick(comp);
    }
#endif
    comp->valuesOfContinuousStatesChanged = false;
    comp->nominalsOfContinuousStatesChanged = false;
    comp->newDiscreteStatesNeeded = false;
    comp->terminateSimulation = false;
    comp->nextEventTimeDefined = false;
    return OK;
}

/* --- parameters ------------------------------------------------------------------------- */

/* The parameter of vr and kind that may be set now (before the start), else NULL (logged). */
static const lsbus_param_t *settable(ModelInstance *comp, ValueReference vr,
                                     lsbus_param_kind_t kind, const char *type, size_t *index)
{
    const lsbus_param_t *p = param_of(vr, kind, index);
    if (p == NULL || M(started)) {
        logError(comp, "Set %s is not allowed for value reference %u now.", type, (unsigned)vr);
        return NULL;
    }
    return p;
}

static void mark_given(ModelInstance *comp, size_t index)
{
    if (index < 32) {
        M(given) |= 1u << index;
    }
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (vr == vr_time) {
        values[(*index)++] = comp->time;
        return OK;
    }
    size_t i;
    const lsbus_param_t *p = param_of(vr, LSBUS_PARAM_FLOAT64, &i);
    if (p == NULL) {
        logError(comp, "Get Float64 is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    memcpy(&values[(*index)++], value_of(comp, p), sizeof(double));
    return OK;
}

#ifdef SET_FLOAT64
Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    size_t i;
    const lsbus_param_t *p = settable(comp, vr, LSBUS_PARAM_FLOAT64, "Float64", &i);
    if (p == NULL) {
        return Error;
    }
    memcpy(value_of(comp, p), &values[(*index)++], sizeof(double));
    mark_given(comp, i);
    return OK;
}
#endif

#ifdef GET_INT32
Status getInt32(ModelInstance *comp, ValueReference vr, int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    size_t i;
    const lsbus_param_t *p = param_of(vr, LSBUS_PARAM_INT32, &i);
    if (p == NULL) {
        logError(comp, "Get Int32 is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    memcpy(&values[(*index)++], value_of(comp, p), sizeof(int32_t));
    return OK;
}
#endif

#ifdef SET_INT32
Status setInt32(ModelInstance *comp, ValueReference vr, const int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    size_t i;
    const lsbus_param_t *p = settable(comp, vr, LSBUS_PARAM_INT32, "Int32", &i);
    if (p == NULL) {
        return Error;
    }
    memcpy(value_of(comp, p), &values[(*index)++], sizeof(int32_t));
    mark_given(comp, i);
    return OK;
}
#endif

#ifdef SET_STRING
Status setString(ModelInstance *comp, ValueReference vr, const char *const values[],
                 size_t nValues, size_t *index)
{
    ASSERT_NVALUES(1);
    const char *text = values[(*index)++];
    size_t i;
    const lsbus_param_t *p = settable(comp, vr, LSBUS_PARAM_STRING, "String", &i);
    if (p == NULL) {
        return Error;
    }
    if (text == NULL || strlen(text) >= p->size) {
        logError(comp, "Set String of value reference %u: longer than %zu characters.",
                 (unsigned)vr, p->size - 1);
        return Error;
    }
    memcpy(value_of(comp, p), text, strlen(text) + 1);
    mark_given(comp, i);
    return OK;
}
#endif

/* --- the CAN terminal --------------------------------------------------------------------- */

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
    if (vr == vr_rx_clock) {
        M(node).rx_clock = true;
        return OK;
    }
#ifdef LSBUS_FMU_TIMED_TX_CLOCK
    if (vr == vr_tx_clock) {
        M(tx_tick) = true;
        return OK;
    }
#endif
    logError(comp, "Activate Clock is not allowed for value reference %u.", (unsigned)vr);
    return Error;
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
