/* C twin of GroundSpeedModel's step loop; see ground_speed_core.h. Comments name the Python
 * lines each block mirrors: keep the two in step (the equivalence tests will say when they
 * are not). */
#include "ground_speed_core.h"

#include <stdlib.h>
#include <string.h>

/* ground_speed._slow_factors */
typedef struct {
    double v_goal, f_wheel, f_wb, f_gb;
} SlowFactors;

static SlowFactors slow_factors(double target, double variation, double wheel_slip,
                                double tractor_slip, double radar_noise, double radar_gain)
{
    SlowFactors f;
    f.v_goal = target * (1.0 + variation);
    f.f_wheel = 1.0 - (wheel_slip > 0.0 ? wheel_slip : 0.0);
    f.f_wb = 1.0 - (tractor_slip > 0.0 ? tractor_slip : 0.0);
    f.f_gb = radar_gain + radar_noise;
    return f;
}

/* self._edges.append(t) on a deque(maxlen=_EDGE_HISTORY): the oldest edge drops out. */
static void add_edge(GroundSpeedCore *gs, double t)
{
    if (gs->edge_count < GS_EDGE_HISTORY) {
        gs->edges[(gs->edge_start + gs->edge_count) % GS_EDGE_HISTORY] = t;
        gs->edge_count += 1;
    } else {
        gs->edges[gs->edge_start] = t;
        gs->edge_start = (gs->edge_start + 1) % GS_EDGE_HISTORY;
    }
}

/* edges[i] of the deque (0 <= i < edge_count; 0 is the oldest). */
static double edge_at(const GroundSpeedCore *gs, int i)
{
    return gs->edges[(gs->edge_start + i) % GS_EDGE_HISTORY];
}

int gs_init(GroundSpeedCore *gs, int n_mag, const double *errors, double variation,
            double wheel_slip, double tractor_slip, double radar_noise, double ar1, double ar2,
            double ar_gain, double radar_gain, double vib_rms_per_mps, double hall_timeout_s,
            double hall_average_window_s, double reported_metres_per_pulse, NormalBlock *z)
{
    memset(gs, 0, sizeof *gs);
    gs->errors = malloc((size_t)n_mag * sizeof(double));
    if (gs->errors == NULL) {
        return -1;
    }
    memcpy(gs->errors, errors, (size_t)n_mag * sizeof(double));
    gs->n_mag = n_mag;
    gs->variation = variation;
    gs->wslip = wheel_slip;
    gs->tslip = tractor_slip;
    gs->rnoise = radar_noise;
    gs->ar1 = ar1;
    gs->ar2 = ar2;
    gs->ar_gain = ar_gain;
    gs->radar_gain_out = radar_gain;
    gs->vib_rms_per_mps = vib_rms_per_mps;
    gs->hall_timeout_s = hall_timeout_s;
    gs->hall_average_window_s = hall_average_window_s;
    gs->reported_metres_per_pulse = reported_metres_per_pulse;
    gs->z = z;
    /* self._next_edge = 1.0 + self.pulse_spacing_errors[1 % n_mag] (the rest of the state
     * starts at zero: memset) */
    gs->next_edge = 1.0 + errors[1 % n_mag];
    return 0;
}

void gs_bind(GroundSpeedCore *gs, double dt, const GsStep *k)
{
    gs->dt = dt;
    gs->k = *k;
    gs->bound = 1;
}

