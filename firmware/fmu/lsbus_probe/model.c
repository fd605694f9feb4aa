/* A diagnostic LS-BUS CAN node (common/lsbus_fmu.h): it reports, in a frame, what the bus
 * simulation told it.
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

#include "lsbus_fmu.h"

#define SYNC_ID 0x080u

const lsbus_param_t lsbus_model_params[] = {
    LSBUS_PARAM(vr_report_id, LSBUS_PARAM_INT32, "report_id", report_id),
    LSBUS_PARAM(vr_fd_at_step, LSBUS_PARAM_INT32, "fd_at_step", fd_at_step),
    LSBUS_PARAM(vr_baudrate, LSBUS_PARAM_INT32, "baudrate", baudrate),
    LSBUS_PARAM(vr_arbitration, LSBUS_PARAM_INT32, "arbitration", arbitration),
    LSBUS_PARAM(vr_wakeup_at_step, LSBUS_PARAM_INT32, "wakeup_at_step", wakeup_at_step),
    LSBUS_PARAM(vr_crash_at_step, LSBUS_PARAM_INT32, "crash_at_step", crash_at_step),
};
const size_t lsbus_model_param_count = sizeof lsbus_model_params / sizeof lsbus_model_params[0];

void lsbus_model_defaults(ModelInstance *comp)
{
    M(report_id) = 0x1A0;
}

bool lsbus_model_start(ModelInstance *comp)
{
    if (M(baudrate) > 0) {
        lsbus_node_configure_baudrate(&M(node), (uint32_t)M(baudrate));
    }
    if (M(arbitration) > 0) {
        lsbus_node_configure_arbitration(&M(node), (uint8_t)M(arbitration));
    }
    return true;
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

void lsbus_model_on_frame(ModelInstance *comp, const hal_can_frame_t *f)
{
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

#ifdef PROBE_TIMED
void lsbus_model_on_tick(ModelInstance *comp)
{
    report(comp);
}
#endif
