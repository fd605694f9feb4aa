#include "roller_hold.h"

#include <math.h>
#include <string.h>

void rhold_defaults(rhold_params_t *p)
{
    p->time_constant_s = 2.0; /* 0.5-1 Hz excursions through 1/sqrt(1+(2 pi f tau)^2): 8-16 % */
    p->gain_per_s = 5.0;      /* kT = 0.05 <= 0.25 with a one-SYNC-old position: no overshoot */
    p->speed_mm_s = 10.0;     /* k v_hold = 50 mm/s^2 < 250 mm/s^2 profile deceleration */
}

int rhold_check(const rhold_params_t *p, const char **err)
{
    if (!(p->time_constant_s > 0.0)) {
        *err = "hold_time_constant_s must be > 0";
        return -1;
    }
    if (!(p->gain_per_s >= 0.0)) {
        *err = "hold_gain_per_s must be >= 0";
        return -1;
    }
    if (!(p->speed_mm_s >= 0.0)) {
        *err = "hold_speed_mm_s must be >= 0";
        return -1;
    }
    return 0;
}

void rhold_reset(rhold_state_t *s)
{
    memset(s, 0, sizeof *s);
}

void rhold_mark(rhold_state_t *s)
{
    s->has_target = s->has_mean;
    s->target_mm = s->mean_mm;
}

void rhold_track(const rhold_params_t *p, rhold_state_t *s, double position_mm,
                 double period_s)
{
    if (!s->has_mean) {
        s->mean_mm = position_mm;
        s->has_mean = true;
        return;
    }
    double alpha = fmin(1.0, period_s / p->time_constant_s);
    s->mean_mm = s->mean_mm + alpha * (position_mm - s->mean_mm);
}

double rhold_speed(const rhold_params_t *p, const rhold_state_t *s, double position_mm)
{
    if (!s->has_target) {
        return 0.0;
    }
    return fmin(fmax(p->gain_per_s * (s->target_mm - position_mm), -p->speed_mm_s),
                p->speed_mm_s);
}