int gs_advance(GroundSpeedCore *gs, long long n, double target)
{
    const GsStep k = gs->k;
    const double dt = gs->dt;
    const double ar1 = gs->ar1, ar2 = gs->ar2, ar_gain = gs->ar_gain;
    const double *errors = gs->errors;
    const long long n_mag = gs->n_mag;
    NormalBlock *z = gs->z;

    double v = gs->v, dist = gs->dist;
    double wheel_dist = gs->wheel_dist, wb_dist = gs->wb_dist, gb_dist = gs->gb_dist;
    double variation = gs->variation, wslip = gs->wslip, tslip = gs->tslip;
    double rnoise = gs->rnoise;
    double vib0 = gs->vib0, vib1 = gs->vib1;
    double pos = gs->pos, next_edge = gs->next_edge;
    long long pulses = gs->pulses;
    long countdown = gs->countdown;
    const long long steps = gs->steps;
    /* v_goal, f_wheel, f_wb, f_gb = _slow_factors(target, variation, wslip, tslip, rnoise,
     *                                             radar_gain) */
    SlowFactors f = slow_factors(target, variation, wslip, tslip, rnoise, k.radar_gain);
    int rc = GS_OK;

    /* for k in range(steps, steps + n): */
    long long kk;
    for (kk = steps; kk < steps + n; ++kk) {
        /* if countdown <= 0: the slow processes, five draws in this order */
        if (countdown <= 0) {
            countdown = k.slow;
            /* the five draws, in the order the statements below make them (a failed draw
             * ends the call; the glue then refuses this twin: see normal_block.h) */
            double z1 = nb_next(z);
            double z2 = nb_next(z);
            double z3 = nb_next(z);
            double z4 = nb_next(z);
            double z5 = nb_next(z);
            if (z->failed) {
                rc = GS_NOISE_FAILED;
                break;
            }
            /* variation = var_a * variation + var_b * znext() */
            variation = k.var_a * variation + k.var_b * z1;
            /* wslip = ws_mean + ws_a * (wslip - ws_mean) + ws_b * znext() */
            wslip = k.ws_mean + k.ws_a * (wslip - k.ws_mean) + k.ws_b * z2;
            /* tslip = ts_mean + ts_a * (tslip - ts_mean) + ts_b * znext() */
            tslip = k.ts_mean + k.ts_a * (tslip - k.ts_mean) + k.ts_b * z3;
            /* rnoise = rn_a * rnoise + rn_b * znext() */
            rnoise = k.rn_a * rnoise + k.rn_b * z4;
            /* vib0, vib1 = ar1 * vib0 + ar2 * vib1 + znext() * ar_gain, vib0 */
            double vib_new = ar1 * vib0 + ar2 * vib1 + z5 * ar_gain;
            vib1 = vib0;
            vib0 = vib_new;
            /* v_goal, f_wheel, f_wb, f_gb = _slow_factors(...) */
            f = slow_factors(target, variation, wslip, tslip, rnoise, k.radar_gain);
        }
        countdown -= 1;
        /* dv = (v_goal - v) * k_tau, clamped to +-dv_max; asked to stop (v_goal <= 0), the
           driver brakes at the field deceleration down to a standstill */
        double dv = (f.v_goal - v) * k.k_tau;
        if (f.v_goal <= 0.0) {
            dv = -k.dv_max;
        } else if (dv > k.dv_max) {
            dv = k.dv_max;
        } else if (dv < -k.dv_max) {
            dv = -k.dv_max;
        }
        v += dv;
        if (v < 0.0) {
            v = 0.0;
        }
        /* dist += v * dt */
        dist += v * dt;
        /* wheel_step = v * f_wheel * dt; wheel_dist += wheel_step */
        double wheel_step = v * f.f_wheel * dt;
        wheel_dist += wheel_step;
        /* wb_dist += v / f_wb * dt   (Python raises ZeroDivisionError on f_wb == 0) */
        if (f.f_wb == 0.0) {
            rc = GS_ZERO_DIVISION;
            break;
        }
        wb_dist += v / f.f_wb * dt;
        /* gb_dist += v * f_gb * dt */
        gb_dist += v * f.f_gb * dt;
        /* step_pitches = wheel_step * inv_pitch; new_pos = pos + step_pitches */
        double step_pitches = wheel_step * k.inv_pitch;
        double new_pos = pos + step_pitches;
        /* while new_pos >= next_edge:
         *     add_edge((k + (next_edge - pos) / step_pitches) * dt)
         *     pulses += 1
         *     next_edge = pulses + 1 + errors[(pulses + 1) % n_mag] */
        while (new_pos >= next_edge) {
            if (step_pitches == 0.0) {
                rc = GS_ZERO_DIVISION;
                break;
            }
            add_edge(gs, ((double)kk + (next_edge - pos) / step_pitches) * dt);
            pulses += 1;
            next_edge = (double)(pulses + 1) + errors[(pulses + 1) % n_mag];
        }
        if (rc != GS_OK) {
            break;
        }
        /* pos = new_pos */
        pos = new_pos;
    }

    /* steps += n and the write-back of the state (on an error: as far as it got) */
    gs->steps = rc == GS_OK ? steps + n : kk;
    gs->v = v;
    gs->dist = dist;
    gs->wheel_dist = wheel_dist;
    gs->wb_dist = wb_dist;
    gs->gb_dist = gb_dist;
    gs->variation = variation;
    gs->wslip = wslip;
    gs->tslip = tslip;
    gs->rnoise = rnoise;
    gs->vib0 = vib0;
    gs->vib1 = vib1;
    gs->pos = pos;
    gs->pulses = pulses;
    gs->next_edge = next_edge;
    gs->countdown = countdown;
    return rc;
}

