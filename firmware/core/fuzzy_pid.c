#include "fuzzy_pid.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

enum { NB, NM, NS, ZE, PS, PM, PB, NSETS };

#define IN_LIMIT 6.0    /* input universe [-6, 6] */
#define IN_HALF 2.0     /* input triangles: peaks -6, -4 ... 6, half-width 2 */
#define OUT_HALF 1.0    /* output triangles: peaks -3 ... 3, half-width 1 */
#define GRID_POINTS 61  /* centroid grid x_j = -3 + 0.1 j */

/* Rule tables: rows e = NB..PB, columns ec = NB..PB (Liu Jinkun's classic fuzzy-PID tables). */
static const uint8_t RULES_KP[NSETS][NSETS] = {
    {PB, PB, PM, PM, PS, ZE, ZE}, {PB, PB, PM, PS, PS, ZE, NS}, {PM, PM, PM, PS, ZE, NS, NS},
    {PM, PM, PS, ZE, NS, NM, NM}, {PS, PS, ZE, NS, NS, NM, NM}, {PS, ZE, NS, NM, NM, NM, NB},
    {ZE, ZE, NM, NM, NM, NB, NB},
};
static const uint8_t RULES_KI[NSETS][NSETS] = {
    {NB, NB, NM, NM, NS, ZE, ZE}, {NB, NB, NM, NS, NS, ZE, ZE}, {NB, NM, NS, NS, ZE, PS, PS},
    {NM, NM, NS, ZE, PS, PM, PM}, {NM, NS, ZE, PS, PS, PM, PB}, {ZE, ZE, PS, PS, PM, PB, PB},
    {ZE, ZE, PS, PM, PM, PB, PB},
};
static const uint8_t RULES_KD[NSETS][NSETS] = {
    {PS, NS, NB, NB, NB, NM, PS}, {PS, NS, NB, NM, NM, NS, ZE}, {ZE, NS, NM, NM, NS, NS, ZE},
    {ZE, NS, NS, NS, NS, NS, ZE}, {ZE, ZE, ZE, ZE, ZE, ZE, ZE}, {PB, NS, PS, PS, PS, PS, PB},
    {PB, PM, PM, PM, PS, PS, PB},
};

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

static double tri(double x, double peak, double half_width)
{
    return fmax(0.0, 1.0 - fabs(x - peak) / half_width);
}

void fpid_defaults(fpid_params_t *p)
{
    /* preset gains are not published in [D]: the Python build's defaults (tuned on the
     * emulator); DUT profiles pass their own */
    p->kp0 = 3.0;
    p->ki0 = 0.1;
    p->kd0 = 0.0;
    p->ke = 0.03;  /* Table 2: [-200, 200] mm -> [-6, 6] */
    p->kec = 0.12; /* [-50, 50] mm/s -> [-6, 6] */
    p->kp_scale = 0.30; /* [-3, 3] -> [-0.9, 0.9] */
    p->ki_scale = 0.02; /* [-3, 3] -> [-0.06, 0.06] */
    p->kd_scale = 0.50; /* [-3, 3] -> [-1.5, 1.5] */
    p->v_max = 50.0;
    p->period_s = 0.01;
}

size_t fpid_param_refs(fpid_params_t *p, param_ref_t refs[FPID_PARAM_COUNT])
{
    const param_ref_t table[FPID_PARAM_COUNT] = {
        {"kp0", &p->kp0},           {"ki0", &p->ki0},           {"kd0", &p->kd0},
        {"ke", &p->ke},             {"kec", &p->kec},           {"kp_scale", &p->kp_scale},
        {"ki_scale", &p->ki_scale}, {"kd_scale", &p->kd_scale}, {"v_max", &p->v_max},
        {"period_s", &p->period_s},
    };
    memcpy(refs, table, sizeof table);
    return FPID_PARAM_COUNT;
}

void fpid_reset(fpid_state_t *s)
{
    memset(s, 0, sizeof *s);
}

/* Centroid of the max-aggregated, weight-clipped output sets (set k clipped at weight[k]).
 * Each set is evaluated on its support only (peak +- 1, i.e. grid points 10k - 10 ... 10k + 10;
 * outside it the membership is exactly 0), which gives the same sums as the full grid. */
