/* agrihil-fertilizer-signal: the fertilizer firmware's control at signal level (FMI 2.0). */
#ifndef config_h
#define config_h

#include <stdbool.h>
#include <stdint.h>

#include "fertilizer_adapter.h"

#define MODEL_IDENTIFIER agrihil_fertilizer_signal
#define INSTANTIATION_TOKEN "{6f0c2f7e-agri-hil0-fert-signal000001}"

#define CO_SIMULATION

#define GET_FLOAT64
#define SET_FLOAT64
#define GET_INT32
#define SET_INT32
#define GET_BOOLEAN
#define SET_BOOLEAN
#define SET_STRING
#define EVENT_UPDATE

/* one fixed step per control period: the control step is a time event at each (0.1 s) */
#define FIXED_SOLVER_STEP 0.1
#define DEFAULT_STOP_TIME 1e9

typedef enum {
    vr_time = 0,
    vr_setpoint_targetrate = 1,
    vr_setpoint_workingwidth = 2,
    vr_setpoint_targetflow = 3,
    vr_setpoint_mode = 4,
    vr_setpoint_enable = 5,
    vr_setpoint_speedsource = 6,
    vr_setpoint_activerows = 7,
    vr_setpoint_counter = 8,
    vr_row1_flow = 10,
    vr_row1_baselineready = 20,
    vr_row1_adcoverrange = 30,
    vr_row1_counter = 40,
    vr_row2_flow = 11,
    vr_row2_baselineready = 21,
    vr_row2_adcoverrange = 31,
    vr_row2_counter = 41,
    vr_row3_flow = 12,
    vr_row3_baselineready = 22,
    vr_row3_adcoverrange = 32,
    vr_row3_counter = 42,
    vr_row4_flow = 13,
    vr_row4_baselineready = 23,
    vr_row4_adcoverrange = 33,
    vr_row4_counter = 43,
    vr_wheelspeed = 50,
    vr_wheelcounter = 51,
    vr_wheelbasedspeed = 52,
    vr_wheelbaseddistance = 53,
    vr_groundbasedspeed = 54,
    vr_groundbaseddistance = 55,
    vr_motorcommand = 100,
    vr_status_targetflow = 101,
    vr_status_measuredflow = 102,
    vr_status_commandvoltage = 103,
    vr_status_pidsegment = 104,
    vr_status_mode = 105,
    vr_status_enabled = 106,
    vr_status_sensorfault = 107,
    vr_status_counter = 108,
    vr_ff_coeff = 200,
    vr_mode = 201,
    vr_calibration_gramsperrev = 60,
    vr_calibration_shaftspeed = 61,
    vr_calibration_revolutions = 62
} ValueReference;

#define N_VR 256
#define MODE_TEXT 32

typedef struct {
    double real[N_VR];
    int32_t integer[N_VR];
    bool boolean[N_VR];
    fert_adapter_t adapter;
    bool started;
    uint32_t steps;
    int32_t last_row_counter[FERT_ROWS];
    int32_t last_wheel_counter;
    char mode[MODE_TEXT];
    bool failed;
} ModelData;

#endif
