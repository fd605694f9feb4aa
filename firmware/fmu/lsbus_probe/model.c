/* A diagnostic LS-BUS CAN node: it reports, in a frame, what the bus simulation told it.
 *
 * Report frame (id `report_id`, default 0x1A0, 8 bytes): confirms, arbitration lost, bus
 * errors, bus errors as sender, last status (1 active, 2 passive, 3 bus off), frames received
 * (low byte), wake-ups, SYNCs seen (low byte). It is sent at every SYNC (0x080) it receives
 * (triggered Tx_Clock) or, built with PROBE_TIMED, at every tick of its time-based Tx_Clock.
 * Parameters: fd_at_step (send a CAN FD frame at that SYNC), baudrate and arbitration
 * (configuration operations at start; 0: none), wakeup_at_step (not used by the bus),
 * crash_at_step (abort() the process at that SYNC: a virtual ECU that crashes). */
#include <stdlib.h>
#include <string.h>

#include "model.h"

#define SYNC_ID 0x080u

static void start(ModelInstance *comp)
{
    if (M(started)) {
        return;
    }
    M(started) = true;
    if (M(baudrate) > 0) {
        lsbus_node_configure_baudrate(&M(node), (uint32_t)M(baudrate));
    }
    if (M(arbitration) > 0) {
        lsbus_node_configure_arbitration(&M(node), (uint8_t)M(arbitration));
    }
}

Status setStartValues(ModelInstance *comp)
{
    memset(&M(node), 0, sizeof M(node));
    lsbus_node_init(&M(node));
    M(started) = false;
    M(tick) = false;
    M(syncs) = 0;
    M(report_id) = 0x1A0;
    M(fd_at_step) = 0;
    M(baudrate) = 0;
    M(arbitration) = 0;
    M(wakeup_at_step) = 0;
    M(crash_at_step) = 0;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

static void report(ModelInstance *comp)
{
    const lsbus_node_t *n = &M(node);
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = (uint32_t)M(report_id);
    f.len = 8;
    f.data[0] = (uint8_t)n->confirms;
    f.data[1] = (uint8_t)n->arbitration_lost;
    f.data[2] = (uint8_t)n->bus_errors;
    f.data[3] = (uint8_t)n->bus_errors_as_sender;
    f.data[4] = n->status;
    f.data[5] = (uint8_t)n->frames_in;
    f.data[6] = (uint8_t)n->wakeups;
    f.data[7] = (uint8_t)M(syncs);
    lsbus_node_transmit(&M(node), &f);
}

static void on_frame(void *ctx, const hal_can_frame_t *f)
{
    ModelInstance *comp = (ModelInstance *)ctx;
    if (f->extended || f->id != SYNC_ID) {
        return;
    }
    M(syncs)++;
    if (M(crash_at_step) > 0 && M(syncs) == M(crash_at_step)) {
        abort();
    }
    if (M(fd_at_step) > 0 && M(syncs) == M(fd_at_step)) {
        const uint8_t data[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
        lsbus_node_transmit_fd(&M(node), 0x1A1, data, sizeof data);
    }
#ifndef PROBE_TIMED
    report(comp);
#endif
}

Status eventUpdate(ModelInstance *comp)
{
    start(comp);
    if (!lsbus_node_read(&M(node), on_frame, comp)) {
        logError(comp, "Rx_Data holds a malformed operation");
        return Error;
    }
    if (M(tick)) {
        M(tick) = false;
        report(comp);
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
    if (vr != vr_time) {
        logError(comp, "Get Float64 is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    values[(*index)++] = comp->time;
    return OK;
}

static int32_t *int_param(ModelInstance *comp, ValueReference vr)
{
    switch (vr) {
    case vr_report_id: return &M(report_id);
    case vr_fd_at_step: return &M(fd_at_step);
    case vr_baudrate: return &M(baudrate);
    case vr_arbitration: return &M(arbitration);
    case vr_wakeup_at_step: return &M(wakeup_at_step);
    case vr_crash_at_step: return &M(crash_at_step);
    default: return NULL;
    }
}

Status getInt32(ModelInstance *comp, ValueReference vr, int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    int32_t *p = int_param(comp, vr);
    if (p == NULL) {
        logError(comp, "Get Int32 is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    values[(*index)++] = *p;
    return OK;
}

Status setInt32(ModelInstance *comp, ValueReference vr, const int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    int32_t *p = int_param(comp, vr);
    if (p == NULL || M(started)) {
        logError(comp, "Set Int32 is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    *p = values[(*index)++];
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
    if (vr == vr_rx_clock) {
        M(node).rx_clock = true;
        return OK;
    }
#ifdef PROBE_TIMED
    if (vr == vr_tx_clock) {
        M(tick) = true;
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
    return OK;
}
