/* What every agrihil LS-BUS CAN node FMU declares to the Reference-FMUs skeleton: included by
 * the model's config.h, which then names the model (MODEL_IDENTIFIER, INSTANTIATION_TOKEN),
 * adds the feature macros of its parameters' types (SET_FLOAT64, GET_INT32, SET_INT32,
 * SET_STRING), and declares
 *
 *     typedef enum { LSBUS_FMU_VALUE_REFERENCES, vr_kp0 = 10, ... } ValueReference;
 *     typedef struct { LSBUS_FMU_DATA  <the model's own fields> } ModelData;
 *
 * The common part (common/lsbus_fmu.c) runs the CAN terminal, the Rx/Tx clocks, the parameters
 * and the node's life cycle; the model supplies the hooks of common/lsbus_fmu.h. */
#ifndef AGRIHIL_LSBUS_FMU_CONFIG_H
#define AGRIHIL_LSBUS_FMU_CONFIG_H

#include <stdbool.h>
#include <stdint.h>

#include "lsbus_node.h"

#define CO_SIMULATION

#define GET_FLOAT64
#define SET_BOOLEAN
#define GET_BINARY
#define SET_BINARY
#define ACTIVATE_CLOCK
#define GET_CLOCK
#define EVENT_UPDATE

#define FIXED_SOLVER_STEP 0.001
#define DEFAULT_STOP_TIME 1e9

/* the CAN terminal (CanChannel.*), Can_BusNotifications and the time */
#define LSBUS_FMU_VALUE_REFERENCES                                                              \
    vr_rx_data = 0, vr_tx_data = 1, vr_rx_clock = 2, vr_tx_clock = 3,                           \
    vr_bus_notifications = 128, vr_time = 1024

/* the common part's state, first in ModelData */
#define LSBUS_FMU_DATA                                                                          \
    lsbus_node_t node;                                                                          \
    bool started;  /* the node has started (its parameters are fixed from then on) */         \
    bool failed;   /* it could not start (logged): every later event is an error */           \
    bool tx_tick;  /* the time-based Tx_Clock ticked (LSBUS_FMU_TIMED_TX_CLOCK) */             \
    uint32_t given; /* bit i: parameter i of the model's table was set by the importer */

#endif
