/* Cross-row plausibility of the fertilizer's flow modules: a row that disagrees with the
 * other rows is left out of the mean.
 *
 * The C build of reference_controllers/fertilizer/cross_row.py (the same arithmetic in the
 * same order; that module derives the numbers). The rows are fed by one shaft through
 * identical rollers, so their flows agree within the rig's roller spread; a module that
 * freezes, steps or drifts with good status bits can be told only by the others. Each step,
 * over the rows that passed the single-row checks (flags, age, 3 Q + 5):
 *
 *   med  = median of their flows (the mean of the middle two for an even count)
 *   row disagrees when |flow - med| > XROW_THRESHOLD_FRAC med + XROW_FLOOR_GPS
 *   count += 1 when it disagrees (up to the dwell), -= 1 when it agrees (down to 0)
 *   excluded once count reaches the dwell (XROW_DWELL_S in steps), readmitted at 0
 *
 * A row that did not pass starts afresh (count 0, not excluded); with fewer than
 * XROW_MIN_ROWS rows to compare nothing is excluded and every count restarts.
 * 12 % + 1 g/s for 3 s: a healthy row of the shipped dispersion at its widest (roller spread
 * 2.5 %, module spread 0.8 %) stays inside: at most 6.7 % beyond the floor for 3 s over 30
 * seeds x 13 nominal scenarios, ~8 % expected over 300 samples; a block-mode module lags the
 * others by up to 2 s after a step or a row switched back on. Pure: no I/O, no allocation. */
#ifndef AGRIHIL_CROSS_ROW_H
#define AGRIHIL_CROSS_ROW_H

#include <stdbool.h>

#define XROW_MAX_ROWS 8
#define XROW_THRESHOLD_FRAC 0.12
#define XROW_FLOOR_GPS 1.0
#define XROW_DWELL_S 3.0
#define XROW_MIN_ROWS 3

typedef struct {
    int dwell_steps;            /* XROW_DWELL_S in whole control steps (>= 1) */
    int count[XROW_MAX_ROWS];   /* steps of disagreement, net of agreement, 0..dwell_steps */
    bool out[XROW_MAX_ROWS];    /* excluded */
} xrow_state_t;

/* A fresh check for a controller stepping every period_s seconds (> 0). */
void xrow_init(xrow_state_t *s, double period_s);

/* One control step over rows 0..n-1 (n <= XROW_MAX_ROWS): flow_gps[i] is row i's report,
 * passed[i] whether it passed the single-row checks. Sets excluded[i] (false for a row that
 * did not pass). */
void xrow_step(xrow_state_t *s, int n, const double flow_gps[], const bool passed[],
               bool excluded[]);

/* The measured flow over rows 0..n-1: the mean of the rows that passed and were not left out
 * (summed in row order, as the Python build's FlowRows.measure), 0 when none; *any_fresh
 * whether one of them reported since the last step. Returns whether any row counted. */
bool xrow_kept_mean(int n, const double flow_gps[], const bool passed[], const bool excluded[],
                    const bool fresh[], double *mean_gps, bool *any_fresh);

#endif
