/* Sowing depth: where the roller is held while the depth sensor is dead (issue #16).
 *
 * The C build of reference_controllers/sowing_depth/roller_hold.py (docs/models/
 * reference-controllers.md section 2, "CAN adapter"): the same arithmetic in the same order.
 * While the depth loop regulates, the rod runs excursions of ~1-2 mm (1-2 s period) around the
 * position that gives the target depth; the mean over the last seconds of valid control is the
 * best estimate of that position. So, with p the drive's Position actual value (0x6064, TPDO1):
 *
 *   tracking (depth valid, control enabled):  m += min(1, T/tau) (p - m)   (first: m = p)
 *   each new X voltage (a sign of life):      h  = m
 *   holding  (depth invalid, enabled):        v  = clamp(k (h - p), -v_hold, v_hold)
 *
 * The target h is the mean at the sensor's last sign of life: a frozen output is recognised
 * only frozen_after_s after its last change, and the positions reached meanwhile, steering on
 * a dead reading, say nothing about the right one.
 *
 * Defaults, from the rig's physics (the Python module says more): tau = 2 s attenuates the
 * 0.5-1 Hz excursions to 8-16 % and follows the soil (>= 4.5 s correlation at 4 km/h); k = 5 /s
 * (0.2 s; with the position one SYNC old the discrete poles stay real for kT <= 0.25, here
 * 0.05: no overshoot); v_hold = 10 mm/s (what a 2 mm offset asks; k v_hold = 50 mm/s^2, far
 * below the drive's 250 mm/s^2 profile deceleration). Pure: no I/O, no allocation. */
#ifndef AGRIHIL_ROLLER_HOLD_H
#define AGRIHIL_ROLLER_HOLD_H

#include <stdbool.h>

typedef struct {
    double time_constant_s; /* tau: low-pass time constant of the mean rod position, s (> 0) */
    double gain_per_s;      /* k: position loop gain, mm/s per mm (>= 0; 0: hold in place) */
    double speed_mm_s;      /* v_hold: bound of the hold speed command, mm/s (>= 0) */
} rhold_params_t;

typedef struct {
    bool has_mean;
    double mean_mm;   /* m: mean rod position of valid control, mm */
    bool has_target;
    double target_mm; /* h: the mean at the depth sensor's last sign of life, mm */
} rhold_state_t;

void rhold_defaults(rhold_params_t *p);

/* 0, or -1 with a message in err if a parameter is out of its range. */
int rhold_check(const rhold_params_t *p, const char **err);

/* Forget the mean and the target (control was switched off). */
void rhold_reset(rhold_state_t *s);

/* The depth sensor showed a sign of life (a new reading): the mean so far is the target. */
void rhold_mark(rhold_state_t *s);

/* One step of valid control at rod position position_mm, period period_s: update the mean. */
void rhold_track(const rhold_params_t *p, rhold_state_t *s, double position_mm,
                 double period_s);

/* The rod speed (mm/s, positive extends) that drives the rod to the target; 0 without one. */
double rhold_speed(const rhold_params_t *p, const rhold_state_t *s, double position_mm);

#endif
