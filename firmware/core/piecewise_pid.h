/* Fertilizer flow: piecewise incremental PID of [F] eq. 11-13, three laws.
 *
 * The contract is docs/reference-controllers.md section 1; this is its C build (the Python build
 * in reference_controllers/ computes the same numbers, checked by the shared test vectors).
 * Pure: no I/O, no allocation, IEEE double throughout.
 *
 *   PPID_LAW_PAPER_LITERAL  eq. 12-13 with the published gains, no feedforward (section 1a)
 *   PPID_LAW_PHYSICAL       same three segments on the relative error, position-form P and D,
 *                           incremental I, multiplier on the flow-map feedforward (section 1b)
 *   PPID_LAW_OPEN_LOOP      feedforward only: [F]'s constant-speed baseline (section 1c)
 *
 * Call ppid_step() once per control period. */
#ifndef AGRIHIL_PIECEWISE_PID_H
#define AGRIHIL_PIECEWISE_PID_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "params.h"

typedef enum {
    PPID_LAW_PHYSICAL = 0,
    PPID_LAW_PAPER_LITERAL = 1,
    PPID_LAW_OPEN_LOOP = 2
} ppid_law_t;

/* PidSegment of the DBC */
enum { PPID_SEG_NONE = 0, PPID_SEG_FINE = 1, PPID_SEG_MEDIUM = 2, PPID_SEG_COARSE = 3 };

typedef struct {
    ppid_law_t law;
    double kp1, kp2, kp3; /* proportional gain of the fine / medium / coarse segment */
    double ki1, ki2;      /* integral gain of the fine / medium segment (coarse: 0) */
    double kd;            /* derivative gain, all segments */
    double e1, e2;        /* segment thresholds: g/s (paper-literal) or fractions of Q */
    double km;            /* paper-literal: volts per controller unit ([F]'s G1 = Km) */
    double v_max;         /* analog output limit, V */
    double c_max;         /* physical: limit of the correction multiplier and of I */
    double settle_periods; /* physical: periods after a target jump whose reports are ignored */
    double ki_first;       /* physical: integral gain of the first update after a reset */
    double ff_coeff;        /* meter's nominal map q = ff_coeff * n^ff_exponent */
    double ff_exponent;     /* (g/s per row, n shaft r/min) */
    double shaft_rpm_per_v; /* drive scaling: shaft r/min per volt (10 V -> 60 r/min: 6) */
    double ff_linear_below_rpm; /* the map is linear below this shaft speed (0: never) */
} ppid_params_t;

typedef struct {
    bool primed;       /* an update happened since the last reset */
    double u;          /* paper-literal: controller output, units */
    double e_prev;     /* paper-literal: e(k-1), g/s */
    double e_prev2;    /* paper-literal: e(k-2), g/s */
    double integral;   /* physical: I */
    double correction; /* physical: c, held between updates */
    double r_prev;     /* physical: r(k-1) */
    double target_prev; /* physical: the target of the previous step */
    uint32_t since_jump; /* physical: steps since the last target jump */
    bool learnt;         /* physical: the integral has had its first update */
    uint8_t segment;   /* segment of the last update */
} ppid_state_t;

typedef struct {
    double volts;
    uint8_t segment;
} ppid_output_t;

#define PPID_PARAM_COUNT 17

/* Defaults of docs/reference-controllers.md for `law` (thresholds and gains differ per law). */
void ppid_defaults(ppid_params_t *p, ppid_law_t law);

/* Fill `refs` with the named parameters of `p`; returns the count (at most PPID_PARAM_COUNT).
 * Names (those of the Python build): kp1 kp2 kp3 ki1 ki2 kd e1 e2 km c_max settle_periods
 * ki_first ff_coeff ff_exponent shaft_rpm_per_v v_max ff_linear_below_rpm; the open-loop law has
 * only the feedforward ones (ff_coeff ff_exponent shaft_rpm_per_v v_max ff_linear_below_rpm). */
size_t ppid_param_refs(ppid_params_t *p, param_ref_t refs[PPID_PARAM_COUNT]);

/* "physical", "paper-literal" or "open-loop" (also with '_' for '-'); false if unknown. */
bool ppid_law_parse(const char *text, ppid_law_t *out);
const char *ppid_law_name(ppid_law_t law);

void ppid_reset(ppid_state_t *s);

/* ff(Q) = clamp(n(Q) / shaft_rpm_per_v, 0, v_max) for Q > 0, else 0, with
 * n(Q) = (Q / ff_coeff)^(1 / ff_exponent) down to the knee n_k = ff_linear_below_rpm and
 * n(Q) = Q / (ff_coeff * n_k^ff_exponent) * n_k below it (a flute holds all it can). */
double ppid_feedforward(const ppid_params_t *p, double target_gps);

/* One control step. target_gps: per-row target; measured_gps: mean of the valid rows;
 * has_measurement: at least one valid row; new_report: a valid row reported since the previous
 * step. The state changes only when new_report && has_measurement (and resets on target <= 0). */
ppid_output_t ppid_step(const ppid_params_t *p, ppid_state_t *s, double target_gps,
                        double measured_gps, bool has_measurement, bool new_report);

#endif
