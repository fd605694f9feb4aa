/* CAN adapter of the fertilizer flow controller (docs/reference-controllers.md section 1, "CAN
 * adapter"): frames in, per-row target and sensor validity worked out, the piecewise PID core
 * stepped, frames out. Pure (no I/O, no allocation): the app feeds it frames and its clock, and
 * sends what it returns, so it runs unchanged on an MCU and in the unit tests.
 *
 * Frames (plant_emulators/fertilizer/db/fertilizer.dbc, generated/fertilizer.[ch]):
 *   in   FertSetpoint 0x210, FlowModule1-4 0x181-0x184, GroundWheelSpeed 0x185,
 *        WheelBasedSpeedDist 0x0CFE48F0 (PGN 65096), GroundBasedSpeedDist 0x0CFE49F0 (65097)
 *   out  AnalogOutputCommand 0x220 every step, ControllerStatus 0x190 every 10th step (the
 *        first step included), ControllerHeartbeat 0x710 (Operational) every step, boot-up 0x710
 *        [0x00] at start.
 * A valid row that disagrees with the other valid rows is left out of the mean (the cross-row
 * check, core/cross_row.h). Terminal mode 2 (constant speed) runs the open-loop law whatever
 * the law; a change of terminal mode resets the closed-loop core (as the Python build does).
 * Ground speeds are held until the next frame (no time-out); a J1939 "not available" speed counts as 0.
 * In field mode a valid ground-based speed (PGN 65097) heard within ground_speed_first_s is used
 * whatever SpeedSource names: the wheels read through slip and skid, a radar does not
 * (reference_controllers/fertilizer/speeds.py; 0 obeys SpeedSource alone).
 * MeterCalibration 0x310 (optional): the operator's calibration test of the lot replaces the
 * feedforward map's ff_coeff, g_rev / 60 * max(n, ff_linear_below_rpm)^(1 - ff_exponent), as
 * reference_controllers/fertilizer/calibration.py computes it (use_calibration = 0 ignores it). */
#ifndef AGRIHIL_FERTILIZER_ADAPTER_H
#define AGRIHIL_FERTILIZER_ADAPTER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "cross_row.h"
#include "hal_can.h"
#include "piecewise_pid.h"

#define FERT_ROWS 4
#define FERT_MAX_OUT 4 /* frames a step can produce */
#define FERT_COMMON_PARAM_COUNT (PPID_PARAM_COUNT + 2)
#define FERT_PARAM_COUNT (FERT_COMMON_PARAM_COUNT + 2)

typedef struct {
    ppid_params_t core;   /* law and gains */
    double stale_after_s; /* a flow report older than this is invalid (2.5 s) */
    double period_s;      /* control period (0.1 s): the adapter clock advances by it per
                           * step in lockstep */
    double ground_speed_first_s; /* field mode: a PGN 65097 speed this fresh is used before
                                  * SpeedSource's (0.3 s; 0: SpeedSource alone) */
    double use_calibration;      /* 1: MeterCalibration replaces core.ff_coeff; 0: ignored */
} fert_config_t;

typedef struct {
    bool seen;
    double flow_gps;
    bool baseline_ready;
    bool overrange;
    double at_s;    /* arrival time */
    bool reported;  /* a report arrived since the previous step */
} fert_row_t;

typedef struct {
    bool seen;  /* a valid speed was received (a J1939 "not available" clears it) */
    double mps;
} fert_speed_t;

typedef struct {
    bool seen;
    uint8_t mode;          /* 0 field, 1 bench, 2 constant speed, 3 reserved */
    bool enable;
    double target_rate;    /* kg/hm2 */
    double working_width;  /* m */
    double target_flow;    /* g/s per row */
    uint8_t speed_source;  /* 0 Hall 0x185, 1 PGN 65096, 2 PGN 65097 */
    uint8_t active_rows;
} fert_setpoint_t;

/* What the last step computed (for the status frame and the tests). */
typedef struct {
    double target_gps;
    double measured_gps;
    bool has_measurement;
    bool new_report;
    bool sensor_fault;
    ppid_law_t law;
    ppid_output_t out;
} fert_step_info_t;

typedef struct {
    fert_config_t cfg;
    ppid_state_t core;
    int active_mode; /* terminal mode of the previous step (-1 before the first) */
    fert_setpoint_t setpoint;
    fert_row_t rows[FERT_ROWS];
    xrow_state_t xrow; /* cross-row plausibility of the rows' reports */
    fert_speed_t speed[3]; /* by SpeedSource */
    double ground_at_s;    /* when the last valid ground-based speed arrived */
    uint32_t steps;
    fert_step_info_t last;
    /* FertSetpoint.ActiveRows = N: only rows 1..N's modules count (the others' clutches are
     * out). An ISOBUS implement clears it: its sections say which rows count. */
    bool rows_follow_setpoint;
} fert_adapter_t;

void fert_config_defaults(fert_config_t *cfg, ppid_law_t law);

/* Named parameters, the Python build's names: the core's (see ppid_param_refs, which depend on
 * the law) plus stale_after_s and period_s (what the ISOBUS implement shares), and
 * ground_speed_first_s and use_calibration (the terminal mode's alone). Set the law before
 * calling. */
size_t fert_common_param_refs(fert_config_t *cfg, param_ref_t refs[FERT_COMMON_PARAM_COUNT]);
size_t fert_param_refs(fert_config_t *cfg, param_ref_t refs[FERT_PARAM_COUNT]);

void fert_init(fert_adapter_t *a, const fert_config_t *cfg);

/* The feedforward map's coefficient from a calibration test (grams per revolution and row at
 * shaft_rpm), or 0 when it holds no usable test (calibration.py ff_coeff_from_test). */
double fert_ff_coeff_from_test(double grams_per_rev, double shaft_rpm, double ff_exponent,
                               double ff_linear_below_rpm);

/* The boot-up frame (heartbeat with state 0x00), sent once at start. */
hal_can_frame_t fert_bootup(void);

/* Take one received frame, stamped with the adapter clock now_s (seconds). */
void fert_on_frame(fert_adapter_t *a, const hal_can_frame_t *frame, double now_s);

/* One control step at now_s: fills out[] (capacity FERT_MAX_OUT), returns the frame count. */
size_t fert_step(fert_adapter_t *a, double now_s, hal_can_frame_t out[FERT_MAX_OUT]);

#endif
