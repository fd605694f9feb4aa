/* CAN adapter of the sowing-depth controller built against another vendor's database: the
 * (fictional) Feldtakt DepthPro DP-200 of docs/examples/byo-depth/depthpro_dp200.dbc.
 *
 * The C twin of reference_controllers/sowing_depth/dbc_adapter.py (DbcDepthController with
 * DP200_SIGNALS) and of the law it drives (depth_law.py): the reference depth control core
 * (core/fuzzy_pid.c, core/roller_hold.c), parameters and step order, but every frame is packed
 * and unpacked by generated/depthpro_dp200.[ch], which cantools generates from the DP-200's
 * database (generate.sh). It knows nothing of agrihil's DBC or of the drive's EDS defaults.
 * Pure: no I/O, no allocation.
 *
 * Frames (the DP-200's layout: node 0x0A, big-endian own frames, cm / V / um):
 *   in   DP_Setpoint 0x20A (target depth in cm, Enable and Mode enums), DP_SensorHub 0x1A5
 *        (multiplexed: Channel ArmInclinometer carries ArmTiltX in V and TiltXState; the
 *        draw-wire channel is not read), GBSD 0x0CFE49F0 (m/s), the drive's DP_DriveFeedback
 *        0x1A2 (position 0.01 mm, statusword), DP_DriveDiagnosis 0x2A2 (error code),
 *        DP_DriveHeartbeat 0x702, DP_DriveSdoResponse 0x582
 *   out  boot-up 0x70A [0x00]; in answer to the drive's boot-up (or any state but
 *        Operational while no configuration is under way) the 30 SDO writes of the drive's
 *        configuration to 0x602, back to back; in a step: the NMT start [0x01, 0x02] on 0x000
 *        once every write is confirmed, the mode write (0x6060 = 3, profile velocity) on the
 *        first step with the drive Operational, DP_Status 0x18A every 20th step (200 ms),
 *        DP_Heartbeat 0x70A every 50th (500 ms), both from the first step, and
 *        DP_DriveCommand 0x302 (target velocity 0.01 mm/s, controlword) last in every step.
 *
 * The drive's configuration (drive_config.py configuration_writes with DP200_DRIVE_PDOS,
 * CiA 301's re-mapping order): RPDO1-3 and TPDO1-3 invalidated (bit 31 of the default COB-ID),
 * then RPDO1 at 0x302 (0x60FF Target velocity, 0x6040 Controlword; synchronous), TPDO1 at 0x1A2
 * (0x6064 Position actual value, 0x6041 Statusword, 0x6061 Modes of operation display; every
 * SYNC), TPDO3 at 0x2A2 (0x603F Error code, 0x6078 Current actual value; event-driven, event
 * timer 100 ms, inhibit 10 ms), each as mapping count 0, entries, count, transmission type,
 * [inhibit time, event timer,] COB-ID made valid; then the heartbeat producer time 0x1017 =
 * 100 ms. Expedited downloads (CiA 301): each answer must be the confirmation (0x60) of the
 * same index and sub-index, in order; an abort (0x80), an answer for another object or any
 * other answer is an error naming the object (and the abort code), after which the drive is
 * left stopped and the status says Fault until the drive boots again.
 *
 * One rule the Python build does not have (dbc_adapter.py waits for ever): a write not
 * confirmed within sdo_timeout_s (0.5 s; counted in control steps) is an error too (a timeout,
 * naming the first unconfirmed object). agrihil-depth-dp200-fw stops on either error.
 *
 * The law's rules, from depth_law.py in its order: depth = 270.35 - 0.065 mm/mV x ArmTiltX by
 * eq. 13, filtered d += 0.2 (depth - d) per valid report; invalid while TiltXState is not Valid
 * or the voltage has not changed for more than frozen_after_s; enabled when Enable = On,
 * Mode = AutoDepth and a ground speed >= min_speed_mps is known (GBSD or GNSS, the most recent
 * within speed_timeout_s); the fuzzy PID, the roller hold, the CiA 402 controlword. Values are
 * converted from the database's units to the law's and rounded to the signal's resolution as
 * the Python build rounds them (Python's round(), half to even on the exact double), so the law
 * sees the same doubles; times are counted in control steps, as there. */
#ifndef AGRIHIL_DEPTH_DP200_ADAPTER_H
#define AGRIHIL_DEPTH_DP200_ADAPTER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "depthpro_dp200.h"
#include "fuzzy_pid.h"
#include "hal_can.h"
#include "roller_hold.h"

#define DP200_CONFIG_WRITES 30 /* 6 invalidations, 3 PDOs mapped, the heartbeat time */
#define DP200_MAX_OUT DP200_CONFIG_WRITES /* frames one event produces at most */
#define DP200_PARAM_COUNT (FPID_PARAM_COUNT + 7)
#define DP200_ERRLEN 160

