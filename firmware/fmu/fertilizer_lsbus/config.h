/* agrihil-fertilizer-lsbus: the fertilizer firmware as an FMI 3.0 LS-BUS CAN node. */
#ifndef config_h
#define config_h

#include <stdbool.h>
#include <stdint.h>

#include "fertilizer_adapter.h"
#include "lsbus_node.h"

#define MODEL_IDENTIFIER agrihil_fertilizer_lsbus
#define INSTANTIATION_TOKEN "{6f0c2f7e-agri-hil0-fert-lsbus0000001}"

#define CO_SIMULATION

#define GET_FLOAT64
#define SET_FLOAT64
#define SET_BOOLEAN
#define SET_STRING
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
    vr_ff_coeff = 10,
    vr_mode = 11,
    vr_bus_notifications = 128,
    vr_time = 1024
} ValueReference;

#define MODE_TEXT 32

typedef struct {
    lsbus_node_t node;
    fert_adapter_t adapter;
    bool started;
    uint64_t steps;
    char mode[MODE_TEXT];
    double ff_coeff;
    bool ff_coeff_given;
    bool failed;
} ModelData;

#endif
