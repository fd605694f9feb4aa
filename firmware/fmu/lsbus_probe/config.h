/* agrihil-lsbus-probe: an FMI-LS-BUS CAN node that reports what the bus told it (tests). */
#ifndef config_h
#define config_h

#include <stdbool.h>
#include <stdint.h>

#include "lsbus_node.h"

#ifndef PROBE_TIMED
#define MODEL_IDENTIFIER agrihil_lsbus_probe
#define INSTANTIATION_TOKEN "{0b1f5c1a-agri-hil0-lsbus-probe000001}"
#endif

#define CO_SIMULATION

#define GET_FLOAT64
#define GET_INT32
#define SET_INT32
#define SET_BOOLEAN
#define GET_BINARY
#define SET_BINARY
#define ACTIVATE_CLOCK
#define GET_CLOCK
#define EVENT_UPDATE

#define FIXED_SOLVER_STEP 0.001
#define DEFAULT_STOP_TIME 1e9

typedef enum {
    vr_rx_data = 0,
    vr_tx_data = 1,
    vr_rx_clock = 2,
    vr_tx_clock = 3,
    vr_report_id = 10,
    vr_fd_at_step = 11,
    vr_baudrate = 12,
    vr_arbitration = 13,
    vr_wakeup_at_step = 14,
    vr_crash_at_step = 15,
    vr_bus_notifications = 128,
    vr_time = 1024
} ValueReference;

typedef struct {
    lsbus_node_t node;
    bool started;
    bool tick;          /* time-based Tx_Clock activated */
    int32_t syncs;
    int32_t report_id;
    int32_t fd_at_step;
    int32_t baudrate;
    int32_t arbitration;
    int32_t wakeup_at_step;
    int32_t crash_at_step;
} ModelData;

#endif
