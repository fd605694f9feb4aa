/* The sowing-depth controller of [D] as an ISOBUS implement: the C twin of
 * reference_controllers/sowing_depth/isobus_mode.py (IsobusDepthController), frame for frame
 * (issue 42: variable-depth seeding under the Task Controller).
 *
 * The control law and the drive side are the firmware's depth adapter (apps/depth_adapter.c:
 * the fuzzy PID, the roller hold, the CiA 402 master of the servo cylinder, the inclinometer,
 * the GNSS speed); only where the target depth comes from changes. DepthSetpoint (0x18FF2026)
 * is not listened to:
 *   - NAME: industry group 2, device class 4 (planters/seeders), function 128,
 *     self-configurable, identity number `identity_number`; preferred address `address`;
 *   - DDOP: iso_depth_pool() (the seed line: DDI 56 settable, 57 actual, 58-60 default, minimum
 *     and maximum seeding depth);
 *   - DDI 56 (mm) from the TC is the target depth; outside [min, max]: refused (process data
 *     acknowledge 0x80, value out of operational range);
 *   - the TC lost (no status for 6 s, a restart, a refused pool) or a new connection: the target
 *     is the default depth the DDOP declares (DDI 58) until the TC sends one;
 *   - DDI 57 reports the sensed depth (eq. 13, filtered) in whole mm, 0 without a valid one;
 *   - DepthControllerStatus goes out from the claimed address (none before the claim).
 * Must-fail parameters (defects a real implement could have; the defaults are the reference):
 * fixed_depth_mm > 0 holds that depth whatever the TC sends; actual=setpoint reports the
 * set-point as the actual depth; fallback=hold keeps the last set-point when the TC is lost.
 *
 * Time, as the Python mode: the controller's time is its step count times the period; frames
 * between two steps carry the time of the next step (the adapter's clock). The network's
 * answers go out with the next step, first, then what is due, then the adapter's frames (the
 * command RPDO2 last). Pure: frames in, frames out; no allocation. */
#ifndef AGRIHIL_ISO_DEPTH_H
#define AGRIHIL_ISO_DEPTH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "depth_adapter.h"
#include "iso_ddop.h"
#include "iso_net.h"
#include "iso_tc.h"

#define ISO_DEPTH_MAX_OUT (ISO_NET_MAX_OUT + DEPTH_MAX_OUT)
#define ISO_DEPTH_PARAM_COUNT (DEPTH_PARAM_COUNT + 7)
/* The seed line: the depth rig's 12 rows of 200 mm, 1.9 m behind the GNSS antenna (the
 * Python takes both from the rig configuration: [machine] rows, row_spacing_mm,
 * tractor_rear_axle_ahead_of_seed_m) */
#define ISO_DEPTH_WIDTH_M 2.4
#define ISO_DEPTH_OFFSET_X_MM (-1900)

typedef struct {
    depth_config_t depth;    /* the adapter's and the fuzzy PID's parameters */
    double address;          /* preferred source address, 0 .. 253 (0x82) */
    double identity_number;  /* NAME identity number, < 2^21 (0x0D42) */
    double default_depth_mm; /* DDI 58 (30) */
    double min_depth_mm;     /* DDI 59 (10) */
    double max_depth_mm;     /* DDI 60 (60) */
    double latency_ms;       /* DDI 142 (1000) */
    double fixed_depth_mm;   /* > 0: hold this depth whatever the TC sends (must-fail) */
    bool actual_setpoint;    /* actual=setpoint: DDI 57 is the set-point (must-fail) */
    bool fallback_hold;      /* fallback=hold: keep the last set-point without the TC */
    bool step_on_sync;       /* one control step per SYNC 0x080 (lockstep) */
} iso_depth_config_t;

typedef struct {
    iso_depth_config_t cfg;
    depth_adapter_t adapter;
    iso_net_t net;
    tcc_t tc;
    iso_ddop_info_t pool;
    uint64_t name;
    bool has_tc_depth;  /* the TC sent a depth on this connection */
    double tc_depth_mm;
    double target_mm;   /* the depth held now (the last step's) */
    hal_can_frame_t out[ISO_DEPTH_MAX_OUT];
    size_t nout;
} iso_depth_t;

void iso_depth_config_defaults(iso_depth_config_t *cfg);

/* Named numeric parameters: the depth adapter's and address, identity_number,
 * default_depth_mm, min_depth_mm, max_depth_mm, latency_ms, fixed_depth_mm (actual= and
 * fallback= are words: iso_depth_word_param). */
size_t iso_depth_param_refs(iso_depth_config_t *cfg,
                            param_ref_t refs[ISO_DEPTH_PARAM_COUNT]);

/* actual=sensed|setpoint, fallback=default|hold: 1 taken, 0 not a word parameter, -1 a bad
 * value (*why says which). */
int iso_depth_word_param(iso_depth_config_t *cfg, const char *key, const char *value,
                         const char **why);

/* Check the parameters: 0, or -1 with a message naming the parameter in err. */
int iso_depth_check(const iso_depth_config_t *cfg, char *err, size_t errlen);

/* Set up (the configuration must pass iso_depth_check). Returns 0, -1 if the pool cannot be
 * written. */
int iso_depth_init(iso_depth_t *c, const iso_depth_config_t *cfg);

/* The boot-up frame (heartbeat 0x701 [0x00]). */
hal_can_frame_t iso_depth_bootup(void);

/* Take a frame; what is sent at once (NMT start, a step on SYNC) is in c->out, the count
 * returned. What the ISOBUS network answers goes out with the next step. */
size_t iso_depth_on_frame(iso_depth_t *c, const hal_can_frame_t *frame);

/* A GNSS speed report (valid fix, m/s) or a no-fix report, applied at the next step. */
void iso_depth_on_gnss(iso_depth_t *c, bool valid, double speed_mps);

/* One control step (free-running, or what a SYNC does in lockstep); frames in c->out. */
size_t iso_depth_step(iso_depth_t *c);

/* The depth the controller holds now: the fixed one, the TC's, or the default. */
double iso_depth_target_mm(const iso_depth_t *c);

/* Control steps done (the adapter's). */
uint32_t iso_depth_steps(const iso_depth_t *c);

#endif
