#include "piecewise_pid.h"

#include <math.h>
#include <string.h>

static double clamp(double x, double lo, double hi)
{
    return fmin(fmax(x, lo), hi);
}

void ppid_defaults(ppid_params_t *p, ppid_law_t law)
{
    memset(p, 0, sizeof *p);
    p->law = law;
    p->km = 0.1;
    p->v_max = 10.0;
    p->c_max = 0.5;
    p->ki_first = 0.8;        /* the first clean report sets most of the meter factor */
    p->settle_periods = 17.0; /* 1.7 s: the sensed flow settles ~1.5 s after a step */
    p->ff_coeff = 4.586; /* the emulated meter's nominal map (plant_emulators/fertilizer/rig.toml) */
    p->ff_exponent = 0.6537;
    p->shaft_rpm_per_v = 6.0;    /* 10 V -> 3,000 motor r/min -> 60 shaft r/min */
    p->ff_linear_below_rpm = 5.0; /* grams per revolution stop rising below it (issue #16) */
    if (law == PPID_LAW_PAPER_LITERAL) {
        /* [F]'s published gains; e1, e2 not published: ~4 % and ~20 % of the middle target */
        p->kp1 = 0.038;
        p->kp2 = 2.089;
        p->kp3 = 212.016;
        p->ki1 = 0.167;
        p->ki2 = 0.015;
        p->kd = 1.317;
        p->e1 = 1.0;
        p->e2 = 5.0;
    } else {
        /* physical (open loop uses none of these): thresholds relative to the target; gains
         * tuned on the emulator with the sliding-window sensor (scripts/tune_piecewise_pid.py),
         * the Python build's defaults */
        p->kp1 = 0.4;
        p->kp2 = 0.4;
        p->kp3 = 0.0;
        p->ki1 = 0.04;
        p->ki2 = 0.04;
        p->kd = 0.0;
        p->e1 = 0.02;
        p->e2 = 0.10;
    }
}

size_t ppid_param_refs(ppid_params_t *p, param_ref_t refs[PPID_PARAM_COUNT])
{
    /* feedforward first: the open-loop law takes only these */
    const param_ref_t table[PPID_PARAM_COUNT] = {
        {"ff_coeff", &p->ff_coeff},
        {"ff_exponent", &p->ff_exponent},
        {"shaft_rpm_per_v", &p->shaft_rpm_per_v},
        {"v_max", &p->v_max},
        {"ff_linear_below_rpm", &p->ff_linear_below_rpm},
        {"kp1", &p->kp1},
        {"kp2", &p->kp2},
        {"kp3", &p->kp3},
        {"ki1", &p->ki1},
        {"ki2", &p->ki2},
        {"kd", &p->kd},
        {"e1", &p->e1},
        {"e2", &p->e2},
        {"km", &p->km},
        {"c_max", &p->c_max},
        {"settle_periods", &p->settle_periods},
        {"ki_first", &p->ki_first},
    };
    size_t n = p->law == PPID_LAW_OPEN_LOOP ? 5 : PPID_PARAM_COUNT;
    memcpy(refs, table, n * sizeof table[0]);
    return n;
}

bool ppid_law_parse(const char *text, ppid_law_t *out)
{
    if (param_name_equal(text, "physical")) {
        *out = PPID_LAW_PHYSICAL;
    } else if (param_name_equal(text, "paper-literal") || param_name_equal(text, "paper_literal")) {
        *out = PPID_LAW_PAPER_LITERAL;
    } else if (param_name_equal(text, "open-loop") || param_name_equal(text, "open_loop")) {
        *out = PPID_LAW_OPEN_LOOP;
    } else {
        return false;
    }
    return true;
}

const char *ppid_law_name(ppid_law_t law)
{
    switch (law) {
    case PPID_LAW_PAPER_LITERAL:
        return "paper-literal";
    case PPID_LAW_OPEN_LOOP:
        return "open-loop";
    case PPID_LAW_PHYSICAL:
    default:
        return "physical";
    }
}

void ppid_reset(ppid_state_t *s)
{
    memset(s, 0, sizeof *s);
}

