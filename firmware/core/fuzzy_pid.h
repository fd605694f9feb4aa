/* Sowing depth: fuzzy self-tuning PID of [D] (eq. 10, Table 2).
 *
 * The contract is docs/reference-controllers.md section 2; this is its C build. A Mamdani fuzzy
 * system (7 triangular sets per input, min inference, max aggregation, centroid on a 61-point
 * grid) corrects the preset gains each step; the PID integrates conditionally (anti-windup).
 * Pure: no I/O, no allocation, IEEE double throughout. Call fpid_step() once per period T. */
#ifndef AGRIHIL_FUZZY_PID_H
#define AGRIHIL_FUZZY_PID_H

#include <stdbool.h>
#include <stddef.h>

#include "params.h"

typedef struct {
    double kp0, ki0, kd0; /* preset gains: mm/s per mm, per mm*s, per mm/s */
    double ke, kec;       /* input scaling: e (mm) -> E, ec (mm/s) -> EC, both on [-6, 6] */
    double kp_scale;      /* output scaling: Up, Ui, Ud on [-3, 3] -> gain corrections */
    double ki_scale;
    double kd_scale;
    double v_max;         /* rod speed limit, mm/s */
    double period_s;      /* control period T, s */
} fpid_params_t;

typedef struct {
    bool has_prev;   /* e_prev exists (false after a reset) */
    double e_prev;   /* mm */
    double integral; /* I = sum of e*T, mm*s */
} fpid_state_t;

typedef struct {
    double speed_mm_s;
    double kp, ki, kd;
} fpid_output_t;

/* Result of the fuzzy layer: corrections on [-3, 3] */
typedef struct {
    double up, ui, ud;
} fpid_fuzzy_t;

#define FPID_PARAM_COUNT 10

void fpid_defaults(fpid_params_t *p);

/* Names: kp0 ki0 kd0 ke kec kp_scale ki_scale kd_scale v_max period_s. */
size_t fpid_param_refs(fpid_params_t *p, param_ref_t refs[FPID_PARAM_COUNT]);

void fpid_reset(fpid_state_t *s);

/* The fuzzy layer alone: (Up, Ui, Ud) for E, EC (clamped to [-6, 6] first). */
fpid_fuzzy_t fpid_fuzzy(double e_norm, double ec_norm);

/* One control step. valid: a depth exists and the drive is in Operation enabled; enabled: the
 * terminal asks for automatic control and the ground speed is known and >= 0.1 m/s. */
fpid_output_t fpid_step(const fpid_params_t *p, fpid_state_t *s, double target_mm,
                        double depth_mm, bool valid, bool enabled);

#endif
