/* C twin of plant_emulators.fertilizer.ground_speed.GroundSpeedModel's step loop.
 *
 * The slow processes (speed variation, wheel and tractor slip, radar noise: OU; frame
 * vibration: AR(2)), the tractor's speed lag with its acceleration limit, the four distances
 * and the Hall pulse edges, one step at a time; the outputs of _update_outputs and the Hall
 * node's report (hall_report) from that state.
 *
 * Every expression is the Python model's, in the same order, compiled without contraction or
 * reassociation (-ffp-contract=off, no -ffast-math), so a step gives the same doubles as the
 * Python loop: tests compare the two bit for bit. The constants are computed once, in Python,
 * and handed over (gs_init, gs_bind). Python ints (step index, pulse count) are 64-bit
 * integers here and become doubles where Python mixes them with floats.
 *
 * Memory: gs_init allocates the per-magnet spacing errors once; the pulse edges live in a
 * fixed ring buffer (the Python model's deque(maxlen=512)); stepping allocates nothing.
 */
#ifndef AGRIHIL_GROUND_SPEED_CORE_H
#define AGRIHIL_GROUND_SPEED_CORE_H

#include <stddef.h>

#include "../../native/normal_block.h"

/* ground_speed._EDGE_HISTORY */
#define GS_EDGE_HISTORY 512

/* Step constants, in ground_speed._StepConstants' order. */
typedef struct {
    long slow;
    double var_a, var_b, ws_a, ws_b, ts_a, ts_b, rn_a, rn_b;
    double ws_mean, ts_mean, k_tau, dv_max, inv_pitch, radar_gain;
} GsStep;

/* What the Hall node reports (ground_speed.HallReport). */
typedef struct {
    double wheel_speed_mps;
    long long pulse_count;
    double last_period_s;
    int moving;
} GsHallReport;

/* The outputs GroundSpeedModel._update_outputs sets, in its order (hall_pulses apart). */
enum {
    GS_TIME_S, GS_TRUE_SPEED, GS_TRUE_DISTANCE, GS_WHEEL_SLIP, GS_TRACTOR_SLIP,
    GS_WHEEL_SPEED, GS_WHEEL_DISTANCE, /* hall_pulses comes here, as an integer */
    GS_WB_SPEED, GS_WB_DISTANCE, GS_GB_SPEED, GS_GB_DISTANCE, GS_VIB_RMS, GS_VIB,
    GS_N_OUTPUTS
};

/* Return codes of gs_advance / gs_outputs. */
#define GS_OK 0
#define GS_NOISE_FAILED (-1)   /* a normal-variate refill failed (z->failed) */
#define GS_ZERO_DIVISION (-2)  /* where the Python model raises ZeroDivisionError */

typedef struct {
    /* fixed at init */
    int n_mag;
    double *errors;            /* pulse_spacing_errors */
    double ar1, ar2, ar_gain;  /* _ar1, _ar2, _ar_gain */
    double radar_gain_out;     /* _radar_gain (what _update_outputs uses) */
    double vib_rms_per_mps;    /* _vib_rms_per_mps */
    double hall_timeout_s, hall_average_window_s, reported_metres_per_pulse;
    NormalBlock *z;
    /* bound with the step size */
    int bound;
    double dt;
    GsStep k;
    /* state */
    long long steps;
    long countdown;
    double v, dist, wheel_dist, wb_dist, gb_dist;
    double variation, wslip, tslip, rnoise;
    double vib0, vib1;
    double pos;                /* _pulse_pos */
    long long pulses;
    double next_edge;
    /* _edges: the last GS_EDGE_HISTORY edge times, oldest at edge_start */
    double edges[GS_EDGE_HISTORY];
    int edge_start, edge_count;
} GroundSpeedCore;

/* Copy the per-run values (the draws and the constants GroundSpeedModel.__init__ computes).
 * Returns 0, or -1 when out of memory. */
int gs_init(GroundSpeedCore *gs, int n_mag, const double *errors, double variation,
            double wheel_slip, double tractor_slip, double radar_noise, double ar1, double ar2,
            double ar_gain, double radar_gain, double vib_rms_per_mps, double hall_timeout_s,
            double hall_average_window_s, double reported_metres_per_pulse, NormalBlock *z);

/* Bind the step size (GroundSpeedModel._bind_dt). */
void gs_bind(GroundSpeedCore *gs, double dt, const GsStep *k);

/* n steps with the target held (target: max(0.0, float(target_speed_mps))). GS_OK, or an
 * error code (the state is then mid-call, as the Python model's would be unusable). */
int gs_advance(GroundSpeedCore *gs, long long n, double target);

/* GroundSpeedModel._update_outputs: out[GS_N_OUTPUTS] and the pulse count. GS_OK or
 * GS_ZERO_DIVISION. */
int gs_outputs(const GroundSpeedCore *gs, double *out, long long *hall_pulses);

/* GroundSpeedModel.hall_report into *out. GS_OK or GS_ZERO_DIVISION. */
int gs_hall_report(const GroundSpeedCore *gs, GsHallReport *out);

void gs_free(GroundSpeedCore *gs);

#endif