int gs_outputs(const GroundSpeedCore *gs, double *out, long long *hall_pulses)
{
    /* GroundSpeedModel._update_outputs, line by line */
    double v = gs->v;
    double wsf = gs->wslip > 0.0 ? gs->wslip : 0.0;
    double tsf = gs->tslip > 0.0 ? gs->tslip : 0.0;
    double wb_den = 1.0 - tsf;
    if (wb_den == 0.0) {
        return GS_ZERO_DIVISION;
    }
    out[GS_TIME_S] = (double)gs->steps * (gs->bound ? gs->dt : 0.0);
    out[GS_TRUE_SPEED] = v;
    out[GS_TRUE_DISTANCE] = gs->dist;
    out[GS_WHEEL_SLIP] = wsf;
    out[GS_TRACTOR_SLIP] = tsf;
    out[GS_WHEEL_SPEED] = v * (1.0 - wsf);
    out[GS_WHEEL_DISTANCE] = gs->wheel_dist;
    *hall_pulses = gs->pulses;
    out[GS_WB_SPEED] = v / wb_den;
    out[GS_WB_DISTANCE] = gs->wb_dist;
    out[GS_GB_SPEED] = v * (gs->radar_gain_out + gs->rnoise);
    out[GS_GB_DISTANCE] = gs->gb_dist;
    out[GS_VIB_RMS] = gs->vib_rms_per_mps * v;
    out[GS_VIB] = out[GS_VIB_RMS] * gs->vib0;
    return GS_OK;
}

int gs_hall_report(const GroundSpeedCore *gs, GsHallReport *out)
{
    /* GroundSpeedModel.hall_report, line by line */
    GsHallReport r = {0.0, gs->pulses, 0.0, 0};
    *out = r;
    double now = (double)gs->steps * (gs->bound ? gs->dt : 0.0);     /* self.time_s */
    int count = gs->edge_count;                                      /* len(edges) */
    if (count == 0) {
        return GS_OK;
    }
    double last = edge_at(gs, count - 1);
    r.last_period_s = count >= 2 ? last - edge_at(gs, count - 2) : 0.0;
    if (now - last > gs->hall_timeout_s || count < 2) {
        *out = r;
        return GS_OK;
    }
    double horizon = now - gs->hall_average_window_s;
    int first_i = count - 2;
    while (first_i > 0 && edge_at(gs, first_i - 1) >= horizon) {
        first_i -= 1;
    }
    double span = last - edge_at(gs, first_i);
    int n = count - 1 - first_i;
    double period = span / (double)n;
    /* period = max(period, now - last): the second only when strictly greater */
    double since_last = now - last;
    if (since_last > period) {
        period = since_last;
    }
    if (period == 0.0) {             /* Python: ZeroDivisionError */
        return GS_ZERO_DIVISION;
    }
    r.wheel_speed_mps = gs->reported_metres_per_pulse / period;
    r.moving = 1;
    *out = r;
    return GS_OK;
}

void gs_free(GroundSpeedCore *gs)
{
    free(gs->errors);
    gs->errors = NULL;
}
