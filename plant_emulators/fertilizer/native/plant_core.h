/* C twin of plant_emulators.fertilizer.physics.FertilizerPlant's step loop.
 *
 * Drive (speed-reference ramp, PI speed loop, current and voltage limits, I2t derating,
 * linearly implicit Euler mechanics with the friction impulse), meter (flow map, hopper level,
 * density wander, flute pulsation and charges) and transport (dispersion, delay line to the
 * sensor and the tube exit, accumulators), one step at a time.
 *
 * Every expression is the Python model's, in the same order, compiled without contraction or
 * reassociation (-ffp-contract=off, no -ffast-math) and with sin/cos/pow/sqrt from the same
 * libm, so a step gives the same doubles as the Python loop: tests compare the two bit for
 * bit. The constants are computed once, in Python, and handed over (pc_bind).
 *
 * Memory: pc_init allocates the per-row arrays and the delay lines once (rows and the delay
 * lengths are fixed for a plant's life); stepping allocates nothing.
 */
#ifndef AGRIHIL_PLANT_CORE_H
#define AGRIHIL_PLANT_CORE_H

#include <stddef.h>

#include "../../native/normal_block.h"

/* Drive constants, in physics._DriveConstants' order. */
typedef struct {
    double ke, kt, ra, inv_j, kp, ki_dt, vs, i_peak, i_cont, i_cont2, budget, ramp, bl;
    double den_emf, dwf_emf, den_lim, dwf_lim, den_pi, dwf_pi;
} PcDrive;

/* Meter constants, in physics._MeterConstants' order. */
typedef struct {
    double shaft_rpm_per_w, rev_per_w_step, coeff, expo, knee, lin_slope, flutes;
    double two_pi_flutes, a1, a2, inv_cap, lsens, starve, starve_level, inv_starve;
    long slow_steps;
    double ou_a, ou_b;
} PcMeter;

typedef struct {
    /* fixed at init */
    int rows;
    double charge_sd;          /* meter.flute_charge_sd_frac */
    double dens_base;          /* 1 + density_offset_frac */
    double *gain, *charge, *cos_off, *sin_off, *offsets;
    long *flute_index;
    NormalBlock *z;
    /* bound with the step size */
    int bound;
    double dt, alpha;
    long to_sensor, to_exit, line_len;
    PcDrive d;
    PcMeter m;
    /* drive and meter state */
    double w, w_ref, xi, cur, i2t;
    int derated;
    double rev, hopper, wander;
    long countdown;
    double flute_lo, flute_hi, n_map, q_map;
    /* transport: per row the sums over steps (x dt = grams) and the dispersion output */
    double *metered, *disp, *passed, *delivered;
    double *flow_at_meter, *flow_at_sensor;
    double *lines;             /* rows x line_len ring buffers of the dispersion output */
    long line_pos;             /* next slot written (the same for every row) */
} PlantCore;

/* Allocate the per-row arrays; draws each row's first flute charge from z (as the Python
 * constructor does). Returns 0, or -1 (out of memory, or z failed: see z->failed). */
int pc_init(PlantCore *pc, int rows, double charge_sd, double dens_base, const double *gain,
            const double *offsets, const double *cos_off, const double *sin_off,
            double hopper_g, double density_wander, NormalBlock *z);

/* Bind the step size: constants and delay lengths (each >= 1 step); allocates the delay
 * lines. 0, or -1 when a delay is < 1, the lines' size overflows or memory runs out. */
int pc_bind(PlantCore *pc, double dt, const PcDrive *drive, const PcMeter *meter,
            double alpha, long to_sensor, long to_exit);

/* n steps with the inputs held (w_target: speed reference target, rad/s; dens_base:
 * 1 + the density offset, read per call as the Python loop does). 0, or -1 when a
 * normal-variate refill failed (z->failed; the state is then mid-step). */
int pc_advance(PlantCore *pc, long long n, double w_target, int stalled, double dens_base);

void pc_free(PlantCore *pc);

#endif