double ppid_feedforward(const ppid_params_t *p, double target_gps)
{
    if (!(target_gps > 0.0)) {
        return 0.0;
    }
    double shaft_rpm = pow(target_gps / p->ff_coeff, 1.0 / p->ff_exponent);
    if (shaft_rpm < p->ff_linear_below_rpm) {
        double q_knee = p->ff_coeff * pow(p->ff_linear_below_rpm, p->ff_exponent);
        shaft_rpm = target_gps / q_knee * p->ff_linear_below_rpm;
    }
    return clamp(shaft_rpm / p->shaft_rpm_per_v, 0.0, p->v_max);
}

/* Segment of |err| against e1, e2 and its gains. */
static uint8_t select_segment(const ppid_params_t *p, double abs_err, double *kp, double *ki)
{
    if (abs_err < p->e1) {
        *kp = p->kp1;
        *ki = p->ki1;
        return PPID_SEG_FINE;
    }
    if (abs_err < p->e2) {
        *kp = p->kp2;
        *ki = p->ki2;
        return PPID_SEG_MEDIUM;
    }
    *kp = p->kp3;
    *ki = 0.0;
    return PPID_SEG_COARSE;
}

static void update_paper_literal(const ppid_params_t *p, ppid_state_t *s, double e)
{
    if (!s->primed) {
        s->e_prev = e;
        s->e_prev2 = e;
        s->primed = true;
    }
    double kp, ki;
    s->segment = select_segment(p, fabs(e), &kp, &ki);
    double du = kp * (e - s->e_prev) + ki * e + p->kd * (e - 2.0 * s->e_prev + s->e_prev2);
    s->u = clamp(s->u + du, 0.0, p->v_max / p->km);
    s->e_prev2 = s->e_prev;
    s->e_prev = e;
}

/* No integration towards a limit the command already sits at (anti-windup). */
static void update_physical(const ppid_params_t *p, ppid_state_t *s, double r, bool saturated)
{
    if (!s->primed) {
        s->r_prev = r;
        s->primed = true;
    }
    double kp, ki;
    s->segment = select_segment(p, fabs(r), &kp, &ki);
    if (!(saturated && r > 0.0)) {
        if (!s->learnt) { /* the first clean report: learn the meter factor */
            ki = p->ki_first;
        }
        s->integral = clamp(s->integral + ki * r, -p->c_max, p->c_max);
        s->learnt = true;
    }
    s->correction = clamp(kp * r + s->integral + p->kd * (r - s->r_prev), -p->c_max, p->c_max);
    s->r_prev = r;
}

ppid_output_t ppid_step(const ppid_params_t *p, ppid_state_t *s, double target_gps,
                        double measured_gps, bool has_measurement, bool new_report)
{
    ppid_output_t out = {0.0, PPID_SEG_NONE};
    if (!(target_gps > 0.0)) {
        ppid_reset(s);
        return out;
    }
    bool update = new_report && has_measurement;
    switch (p->law) {
    case PPID_LAW_OPEN_LOOP:
        out.volts = ppid_feedforward(p, target_gps);
        return out;
    case PPID_LAW_PAPER_LITERAL:
        if (update) {
            update_paper_literal(p, s, target_gps - measured_gps);
        }
        out.volts = p->km * s->u;
        break;
    case PPID_LAW_PHYSICAL:
    default: {
        if (fabs(target_gps - s->target_prev) > p->e2 * s->target_prev) {
            /* a jump (also the first step after a reset): the sensors' windows still hold the
             * old flow; keep only the integral (P and D were about the old target) and wait */
            s->since_jump = 0;
            s->primed = false;
            s->correction = s->integral;
        } else if (s->since_jump < UINT32_MAX) {
            s->since_jump++;
        }
        s->target_prev = target_gps;
        double ff = ppid_feedforward(p, target_gps);
        if (update && (double)s->since_jump >= p->settle_periods) {
            update_physical(p, s, (target_gps - measured_gps) / target_gps,
                            ff * (1.0 + s->correction) >= p->v_max);
        }
        out.volts = clamp(ff * (1.0 + s->correction), 0.0, p->v_max);
        break;
    }
    }
    out.segment = s->segment;
    return out;
}
