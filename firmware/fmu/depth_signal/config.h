/* agrihil-depth-signal: the sowing-depth firmware's control at signal level (FMI 2.0). */
#ifndef config_h
#define config_h

#include <stdbool.h>
#include <stdint.h>

#include "depth_adapter.h"
#include "hal_serial.h"
#include "nmea.h"

#define MODEL_IDENTIFIER agrihil_depth_signal
#define INSTANTIATION_TOKEN "{6f0c2f7e-agri-hil0-dept-signal00001}"

#define CO_SIMULATION

#define GET_FLOAT64
#define SET_FLOAT64
#define GET_INT32
#define SET_INT32
#define GET_BOOLEAN
#define SET_STRING
#define EVENT_UPDATE

/* one fixed step per control period: the control step is a time event at each (0.01 s) */
#define FIXED_SOLVER_STEP 0.01
#define DEFAULT_STOP_TIME 1e9

typedef enum {
    vr_time = 0,
    /* the tractor (PGN 65097) */
    vr_groundspeed = 1,
    vr_grounddistance = 2,
    /* the inclinometer's module */
    vr_inclinometer_x = 3,
    vr_inclinometer_xstatus = 4,
    vr_inclinometer_counter = 5,
    /* the operator's terminal */
    vr_setpoint_targetdepth = 6,
    vr_setpoint_enable = 7,
    vr_setpoint_mode = 8,
    vr_setpoint_counter = 9,
    /* the servo drive (CiA 402): its heartbeat and TPDO1 */
    vr_drive_nmtstate = 10,
    vr_drive_statusword = 11,
    vr_drive_position = 12,
    /* to the servo drive: NMT, RPDO2, RPDO3 */
    vr_drive_nmtcommand = 100,
    vr_drive_controlword = 101,
    vr_drive_targetvelocity = 102,
    vr_drive_modeofoperation = 103,
    /* the controller's status frame */
    vr_status_measureddepth = 110,
    vr_status_rollerpositioncommand = 111,
    vr_status_state = 112,
    vr_status_sensorfault = 113,
    vr_status_drivefault = 114,
    vr_status_speedlost = 115,
    vr_status_counter = 116,
    /* parameters */
    vr_kp0 = 200,
    vr_ki0 = 201,
    vr_kd0 = 202,
    vr_gnss_port = 210
} ValueReference;

#define N_VR 256
#define PORT_TEXT 256

typedef struct {
    double real[N_VR];
    int32_t integer[N_VR];
    bool boolean[N_VR];
    bool given[N_VR]; /* a parameter set by the importer */
    depth_adapter_t adapter;
    bool started;
    bool failed;
    uint32_t steps;
    int32_t last_inclinometer_counter;
    int32_t last_nmt_state;
    char gnss_port[PORT_TEXT];
    hal_serial_t gnss;
    bool gnss_open;
    nmea_reader_t nmea;
} ModelData;

#endif
