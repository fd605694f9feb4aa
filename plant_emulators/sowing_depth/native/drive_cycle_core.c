/* C twin of the depth drive's profile-velocity loop (see drive_cycle_core.h): each function
 * is the Python method it names, expression for expression. */
#include "drive_cycle_core.h"

#include <math.h>

/* Cia402Drive._clamp_v */
static double clamp_v(const DcDrive *d, double v)
{
    if (v > d->vmax) {
        return d->vmax;
    }
    if (v < -d->vmax) {
        return -d->vmax;
    }
    return v;
}

/* MotionProfile.velocity_step (its position sum is overwritten by _pv_cycle: left out) */
static void velocity_step(DcDrive *d, double dt, double v_target)
{
    double v = d->prof_velocity;
    double dv = v_target - v;
    if (dv != 0.0) {
        double rate = v * dv >= 0.0 ? d->accel : d->decel;
        double step = rate * dt;
        if (dv > step) {
            v += step;
        } else if (dv < -step) {
            v -= step;
        } else {
            v = v_target;
        }
        d->prof_velocity = v;
    }
}

/* Cia402Drive._pv_cycle */
static double pv_cycle(DcDrive *d, const DcCylinder *c, double dt)
{
    double target = d->target;
    int limited = 0;
    double x = c->position_mm;
    if (target > 0.0) {
        double room = d->lim_max - x;
        double v_allow = room > 0.0 ? sqrt(2.0 * d->decel * room) : 0.0;
        if (target > v_allow) {
            target = v_allow;
            limited = 1;
        }
    } else if (target < 0.0) {
        double room = x - d->lim_min;
        double v_allow = room > 0.0 ? sqrt(2.0 * d->decel * room) : 0.0;
        if (-target > v_allow) {
            target = -v_allow;
            limited = 1;
        }
    }
    d->internal_limit = limited;
    velocity_step(d, dt, target);
    d->prof_position = x;
    return d->prof_velocity;
}

/* ServoCylinder.step, not jammed */
static void cylinder_step(DcCylinder *c, double dt, double v_cmd_mm_s)
{
    double v = c->velocity_mm_s;
    double x = c->position_mm;
    double pen = x - c->load_contact_mm;
    double f_load;
    if (pen > 0.0) {
        f_load = c->load_stiffness_n_per_mm * pen + c->load_damping_n_s_per_mm * v
                 - c->load_preload_n;
    } else {
        f_load = -c->load_preload_n;
    }
    double m_eff = c->m_eff_kg;
    double k_f = c->k_force_n_per_n_m;
    double torque = (m_eff * (v_cmd_mm_s - v) * c->k_vel * 1e-3 + f_load) / k_f;
    double limit = c->torque_limit_n_m;
    if (torque * v > 0.0) {
        double volt_limit = c->kt_n_m_per_a
                            * (c->dc_bus_voltage_v - c->ke_v_s_per_rad * fabs(v) * c->rad_per_mm)
                            / c->ra_ohm;
        if (volt_limit < limit) {
            limit = volt_limit > 0.0 ? volt_limit : 0.0;
        }
    }
    int saturated = 0;
    if (torque > limit) {
        torque = limit;
        saturated = 1;
    } else if (torque < -limit) {
        torque = -limit;
        saturated = 1;
    }
    double force = torque * k_f;
    double v_new = v + (force - f_load) / m_eff * 1e3 * dt;
    double vmax = c->rod_speed_max_mm_per_s;
    if (v_new > vmax) {
        v_new = vmax;
    } else if (v_new < -vmax) {
        v_new = -vmax;
    }
    double x_new = x + 0.5 * (v + v_new) * dt;
    if (x_new <= 0.0) {
        x_new = 0.0;
        v_new = 0.0;
    } else if (x_new >= c->stroke_mm) {
        x_new = c->stroke_mm;
        v_new = 0.0;
    }
    c->position_mm = x_new;
    c->velocity_mm_s = v_new;
    c->torque_n_m = torque;
    c->current_a = torque / c->kt_n_m_per_a;
    c->force_n = force;
    c->at_force_limit = saturated;
}

/* Cia402Drive._monitor_velocity (the drive stays OPERATION ENABLED within a call) */
static void monitor_velocity(DcDrive *d, const DcCylinder *c, double dt)
{
    double v = c->velocity_mm_s;
    double target = d->target;
    if (fabs(target - v) <= d->vel_window) {
        d->window_time_s += dt;
        d->target_reached = d->window_time_s >= d->vel_window_s;
    } else {
        d->window_time_s = 0.0;
        d->target_reached = 0;
    }
    if (fabs(v) <= d->vel_threshold) {
        d->threshold_time_s += dt;
        d->speed_zero = d->threshold_time_s >= d->vel_threshold_s;
    } else {
        d->threshold_time_s = 0.0;
        d->speed_zero = 0;
    }
}

/* Cia402Drive._monitor_overload without the fault itself: 1 when it must be raised */
static int monitor_overload(DcDrive *d, const DcCylinder *c, double dt)
{
    if (c->at_force_limit) {
        d->overload_s += dt;
        return d->overload_s >= d->overload_limit_s;
    }
    if (d->overload_s > 0.0) {
        double left = d->overload_s - dt;
        d->overload_s = left > 0.0 ? left : 0.0;    /* max(0.0, left) */
    }
    return 0;
}

long long dc_run(DcDrive *d, DcCylinder *c, long long n, double dt, double dx, double *t,
                 double *x, double next_cell, int *why)
{
    double tt = *t;
    double xx = *x;
    long long k = 0;
    *why = 0;
    while (k < n) {
        cylinder_step(c, dt, clamp_v(d, pv_cycle(d, c, dt)));
        monitor_velocity(d, c, dt);
        int flags = monitor_overload(d, c, dt) ? DC_OVERLOAD : 0;
        tt += dt;
        xx += dx;
        ++k;
        if (xx >= next_cell) {
            flags |= DC_CELL;
        }
        if (flags) {
            *why = flags;
            break;
        }
    }
    *t = tt;
    *x = xx;
    return k;
}
