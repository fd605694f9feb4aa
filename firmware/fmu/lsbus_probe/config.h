/* agrihil-lsbus-probe: an FMI-LS-BUS CAN node that reports what the bus told it (tests). */
#ifndef config_h
#define config_h

#include "lsbus_fmu_config.h"

#ifndef PROBE_TIMED
#define MODEL_IDENTIFIER agrihil_lsbus_probe
#define INSTANTIATION_TOKEN "{0b1f5c1a-agri-hil0-lsbus-probe000001}"
#else
#define LSBUS_FMU_TIMED_TX_CLOCK
#endif

#define GET_INT32
#define SET_INT32

typedef enum {
    LSBUS_FMU_VALUE_REFERENCES,
    vr_report_id = 10,
    vr_fd_at_step = 11,
    vr_baudrate = 12,
    vr_arbitration = 13,
    vr_wakeup_at_step = 14,
    vr_crash_at_step = 15
} ValueReference;

typedef struct {
    LSBUS_FMU_DATA
    int32_t syncs;
    int32_t report_id;
    int32_t fd_at_step;
    int32_t baudrate;
    int32_t arbitration;
    int32_t wakeup_at_step;
    int32_t crash_at_step;
} ModelData;

#endif
