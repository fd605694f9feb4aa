/* C twin of plant_emulators.fertilizer.flow_sensor.FlowSensor's step loop.
 *
 * Holdup between the electrodes (dH/dt = q - H/tau, explicit Euler), its sum over the running
 * AD7746 conversion, the module clock that ends a conversion, and each conversion
 * (FlowSensor._convert): transit-time jitter and baseline drift (OU processes), noise,
 * clipping at the input range, quantization, then either the start-up baseline average
 * (FlowSensor._acquire_baseline) or the running window's sum of C - C_initial.
 *
 * The core also schedules the window ends on the module's clock (flow_sensor._crossing: the
 * same additions; in Python it costs some 20 us a window, more than the steps). What runs
 * once per window or less stays in Python: the reports (FlowSensor._close_sub_window), faults,
 * and the vibration noise level (math.hypot is not libm's hypot: Python computes it and passes
 * it in). The core advances up to the end of the call or of the running window, whichever
 * comes first, and says which: at a window's end it schedules the next one and returns, and
 * Python closes the window and resumes.
 *
 * Every expression is the Python model's, in the same order, compiled without contraction or
 * reassociation (-ffp-contract=off, no -ffast-math), so the doubles are the same bit for bit:
 * tests compare the two engines. Normal variates come from the same generator in the same
 * blocks as the Python model's NormalStream (normal_block.h). Nothing is allocated.
 */
#ifndef AGRIHIL_FLOW_SENSOR_CORE_H
#define AGRIHIL_FLOW_SENSOR_CORE_H

#include "../../native/normal_block.h"

/* fs_advance's results */
enum {
    FS_OK = 0,
    FS_Z_FAILED = -1,     /* a normal-variate refill failed (z->failed) */
    FS_ROUND_NAN = -2,    /* round(c / lsb) of a NaN: Python raises ValueError */
    FS_ROUND_INF = -3,    /* round(c / lsb) of an infinity: Python raises OverflowError */
    FS_CLOCK_STUCK = -4,  /* the module clock does not advance (t + step == t): Python's
                           * _crossing would never return */
};

typedef struct {
    /* constants, fixed at init (FlowSensor.__init__) */
    double conv_s;            /* _conv_s */
    double jit_a, jit_b;      /* _jit_a, _jit_b */
    double drift_a, drift_b;  /* _drift_a, _drift_b */
    double transit_s;         /* _transit_s */
    double sensitivity;       /* _sensitivity */
    double range_pf, lsb_pf;  /* _range_pf, _lsb_pf */
    long long baseline_samples;   /* config.baseline_samples */
    NormalBlock *z;           /* _z */
    /* bound with the step size (FlowSensor._bind_dt) */
    int bound;
    double dt, step, conv_due;    /* dt, _step_rig, _conv_due */
    double sub_s, sub_due;        /* _sub_s, _sub_due */
    /* state */
    long long steps;          /* _steps */
    long long sub_at;         /* _sub_at: step count at which the running window ends */
    double sub_clock;         /* _sub_clock: the module clock then (s) */
    double holdup;            /* _holdup_g */
    double inv_tau;           /* _inv_tau */
    double jitter;            /* _jitter */
    double drift;             /* _drift_pf */
    double h_acc;             /* _h_acc */
    long long conv_start;     /* _conv_start */
    double t_conv;            /* _t_conv */
    double baseline_acc;      /* _baseline_acc */
    long long baseline_n;     /* _baseline_n */
    int baseline_ready;       /* _baseline_pf is not None */
    double baseline_pf;       /* _baseline_pf (when ready) */
    double sub_sum_pf;        /* _sub_sum_pf */
    int sub_overrange;        /* _sub_overrange */
} FlowSensorCore;

/* The constants and the initial state the Python constructor drew. */
void fs_init(FlowSensorCore *fs, double conv_s, double jit_a, double jit_b, double drift_a,
             double drift_b, double transit_s, double sensitivity, double range_pf,
             double lsb_pf, long long baseline_samples, double jitter, double drift_pf,
             double inv_tau, NormalBlock *z);

/* The step size, the module-clock step, the conversion threshold, the window length and its
 * threshold; schedules the first window end. FS_OK or FS_CLOCK_STUCK. */
int fs_bind(FlowSensorCore *fs, double dt, double step, double conv_due, double sub_s,
            double sub_due);

/* Up to n steps with the flow held at flow_gps and the conversion noise at noise_pf (pF).
 * Stops early at the end of the running window (steps == the window's end): it schedules the
 * next window and sets *rest to the number of steps still to do (>= 0; the caller closes the
 * window that ended and calls again with them); otherwise *rest is -1. Returns FS_OK or an
 * error above (the state is then mid-call, as Python's after its exception). */
int fs_advance(FlowSensorCore *fs, long long n, double flow_gps, double noise_pf,
               long long *rest);

/* flow_sensor._crossing(t0, step, due): the number of steps (>= 1) after which a clock that
 * adds step once per step, from t0, first reaches due, and the clock then (*t_out); -1 when
 * the clock does not advance. */
long long fs_crossing(double t0, double step, double due, double *t_out);

/* The running window's sum of C - C_initial and overrange flag; resets both. */
void fs_take_window(FlowSensorCore *fs, double *sum_pf, int *overrange);

#endif
