/* CAN adapter of the fertilizer flow controller built against another vendor's database: the
 * (fictional) Nordfeld RateMaster RC-400 of docs/examples/byo-fertilizer/ratemaster_rc400.dbc.
 *
 * The C twin of reference_controllers/fertilizer/dbc_adapter.py (DbcFlowController with
 * RC400_SIGNALS): the same control core (core/piecewise_pid.c), parameters, row validity and
 * step order as the reference adapter (apps/fertilizer_adapter.c), but every frame is packed and
 * unpacked by generated/ratemaster_rc400.[ch], which cantools generates from the RC-400's
 * database (generate.sh). It knows nothing of agrihil's DBC. Pure: no I/O, no allocation.
 *
 * Frames (the RC-400's layout: node 0x12, Motorola byte order for its own frames):
 *   in   RC_Command 0x312 (set-points; rates in kg/ha, width in mm, target in kg/h, Program
 *        and SpeedSrc enums, Sections), RH_RowFlow 0x1B0 (one multiplexed frame for all rows:
 *        RowNo 0-3 = rows 1-4, flow in kg/h, State_n / Diag_n enums), WS_GroundSpeed 0x1B5
 *        (km/h), WheelBasedSpeedDist PGN 65096 and GroundBasedSpeedDist PGN 65097 (matched by
 *        PGN, any source address)
 *   out  RC_Status 0x292 every 5th step (500 ms; the first step included), RC_Heartbeat 0x712
 *        (Operational) every step, DriveCommand 0x220 (mV) last in every step; at start the
 *        boot-up 0x712 [0x00] and an SDO write to the drive module (node 0x20): its consumer
 *        heartbeat 0x1016 sub 1 = this node, 300 ms.
 *
 * The rules of dbc_adapter.py, one by one:
 *   - units converted to the law's by the database's units: kg/h -> g/s and km/h -> m/s by
 *     x (1/3.6), mm -> m by x 0.001, kg/ha and m/s as they are;
 *   - Program SpeedRelated = field rate, FixedRate = bench flow, FixedSpeed = constant speed
 *     (open loop); Off, or no set-point yet, = bench; a change of program resets the core;
 *   - SpeedSrc WheelSensor = the ground wheel (0x1B5), TractorWheel = PGN 65096, Radar =
 *     PGN 65097, None = no speed; a speed outside 0 - 64.255 m/s counts as 0;
 *   - a row is valid when its State is Measuring, its Diag is not CapOverrange, its report is at
 *     most stale_after_s / period_s steps old and its flow is at most 3 Q + 5 g/s, and it
 *     agrees with the other valid rows (the cross-row check, core/cross_row.h);
 *   - field target 0.1 M D v / max(1, Sections); enabled when a set-point has Run = 1;
 *   - age is counted in control steps (the controller's tick counter), as the Python build's. */
#ifndef AGRIHIL_FERTILIZER_RC400_ADAPTER_H
#define AGRIHIL_FERTILIZER_RC400_ADAPTER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "cross_row.h"
#include "hal_can.h"
#include "piecewise_pid.h"
#include "ratemaster_rc400.h"

#define RC400_ROWS 4
#define RC400_MAX_OUT 3   /* frames a step produces at most */
#define RC400_BOOT_FRAMES 2
#define RC400_PARAM_COUNT (PPID_PARAM_COUNT + 3)

typedef struct {
    ppid_params_t core;   /* law and gains */
    double stale_after_s; /* a row report older than this is invalid (2.5 s) */
    double period_s;      /* control period (0.1 s): ages are counted in steps of it */
    double ground_speed_first_s; /* field: a Radar speed (PGN 65097) this fresh is used before
                                  * SpeedSrc's (0.3 s; 0: SpeedSrc alone; speeds.py) */
} rc400_config_t;

/* The law's modes, which the RC-400's programs select. */
typedef enum { RC400_MODE_FIELD = 0, RC400_MODE_BENCH = 1, RC400_MODE_CONSTANT = 2 } rc400_mode_t;

typedef struct {
    bool seen;
    double flow_gps;
    bool measuring;  /* State_n = Measuring */
    bool overrange;  /* Diag_n = CapOverrange */
    uint32_t at_step; /* the step count when it arrived */
    bool fresh;       /* not yet seen by a step */
} rc400_row_t;

/* What the last step computed (for the tests). */
typedef struct {
    double target_gps;
    double measured_gps;
    bool has_measurement;
    bool new_report;
    bool alarm;
    rc400_mode_t mode;
    ppid_law_t law;
    ppid_output_t out;
} rc400_step_info_t;

typedef struct {
    rc400_config_t cfg;
    ppid_state_t core;
    int active_mode; /* mode of the previous step (-1 before the first) */
    bool has_setpoint;
    struct ratemaster_rc400_rc_command_t setpoint; /* the last RC_Command, as on the bus */
    rc400_row_t rows[RC400_ROWS];
    xrow_state_t xrow; /* cross-row plausibility of the rows' reports */
    double speed_mps[3]; /* ground wheel, tractor wheel-based, radar */
    bool ground_heard;       /* the last radar speed was valid */
    uint32_t ground_at_step; /* the step count when it arrived */
    uint32_t steps;
    rc400_step_info_t last;
} rc400_adapter_t;

void rc400_config_defaults(rc400_config_t *cfg, ppid_law_t law);

/* Named parameters, the Python build's names: the core's (which depend on the law: set it
 * first) plus stale_after_s, period_s and ground_speed_first_s. */
size_t rc400_param_refs(rc400_config_t *cfg, param_ref_t refs[RC400_PARAM_COUNT]);

void rc400_init(rc400_adapter_t *a, const rc400_config_t *cfg);

/* The start-up frames, in order: boot-up heartbeat, then the SDO configuring the drive module's
 * consumer heartbeat. Returns RC400_BOOT_FRAMES. */
size_t rc400_boot_frames(hal_can_frame_t out[RC400_BOOT_FRAMES]);

/* Take one received frame (frames of other ids, and frames too short for their message, are
 * ignored, as on a bus). */
void rc400_on_frame(rc400_adapter_t *a, const hal_can_frame_t *frame);

/* The target flow per row (g/s) from the last set-point and speeds; 0 when not enabled. */
double rc400_target_gps(const rc400_adapter_t *a);

/* The mode the last set-point selects (bench before any). */
rc400_mode_t rc400_mode(const rc400_adapter_t *a);

/* One control step: fills out[] (capacity RC400_MAX_OUT), returns the frame count. */
size_t rc400_step(rc400_adapter_t *a, hal_can_frame_t out[RC400_MAX_OUT]);

#endif
