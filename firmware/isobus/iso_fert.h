/* The fertilizer flow controller of [F] as an ISOBUS implement: the C twin of
 * reference_controllers/fertilizer/isobus_mode.py (IsobusFlowController), frame for frame.
 *
 * The control law and the rig's frames are the firmware's fertilizer adapter
 * (apps/fertilizer_adapter.c: FlowModule1-4 in, AnalogOutputCommand 0x220, ControllerStatus
 * 0x190, heartbeat 0x710 out); the set-point comes from the Task Controller instead of
 * FertSetpoint (0x210, ignored here):
 *   - NAME: industry group 2, device class 5 (fertilizers), function 128 (rate control),
 *     self-configurable, identity number `identity_number`; preferred address `address`;
 *   - DDOP: iso_meter_pool() (one boom, one section per row);
 *   - DDI 6 (mg/m2) is the target rate M (1 kg/ha = 100 mg/m2), DDI 290 switches rows (a
 *     section per row), DDI 289 = 0 stops the boom; DDI 7 reports the measured flow of the
 *     active rows as kg/ha through eq. 1, DDI 141 / 161 the actual work states;
 *   - ground speed from PGN 65097, PGN 65096 only while no fresh 65097 is heard (speed=wheel:
 *     PGN 65096 only); a speed older than 0.3 s is lost;
 *   - metering (volts > 0) only while the pool is active, a rate is set, the boom is not
 *     stopped, a row is on and a speed is known; each active row's target is
 *     0.1 M (D / rows) v.
 * Time is the step count times the period (frames between two steps carry the time of the
 * last step), as the Python's: no clock is read. The controller sends only in its step: what
 * the network answered since the last one (a TP CTS's packets, a reply to a request) goes out
 * first, then what is due, then the adapter's frames (the command 0x220 last).
 *
 * Pure: frames in, frames out (iso_fert_on_frame, iso_fert_step); no allocation. */
#ifndef AGRIHIL_ISO_FERT_H
#define AGRIHIL_ISO_FERT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "fertilizer_adapter.h"
#include "iso_ddop.h"
#include "iso_net.h"
#include "iso_tc.h"
#include "iso_vt.h"

#define ISO_FERT_MAX_OUT (ISO_NET_MAX_OUT + FERT_MAX_OUT)
#define ISO_FERT_PARAM_COUNT (FERT_COMMON_PARAM_COUNT + 3)
#define ISO_FERT_LATENCY_MS 430 /* the rig's meter-to-furrow delay, 0.08 s + 0.35 s (the
                                 * Python takes it from the rig configuration) */
#define ISO_FERT_SPEED_TIMEOUT_S 0.3

/* vt_defect (reference_controllers/fertilizer/isobus_vt.py DEFECTS): the must-fail implements
 * made of the reference */
typedef enum {
    ISO_VT_DEFECT_NONE,
    ISO_VT_DEFECT_IGNORES_MASTER,    /* Master off does not stop it */
    ISO_VT_DEFECT_NO_ALARM,          /* never raises the lost row's alarm */
    ISO_VT_DEFECT_BAD_POOL,          /* a pool the VT refuses (a font that is not there) */
    ISO_VT_DEFECT_NO_RECONNECT,      /* never notices the VT went away */
    ISO_VT_DEFECT_METERS_WITHOUT_VT, /* meters without its pool active and Master on */
    ISO_VT_DEFECT_NO_STORE,          /* never stores its pool (uploads it after a VT restart) */
    ISO_VT_DEFECT_SLOW_MAINTENANCE,  /* working set maintenance every 2 s, not every second */
    ISO_VT_DEFECT_IGNORES_CALIBRATION /* shows the calibration, meters on its own map */
} iso_vt_defect_t;

#define ISO_FERT_ALARM_AFTER_S 1.0   /* a row's flow lost this long while metering: alarm */
#define ISO_FERT_DISPLAY_PERIOD_S 1.0 /* the Run mask's values refreshed (changed ones only) */

