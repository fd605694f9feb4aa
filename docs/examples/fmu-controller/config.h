/* A minimal controller FMU (FMI 3.0, signal level): what the Reference-FMUs skeleton needs. */
#ifndef config_h
#define config_h

#define MODEL_IDENTIFIER minimal_flow_controller
#define INSTANTIATION_TOKEN "{8c4e1d5e-0f1a-4b6e-9c1d-minimal00001}"
#define CO_SIMULATION
#define GET_FLOAT64
#define SET_FLOAT64
#define FIXED_SOLVER_STEP 0.1
#define DEFAULT_STOP_TIME 1e9

typedef enum { vr_time, vr_target, vr_flow, vr_command, vr_kp } ValueReference;

typedef struct {
    double target, flow, command, kp;
} ModelData;

#endif