static double defuzzify(const double weight[NSETS])
{
    double mu[GRID_POINTS] = {0.0};
    int lo = GRID_POINTS, hi = -1;
    for (int k = 0; k < NSETS; k++) {
        if (!(weight[k] > 0.0)) {
            continue;
        }
        int first = 10 * k - 10 < 0 ? 0 : 10 * k - 10;
        int last = 10 * k + 10 >= GRID_POINTS ? GRID_POINTS - 1 : 10 * k + 10;
        for (int j = first; j <= last; j++) {
            double x = -3.0 + 0.1 * (double)j;
            mu[j] = fmax(mu[j], fmin(weight[k], tri(x, (double)(k - 3), OUT_HALF)));
        }
        lo = first < lo ? first : lo;
        hi = last > hi ? last : hi;
    }
    double num = 0.0;
    double den = 0.0;
    for (int j = lo; j <= hi; j++) {
        double x = -3.0 + 0.1 * (double)j;
        num += x * mu[j];
        den += mu[j];
    }
    return den > 0.0 ? num / den : 0.0;
}

fpid_fuzzy_t fpid_fuzzy(double e_norm, double ec_norm)
{
    double e = clamp(e_norm, -IN_LIMIT, IN_LIMIT);
    double ec = clamp(ec_norm, -IN_LIMIT, IN_LIMIT);
    double mu_e[NSETS], mu_ec[NSETS];
    for (int i = 0; i < NSETS; i++) {
        double peak = -IN_LIMIT + IN_HALF * (double)i;
        mu_e[i] = tri(e, peak, IN_HALF);
        mu_ec[i] = tri(ec, peak, IN_HALF);
    }
    /* per output set, the strongest rule firing it (max aggregation of the clipped sets is the
     * same as clipping each set at the max weight of the rules that name it) */
    double wp[NSETS] = {0}, wi[NSETS] = {0}, wd[NSETS] = {0};
    for (int i = 0; i < NSETS; i++) {
        if (mu_e[i] <= 0.0) {
            continue;
        }
        for (int j = 0; j < NSETS; j++) {
            double w = fmin(mu_e[i], mu_ec[j]);
            if (w <= 0.0) {
                continue;
            }
            wp[RULES_KP[i][j]] = fmax(wp[RULES_KP[i][j]], w);
            wi[RULES_KI[i][j]] = fmax(wi[RULES_KI[i][j]], w);
            wd[RULES_KD[i][j]] = fmax(wd[RULES_KD[i][j]], w);
        }
    }
    fpid_fuzzy_t out = {defuzzify(wp), defuzzify(wi), defuzzify(wd)};
    return out;
}

static int sign(double x)
{
    return (x > 0.0) - (x < 0.0);
}

fpid_output_t fpid_step(const fpid_params_t *p, fpid_state_t *s, double target_mm,
                        double depth_mm, bool valid, bool enabled)
{
    fpid_output_t out = {0.0, p->kp0, p->ki0, p->kd0};
    if (!(valid && enabled)) {
        fpid_reset(s);
        return out;
    }
    double e = target_mm - depth_mm;
    double ec = s->has_prev ? (e - s->e_prev) / p->period_s : 0.0;
    fpid_fuzzy_t f = fpid_fuzzy(p->ke * e, p->kec * ec);
    out.kp = fmax(0.0, p->kp0 + p->kp_scale * f.up);
    out.ki = fmax(0.0, p->ki0 + p->ki_scale * f.ui);
    out.kd = fmax(0.0, p->kd0 + p->kd_scale * f.ud);
    double u = out.kp * e + out.ki * s->integral + out.kd * ec;
    out.speed_mm_s = clamp(u, -p->v_max, p->v_max);
    /* conditional integration: freeze I while saturated in the direction of the error */
    if (!(u != out.speed_mm_s && sign(e) == sign(u))) {
        s->integral += e * p->period_s;
    }
    s->e_prev = e;
    s->has_prev = true;
    return out;
}