typedef struct {
    fert_config_t fert;     /* law, gains, stale_after_s, period_s */
    double address;         /* preferred source address, 0 .. 253 (0x81) */
    double identity_number; /* NAME identity number, < 2^21 (0x0F27) */
    double width_m;         /* boom working width, (0, 30] m (3.0) */
    bool speed_wheel;       /* speed=wheel: PGN 65096 only (the must-fail variant) */
    bool ddop_broken;       /* ddop=broken: a DDOP a strict TC refuses (the must-fail variant) */
    bool step_on_sync;      /* one control step per SYNC 0x080 (lockstep) */
    bool vt;                /* vt=yes: the operator interface on a VT (isobus_vt.py) */
    iso_vt_defect_t vt_defect; /* vt_defect=...: a must-fail implement (none: the reference) */
} iso_fert_config_t;

typedef struct {
    iso_fert_config_t cfg;
    fert_adapter_t adapter;
    iso_net_t net;
    tcc_t tc;
    iso_ddop_info_t pool;
    uint64_t name;
    double row_width_m;
    uint32_t steps;
    double clock_s;      /* the time of the last step */
    double rate_kg_ha;   /* target rate M from the TC */
    bool sections[FERT_ROWS];
    int work_state;      /* DDI 289 from the TC, -1 until it sends one */
    bool heard[2];       /* 0 ground-based, 1 wheel-based */
    double heard_s[2];
    double heard_mps[2];
    hal_can_frame_t out[ISO_FERT_MAX_OUT];
    size_t nout;
    /* the operator interface (cfg.vt) */
    vtc_t vt;
    bool master_on;             /* the operator's Master (off at power-up) */
    double cal_grams, cal_rpm;  /* the calibration test entered on the VT */
    int alarm_row;              /* the row whose alarm is shown, 0: none */
    bool shown_set[1 + FERT_ROWS];
    int64_t shown[1 + FERT_ROWS]; /* what the Run mask shows: rate, then each row (x 10) */
    double next_display_s;
    bool lost[FERT_ROWS];
    double lost_since[FERT_ROWS];
    bool alarmed[FERT_ROWS];
    double maintenance_due; /* slow-maintenance: the maintenance time it last put off */
} iso_fert_t;

void iso_fert_config_defaults(iso_fert_config_t *cfg, ppid_law_t law);

/* Named numeric parameters: the fertilizer adapter's and address, identity_number, width_m
 * (speed= and ddop= are words: the program reads them). */
size_t iso_fert_param_refs(iso_fert_config_t *cfg, param_ref_t refs[ISO_FERT_PARAM_COUNT]);

/* The operator interface's word parameters: vt=yes|no, vt_defect=NAME (isobus_vt.py's names;
 * empty: the reference). Returns 1 when taken, 0 for another key, -1 for a bad value (with
 * *why naming it). */
int iso_fert_vt_param(iso_fert_config_t *cfg, const char *key, const char *value,
                      const char **why);

/* Check the ISOBUS parameters: NULL when valid, else a message naming the parameter. */
const char *iso_fert_check(const iso_fert_config_t *cfg);

/* Set up (the configuration must pass iso_fert_check). Returns 0, -1 if the pool cannot be
 * written. */
int iso_fert_init(iso_fert_t *c, const iso_fert_config_t *cfg);

/* The boot-up frame (heartbeat 0x710 [0x00]). */
hal_can_frame_t iso_fert_bootup(void);

/* Take a frame. Returns 0: what the network answers is sent with the next step. */
size_t iso_fert_on_frame(iso_fert_t *c, const hal_can_frame_t *frame);

/* One control step (free-running, or what a SYNC does in lockstep); frames in c->out. */
size_t iso_fert_step(iso_fert_t *c);

/* What the controller does now (for tests and logs). */
bool iso_fert_metering(const iso_fert_t *c);
bool iso_fert_ground_speed(const iso_fert_t *c, double *mps, int *source);

#endif