typedef struct {
    fpid_params_t core;
    double min_speed_mps;   /* control only at or above this ground speed (0.1 m/s) */
    double speed_timeout_s; /* no valid ground speed for longer than this: unknown (1 s) */
    double frozen_after_s;  /* ArmTiltX unchanged for longer than this: sensor dead (0.2 s) */
    rhold_params_t hold;    /* where the roller is held while the depth is invalid */
    double sdo_timeout_s;   /* an SDO write unconfirmed for longer than this: error (0.5 s) */
} dp200_config_t;

/* One expedited SDO download: object, value, size in bytes (1, 2 or 4). */
typedef struct {
    uint16_t index;
    uint8_t subindex;
    uint32_t value;
    uint8_t size;
} dp200_write_t;

/* Writes sent back to back, their confirmations counted (drive_config.py SdoBatch). */
typedef struct {
    bool active;                 /* a batch exists (Python: not None) */
    const dp200_write_t *writes;
    size_t count;
    size_t confirmed;
    bool failed;                 /* the drive refused, or answered out of turn */
    uint32_t sent_step;          /* the step count when it was sent (for the timeout) */
} dp200_sdo_batch_t;

/* The law's state (depth_law.py DepthLaw). */
typedef struct {
    fpid_state_t core;
    rhold_state_t hold;
    uint16_t statusword;
    bool have_position;
    double position_mm;
    bool holding;
    uint16_t last_controlword;
    double target_mm;
    bool terminal_on, automatic, manual;
    bool have_depth;
    double depth_mm;
    bool depth_ok;
    bool have_x;
    double last_x_mv;
    double x_changed_at_s;
    /* ground speed sources in the order they first reported (SpeedSources.latest) */
    int source_order[2];
    int sources;
    bool speed_valid[2];
    double speed_mps[2];
    double speed_at_s[2];
    uint32_t steps;
} dp200_law_t;

/* What the last step computed (for the tests). */
typedef struct {
    uint16_t controlword;
    double speed_mm_s;
    bool valid, enabled, frozen;
    int32_t target_velocity; /* raw, 0.01 mm/s */
} dp200_step_info_t;

typedef struct {
    dp200_config_t cfg;
    dp200_law_t law;
    uint8_t drive_node; /* from the database: DP_DriveHeartbeat's id - 0x700 */
    dp200_write_t configuration[DP200_CONFIG_WRITES];
    dp200_sdo_batch_t sdo;      /* the configuration */
    dp200_sdo_batch_t mode_sdo; /* the mode write, once per start of the drive */
    bool configured;
    int drive_nmt; /* the drive's last heartbeat state, -1 before any */
    uint16_t drive_error; /* 0x603F from DP_DriveDiagnosis */
    bool has_error;
    char error[DP200_ERRLEN]; /* why the configuration failed (has_error) */
    dp200_step_info_t last;
} dp200_adapter_t;

void dp200_config_defaults(dp200_config_t *cfg);

/* Named parameters, the Python build's names (the core's, min_speed_mps, speed_timeout_s,
 * frozen_after_s, hold_time_constant_s, hold_gain_per_s, hold_speed_mm_s) plus this build's
 * sdo_timeout_s. */
size_t dp200_param_refs(dp200_config_t *cfg, param_ref_t refs[DP200_PARAM_COUNT]);

/* 0, or -1 if a parameter is out of its range (message in err). */
int dp200_config_check(const dp200_config_t *cfg, char *err, size_t errlen);

void dp200_init(dp200_adapter_t *a, const dp200_config_t *cfg);

/* The boot-up heartbeat 0x70A [0x00]. */
hal_can_frame_t dp200_bootup(void);

/* Take one received frame (other ids, and frames too short for their message, are ignored);
 * the frames to send at once (the configuration) go to out[], the count is returned. */
size_t dp200_on_frame(dp200_adapter_t *a, const hal_can_frame_t *frame,
                      hal_can_frame_t out[DP200_MAX_OUT]);

/* A ground speed from the GNSS receiver (valid fix) or a no-fix report, at the time of the
 * next step (call before dp200_step, as the Python build polls its port). */
void dp200_on_gnss(dp200_adapter_t *a, bool valid, double speed_mps);

/* One control step: fills out[] (at most 4 frames), returns the count. */
size_t dp200_step(dp200_adapter_t *a, hal_can_frame_t out[DP200_MAX_OUT]);

/* Why the drive's configuration failed (an SDO abort with its code and meaning, an answer out
 * of turn, a timeout), or NULL while it has not. */
const char *dp200_error(const dp200_adapter_t *a);

/* CiA 301's meaning of an SDO abort code ("unknown abort code" for others). */
const char *dp200_abort_text(uint32_t code);

/* Python's round(x, places) for places 0-9: the double nearest the decimal that the exact
 * value of x rounds to, half to even. */
double dp200_py_round(double x, int places);

#endif
