/* agrihil-depth-lsbus: the sowing-depth firmware as an FMI 3.0 LS-BUS CAN node. */
#ifndef config_h
#define config_h

#include <stdbool.h>
#include <stdint.h>

#include "depth_adapter.h"
#include "hal_serial.h"
#include "lsbus_node.h"
#include "nmea.h"

#define MODEL_IDENTIFIER agrihil_depth_lsbus
#define INSTANTIATION_TOKEN "{6f0c2f7e-agri-hil0-dept-lsbus0000001}"

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
    vr_kp0 = 10,
    vr_ki0 = 11,
    vr_kd0 = 12,
    vr_gnss_port = 20,
    vr_bus_notifications = 128,
    vr_time = 1024
} ValueReference;

#define N_PARAMS 3
#define PORT_TEXT 256

typedef struct {
    lsbus_node_t node;
    depth_adapter_t adapter;
    bool started;
    bool failed;
    uint64_t steps;
    double param[N_PARAMS];
    bool param_given[N_PARAMS];
    char gnss_port[PORT_TEXT];
    hal_serial_t gnss;
    bool gnss_open;
    nmea_reader_t nmea;
} ModelData;

#endif
