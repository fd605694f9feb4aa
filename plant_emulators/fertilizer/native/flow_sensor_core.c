/* C twin of FlowSensor's step loop; see flow_sensor_core.h. Comments name the Python lines
 * each block mirrors: keep the two in step (the equivalence tests will say when they are
 * not). */
#include "flow_sensor_core.h"

#include <math.h>
#include <string.h>

/* flow_sensor._EMPTY_PIPE_PF */
#define EMPTY_PIPE_PF 1.0

void fs_init(FlowSensorCore *fs, double conv_s, double jit_a, double jit_b, double drift_a,
             double drift_b, double transit_s, double sensitivity, double range_pf,
             double lsb_pf, long long baseline_samples, double jitter, double drift_pf,
             double inv_tau, NormalBlock *z)
{
    memset(fs, 0, sizeof *fs);
    fs->conv_s = conv_s;
    fs->jit_a = jit_a;
    fs->jit_b = jit_b;
    fs->drift_a = drift_a;
    fs->drift_b = drift_b;
    fs->transit_s = transit_s;
    fs->sensitivity = sensitivity;
    fs->range_pf = range_pf;
    fs->lsb_pf = lsb_pf;
    fs->baseline_samples = baseline_samples;
    fs->z = z;
    fs->jitter = jitter;
    fs->drift = drift_pf;
    fs->inv_tau = inv_tau;
    /* steps, holdup, h_acc, conv_start, t_conv, baseline and window sums: 0 (memset) */
}

long long fs_crossing(double t0, double step, double due, double *t_out)
{
    /* _crossing: clock = list(accumulate(repeat(step, chunk), initial=t0)), then the first
     * k >= 1 with clock[k] >= due (bisect_left of the increasing clock): the same additions
     * one at a time, stopping at the first that reaches due. */
    double t = t0;
    long long k = 0;
    do {
        double next = t + step;
        if (next == t) {
            return -1;
        }
        t = next;
        ++k;
    } while (!(t >= due));
    *t_out = t;
    return k;
}

int fs_bind(FlowSensorCore *fs, double dt, double step, double conv_due, double sub_s,
            double sub_due)
{
    /* FlowSensor._bind_dt:
     *     self._sub_at, self._sub_clock = _crossing(0.0, self._step_rig, self._sub_due) */
    double sub_clock;
    long long k = fs_crossing(0.0, step, sub_due, &sub_clock);
    if (k < 0) {
        return FS_CLOCK_STUCK;
    }
    fs->dt = dt;
    fs->step = step;
    fs->conv_due = conv_due;
    fs->sub_s = sub_s;
    fs->sub_due = sub_due;
    fs->sub_at = k;
    fs->sub_clock = sub_clock;
    fs->bound = 1;
    return FS_OK;
}

void fs_take_window(FlowSensorCore *fs, double *sum_pf, int *overrange)
{
    /* FlowSensor._close_sub_window:
     *     self._window.append((self._sub_sum_pf, self._sub_overrange))
     *     self._sub_sum_pf = 0.0
     *     self._sub_overrange = False */
    *sum_pf = fs->sub_sum_pf;
    *overrange = fs->sub_overrange;
    fs->sub_sum_pf = 0.0;
    fs->sub_overrange = 0;
}

/* FlowSensor._convert(holdup_g): one conversion; returns FS_OK or an error, and the next
 * 1/tau in *inv_tau_out. */
