/* C twin of the sowing-depth drive's inner loop in profile velocity mode: per physics step
 * Cia402Drive._pv_cycle, ServoCylinder.step, Cia402Drive._monitor_velocity and
 * _monitor_overload, then SowingDepthPlant.advance's time and distance sums.
 *
 * Only the steady case is here: the drive in OPERATION ENABLED, mode 3 (profile velocity),
 * the rod not jammed. Everything that changes the drive's state (a fault, a controlword, a
 * truth cell, which sets the soil spring under the roller) happens between calls, in Python:
 * dc_run stops after the step in which the overload monitor faults or the seed point reaches
 * the next truth cell, and says which.
 *
 * Every expression is the Python model's, in the same order, compiled without contraction or
 * reassociation (-ffp-contract=off, no -ffast-math), so a step gives the same doubles as the
 * Python loop: tests compare the two bit for bit. No allocation.
 */
#ifndef AGRIHIL_DRIVE_CYCLE_CORE_H
#define AGRIHIL_DRIVE_CYCLE_CORE_H

/* The cylinder (ServoCylinder's attributes of the same names). */
typedef struct {
    double position_mm, velocity_mm_s;                       /* state */
    double torque_n_m, current_a, force_n;                   /* outputs of the last step */
    int at_force_limit;
    double load_contact_mm, load_stiffness_n_per_mm, load_damping_n_s_per_mm,
        load_preload_n;                                      /* the soil, set per cell */
    double m_eff_kg, k_force_n_per_n_m, k_vel, torque_limit_n_m, kt_n_m_per_a,
        dc_bus_voltage_v, ke_v_s_per_rad, rad_per_mm, ra_ohm, rod_speed_max_mm_per_s,
        stroke_mm;                                           /* constants (k_vel: _k_vel) */
} DcCylinder;

/* The drive (Cia402Drive's attributes without their leading underscore). */
typedef struct {
    double target;          /* 0x60FF in mm/s, clamped to vmax (0 when halted) */
    double lim_min, lim_max, accel, decel, vmax;
    double vel_window, vel_window_s, vel_threshold, vel_threshold_s, overload_limit_s;
    double prof_velocity, prof_position;                    /* the motion profile */
    double window_time_s, threshold_time_s, overload_s;     /* monitoring */
    int internal_limit, target_reached, speed_zero;
} DcDrive;

/* Why dc_run stopped (besides running all n steps): bit flags. */
#define DC_CELL 1          /* the seed point reached the next truth cell (x >= next cell) */
#define DC_OVERLOAD 2      /* the overload monitor reached 0x2002: the drive faults (0x2310) */

/* Run up to n steps of dt; *t and *x advance by dt and dx per step as in advance(). Returns
 * the number of steps run; *why gets the DC_ flags of the last step (0: all n ran). */
long long dc_run(DcDrive *d, DcCylinder *c, long long n, double dt, double dx, double *t,
                 double *x, double next_cell, int *why);

#endif
