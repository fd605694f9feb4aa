/* agrihil-crash-fmu: a proportional flow controller (FMI 3.0, signal level) that fails in its
 * C code at a chosen control period (the FMU host's tests). */
#ifndef config_h
#define config_h

#include <stdint.h>

#define MODEL_IDENTIFIER agrihil_crash_fmu
#define INSTANTIATION_TOKEN "{5d0c9e2a-agri-hil0-crash-fmu00000001}"
#define CO_SIMULATION
#define GET_FLOAT64
#define SET_FLOAT64
#define GET_INT32
#define SET_INT32
#define FIXED_SOLVER_STEP 0.1
#define DEFAULT_STOP_TIME 1e9

typedef enum {
    vr_time, vr_target, vr_flow, vr_command, vr_kp, vr_fail_at_step, vr_fail_how
} ValueReference;

typedef struct {
    double target, flow, command, kp;
    int32_t fail_at_step, fail_how, steps;
} ModelData;

#endif
