/* CAN adapter of the sowing-depth controller (docs/reference-controllers.md section 2, "CAN
 * adapter"): the CANopen master of the servo cylinder drive (CiA 402, node 2) and a J1939 node
 * on the implement bus. Pure (no I/O, no allocation): the app feeds it frames, GNSS speeds and
 * its clock, and sends what it returns.
 *
 * Frames (plant_emulators/sowing_depth/db/sowing_depth.dbc and the drive's EDS, generated code in
 * generated/sowing_depth.[ch] and generated/servo_cylinder_pdo.[ch]):
 *   in   drive heartbeat 0x702, TPDO1 0x182 (statusword, Position actual value) / TPDO2
 *        0x282 (statusword), Inclinometer
 *        0x0CFF11A1, DepthSetpoint 0x18FF2026, GBSD 0x0CFE49F0
 *   out  NMT start [0x01, 2] on 0x000 when the drive's heartbeat is not Operational (at once),
 *        RPDO3 0x402 (Modes of operation = 3) once the drive is Operational, RPDO2 0x302
 *        (Controlword, Target velocity) every step, DepthControllerStatus 0x18FF3080 and the
 *        heartbeat 0x701 every 10th step (the first step included), boot-up 0x701 [0x00].
 * Depth: eq. 13 on the X voltage of frames with status ok, filtered d += 0.2 (depth - d) per
 * frame (the first frame sets d). The depth is invalid (the core resets and the roller is
 * held, see below; the status frame says SensorFault) while the latest frame's X status is
 * not ok, and while the X voltage has not changed for more than frozen_after_s (0.2 s; 0 or
 * less turns this check off): a live inclinometer never repeats one ADC count for 20 reports
 * (0.2 s), so a frozen output, or one that stopped sending, is a dead sensor,
 * not a steady depth. Where the roller is held (roller_hold.h): while the depth is valid and
 * control enabled, the adapter tracks the mean rod position (TPDO1's Position actual value,
 * tau = 2 s), and takes it as the hold target at each new X voltage (the sensor's last sign of
 * life); when the depth turns invalid while control stays enabled (and the drive is in
 * Operation enabled) it drives the rod back to that target, speed = clamp(5/s (h - p),
 * +-10 mm/s), and holds it there, the status frame carrying the target as
 * DC_RollerPositionCommand (0 otherwise); control disabled forgets both and commands 0.
 * Parameters hold_time_constant_s, hold_gain_per_s, hold_speed_mm_s. As in the Python
 * build. */
#ifndef AGRIHIL_DEPTH_ADAPTER_H
#define AGRIHIL_DEPTH_ADAPTER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "fuzzy_pid.h"
#include "hal_can.h"
#include "roller_hold.h"

#define DEPTH_MAX_OUT 4
#define DEPTH_PARAM_COUNT (FPID_PARAM_COUNT + 6)
#define DEPTH_DRIVE_NODE 2 /* CANopen node id of the servo cylinder drive */

/* CiA 402 controlwords */
#define CW_DISABLE_VOLTAGE 0x00u
#define CW_SHUTDOWN 0x06u
#define CW_SWITCH_ON 0x07u
#define CW_ENABLE_OPERATION 0x0Fu
#define CW_FAULT_RESET 0x80u

typedef struct {
    fpid_params_t core;
    double min_speed_mps;   /* control only at or above this ground speed (0.1 m/s) */
    double speed_timeout_s; /* no valid ground speed for longer than this: unknown (1 s) */
    double frozen_after_s;  /* X voltage unchanged for longer than this: sensor dead (0.2 s;
                               0 or less: no check) */
    rhold_params_t hold;    /* where the roller is held while the depth is invalid */
} depth_config_t;

typedef struct {
    double target_mm;
    double depth_mm;
    bool valid;
    bool frozen; /* the X voltage has not changed for more than frozen_after_s */
    bool enabled;
    bool speed_known;
    bool holding;          /* enabled, depth invalid: the rod is driven to the hold target */
    double hold_target_mm; /* the hold target (valid if a.hold.has_target) */
    uint16_t controlword;
    int32_t target_velocity; /* 0.01 mm/s */
    fpid_output_t out;
} depth_step_info_t;

typedef struct {
    depth_config_t cfg;
    uint8_t node;
    fpid_state_t core;
    int drive_nmt;          /* last heartbeat state, -1 before any */
    bool have_statusword;
    uint16_t statusword;
    bool have_position;
    double position_mm;     /* Position actual value 0x6064 (TPDO1), 0.01 mm increments / 100 */
    rhold_state_t hold;
    bool mode_sent;
    uint16_t last_controlword;
    /* setpoint */
    bool have_setpoint;
    double target_mm;
    uint8_t ds_enable;
    uint8_t ds_mode;
    /* depth: filtered; depth_ok is the status of the latest inclinometer frame */
    bool have_depth;
    double depth_mm;
    bool depth_ok;
    /* the last X voltage with status ok and when it last changed (frozen-sensor check) */
    bool have_x;
    double last_x_mv;
    double x_changed_at_s;
    /* ground speed by source: [0] GBSD (PGN 65097), [1] GNSS; the fresher valid one counts,
     * and of two as fresh the one that reported first (speed_order: the sources in the order
     * of their first report, valid or not, as the Python reference's dict keeps them) */
    bool have_speed[2];
    double speed_mps[2];
    double speed_at_s[2];
    uint8_t speed_order[2];
    uint8_t speed_sources;
    /* the GNSS reports since the last step, applied at the start of the next (the Python
     * reference polls its receiver there): the latest one, valid or not */
    bool gnss_pending;
    bool gnss_pending_valid;
    double gnss_pending_mps;
    uint32_t steps;
    uint8_t status_counter;
    depth_step_info_t last;
} depth_adapter_t;

void depth_config_defaults(depth_config_t *cfg);

/* Named parameters, the Python build's names: the core's (see fpid_param_refs) plus
 * min_speed_mps, speed_timeout_s, frozen_after_s, hold_time_constant_s, hold_gain_per_s and
 * hold_speed_mm_s. */
size_t depth_param_refs(depth_config_t *cfg, param_ref_t refs[DEPTH_PARAM_COUNT]);

/* 0, or -1 if a parameter is out of its range (message in err). */
int depth_config_check(const depth_config_t *cfg, char *err, size_t errlen);

void depth_init(depth_adapter_t *a, const depth_config_t *cfg);

hal_can_frame_t depth_bootup(void);

/* CiA 402: the controlword that moves the drive one step towards Operation enabled. */
uint16_t depth_next_controlword(uint16_t statusword);

/* Take one received frame at now_s; frames to send at once (NMT start) go to out[], the count
 * is returned. */
size_t depth_on_frame(depth_adapter_t *a, const hal_can_frame_t *frame, double now_s,
                      hal_can_frame_t out[DEPTH_MAX_OUT]);

/* A ground speed from the GNSS receiver (valid fix), or a no-fix report (valid = false). It
 * takes effect at the next depth_step, stamped with that step's time, as the Python reference
 * reads its receiver at the start of a step (now_s is not used). */
void depth_on_gnss(depth_adapter_t *a, bool valid, double speed_mps, double now_s);

size_t depth_step(depth_adapter_t *a, double now_s, hal_can_frame_t out[DEPTH_MAX_OUT]);

#endif