static int convert(FlowSensorCore *fs, double holdup_g, double noise_pf, double *inv_tau_out)
{
    NormalBlock *z = fs->z;
    /* jitter = self._jit_a * self._jitter + self._jit_b * z()
     * self._jitter = jitter */
    double z_jit = nb_next(z);
    if (z->failed) {            /* (never ask the source again once it failed) */
        return FS_Z_FAILED;
    }
    double jitter = fs->jit_a * fs->jitter + fs->jit_b * z_jit;
    fs->jitter = jitter;
    /* inv_tau = 1.0 / (self._transit_s * (1.0 + jitter))
     * self._inv_tau = inv_tau */
    double inv_tau = 1.0 / (fs->transit_s * (1.0 + jitter));
    fs->inv_tau = inv_tau;
    /* drift = self._drift_pf = self._drift_a * self._drift_pf + self._drift_b * z() */
    double z_drift = nb_next(z);
    if (z->failed) {
        return FS_Z_FAILED;
    }
    double drift = fs->drift_a * fs->drift + fs->drift_b * z_drift;
    fs->drift = drift;
    /* c = _EMPTY_PIPE_PF + drift + self._sensitivity * holdup_g + self._noise_pf * z()
     * (left to right: ((1 + drift) + s*H) + noise*z) */
    double z_noise = nb_next(z);
    if (z->failed) {
        return FS_Z_FAILED;
    }
    double c = EMPTY_PIPE_PF + drift + fs->sensitivity * holdup_g + noise_pf * z_noise;
    /* overrange = abs(c) > range_pf
     * if overrange: c = math.copysign(range_pf, c) */
    double range_pf = fs->range_pf;
    int overrange = fabs(c) > range_pf;
    if (overrange) {
        c = copysign(range_pf, c);
    }
    /* c = round(c / lsb) * lsb: round() of a float is round-half-even to an int, which is a
     * whole double here, so nearbyint (default rounding mode: to nearest, ties to even) gives
     * the same value; int * float converts the int back to that double exactly. round()
     * raises on NaN and infinities: say so, the glue raises what Python would. */
    double lsb = fs->lsb_pf;
    double units = c / lsb;
    if (isnan(units)) {
        return FS_ROUND_NAN;
    }
    if (isinf(units)) {
        return FS_ROUND_INF;
    }
    /* + 0.0: round() of a value in (-0.5, 0] is the int 0, which converts to +0.0; nearbyint
     * gives -0.0 there */
    c = (nearbyint(units) + 0.0) * lsb;
    if (!fs->baseline_ready) {
        /* FlowSensor._acquire_baseline(c):
         *     self._baseline_acc += c
         *     self._baseline_n += 1
         *     if self._baseline_n >= self.config.baseline_samples:
         *         self._baseline_pf = self._baseline_acc / self._baseline_n */
        fs->baseline_acc += c;
        fs->baseline_n += 1;
        if (fs->baseline_n >= fs->baseline_samples) {
            fs->baseline_pf = fs->baseline_acc / (double)fs->baseline_n;
            fs->baseline_ready = 1;
        }
    } else {
        /* self._sub_sum_pf += c - baseline
         * if overrange: self._sub_overrange = True */
        fs->sub_sum_pf += c - fs->baseline_pf;
        if (overrange) {
            fs->sub_overrange = 1;
        }
    }
    *inv_tau_out = inv_tau;
    return FS_OK;
}

int fs_advance(FlowSensorCore *fs, long long n, double flow_gps, double noise_pf,
               long long *rest)
{
    /* q = flow_gps if flow_gps > 0.0 else 0.0 (NaN: 0.0) */
    const double q = flow_gps > 0.0 ? flow_gps : 0.0;
    /* step, conv_due, conv_s = self._step_rig, self._conv_due, self._conv_s
     * h, inv_tau = self._holdup_g, self._inv_tau
     * h_acc, conv_start = self._h_acc, self._conv_start
     * t_conv = self._t_conv
     * steps = self._steps
     * end = steps + n */
    const double dt = fs->dt, step = fs->step, conv_due = fs->conv_due, conv_s = fs->conv_s;
    double h = fs->holdup, inv_tau = fs->inv_tau;
    double h_acc = fs->h_acc;
    long long conv_start = fs->conv_start;
    double t_conv = fs->t_conv;
    const long long steps = fs->steps;
    const long long end = steps + n;
    const long long sub_at = fs->sub_at;
    /* stop = end if end < sub_at else sub_at */
    const long long stop = end < sub_at ? end : sub_at;
    int rc = FS_OK;
    /* for count in range(steps + 1, stop + 1): */
    for (long long count = steps + 1; count <= stop; ++count) {
        /* h += dt * (q - h * inv_tau)
         * h_acc += h
         * t_conv += step */
        h += dt * (q - h * inv_tau);
        h_acc += h;
        t_conv += step;
        /* if t_conv >= conv_due:
         *     t_conv -= conv_s
         *     inv_tau = self._convert(h_acc / (count - conv_start))
         *     h_acc = 0.0
         *     conv_start = count */
        if (t_conv >= conv_due) {
            t_conv -= conv_s;
            rc = convert(fs, h_acc / (double)(count - conv_start), noise_pf, &inv_tau);
            if (rc != FS_OK) {
                break;
            }
            h_acc = 0.0;
            conv_start = count;
        }
    }
    if (rc != FS_OK) {
        /* Python's advance leaves through the exception before storing its locals: the
         * state keeps what _convert stored (jitter, 1/tau, drift), as here */
        *rest = -1;
        return rc;
    }
    /* self._holdup_g = h
     * self._h_acc, self._conv_start = h_acc, conv_start
     * self._t_conv = t_conv
     * self._steps = steps (= stop) */
    fs->holdup = h;
    fs->h_acc = h_acc;
    fs->conv_start = conv_start;
    fs->t_conv = t_conv;
    fs->steps = stop;
    /* if steps != sub_at: break */
    if (stop != sub_at) {
        *rest = -1;
        return FS_OK;
    }
    /* The window ends: the caller closes it (self._close_sub_window(steps * dt)); the next
     * one is scheduled here:
     *     k, self._sub_clock = _crossing(self._sub_clock - self._sub_s, step, self._sub_due)
     *     sub_at += k */
    double sub_clock;
    long long k = fs_crossing(fs->sub_clock - fs->sub_s, step, fs->sub_due, &sub_clock);
    if (k < 0) {
        *rest = -1;
        return FS_CLOCK_STUCK;
    }
    fs->sub_clock = sub_clock;
    fs->sub_at = sub_at + k;
    *rest = end - stop;
    return FS_OK;
}
