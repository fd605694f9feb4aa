/* C twin of FertilizerPlant's step loop; see plant_core.h. Comments name the Python lines
 * each block mirrors: keep the two in step (the equivalence tests will say when they are
 * not). */
#include "plant_core.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* physics._FLUTE_GUARD */
#define FLUTE_GUARD 1e-12

/* physics._flute_window: the open interval of flutes x revolutions in which no row changes
 * flute. */
static void flute_window(const PlantCore *pc, double *lo_out, double *hi_out)
{
    double lo = -INFINITY, hi = INFINITY;
    for (int r = 0; r < pc->rows; ++r) {
        long k = pc->flute_index[r];
        double off = pc->offsets[r];
        long a, b;
        if (k >= 1) {
            a = k;
            b = k + 1;
        } else if (k == 0) {
            a = -1;
            b = 1;
        } else {
            a = k - 1;
            b = k;
        }
        double margin = FLUTE_GUARD * (double)(labs(k) + 2);
        double x = (double)a - off + margin;
        if (x > lo) {            /* max(lo, x) */
            lo = x;
        }
        double y = (double)b - off - margin;
        if (y < hi) {            /* min(hi, y) */
            hi = y;
        }
    }
    *lo_out = lo;
    *hi_out = hi;
}

/* FertilizerPlant._draw_charge / the redraw in _next_flutes */
static double draw_charge(PlantCore *pc)
{
    double ch = 1.0 + pc->charge_sd * nb_next(pc->z);
    return ch > 0.0 ? ch : 0.0;
}

/* FertilizerPlant._next_flutes */
static void next_flutes(PlantCore *pc, double fpos)
{
    for (int r = 0; r < pc->rows; ++r) {
        long k = (long)(fpos + pc->offsets[r]);       /* int() truncates toward zero */
        if (k != pc->flute_index[r]) {
            pc->flute_index[r] = k;
            pc->charge[r] = draw_charge(pc);
        }
    }
    flute_window(pc, &pc->flute_lo, &pc->flute_hi);
}

static void *zalloc(size_t n, size_t size)
{
    return calloc(n == 0 ? 1 : n, size);
}

int pc_init(PlantCore *pc, int rows, double charge_sd, double dens_base, const double *gain,
            const double *offsets, const double *cos_off, const double *sin_off,
            double hopper_g, double density_wander, NormalBlock *z)
{
    memset(pc, 0, sizeof *pc);
    pc->rows = rows;
    pc->charge_sd = charge_sd;
    pc->dens_base = dens_base;
    pc->z = z;
    size_t n = (size_t)rows;
    double **arrays[] = {&pc->gain, &pc->charge, &pc->cos_off, &pc->sin_off, &pc->offsets,
                         &pc->metered, &pc->disp, &pc->passed, &pc->delivered,
                         &pc->flow_at_meter, &pc->flow_at_sensor};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; ++i) {
        *arrays[i] = zalloc(n, sizeof(double));
        if (*arrays[i] == NULL) {
            pc_free(pc);
            return -1;
        }
    }
    pc->flute_index = zalloc(n, sizeof(long));
    if (pc->flute_index == NULL) {
        pc_free(pc);
        return -1;
    }
    for (int r = 0; r < rows; ++r) {
        pc->gain[r] = gain[r];
        pc->offsets[r] = offsets[r];
        pc->cos_off[r] = cos_off[r];
        pc->sin_off[r] = sin_off[r];
        pc->flute_index[r] = (long)offsets[r];
    }
    for (int r = 0; r < rows; ++r) {
        pc->charge[r] = draw_charge(pc);
        if (z->failed) {
            pc_free(pc);
            return -1;
        }
    }
    pc->hopper = hopper_g;
    pc->wander = density_wander;
    flute_window(pc, &pc->flute_lo, &pc->flute_hi);
    return 0;
}

int pc_bind(PlantCore *pc, double dt, const PcDrive *drive, const PcMeter *meter,
            double alpha, long to_sensor, long to_exit)
{
    if (to_sensor < 1 || to_exit < 1 || to_exit > LONG_MAX - to_sensor
        || (size_t)(to_sensor + to_exit) > SIZE_MAX / sizeof(double) / (size_t)pc->rows) {
        return -1;
    }
    pc->line_len = to_sensor + to_exit;
    pc->lines = zalloc((size_t)pc->rows * (size_t)pc->line_len, sizeof(double));
    if (pc->lines == NULL) {
        return -1;
    }
    pc->dt = dt;
    pc->d = *drive;
    pc->m = *meter;
    pc->alpha = alpha;
    pc->to_sensor = to_sensor;
    pc->to_exit = to_exit;
    pc->line_pos = 0;
    pc->bound = 1;
    return 0;
}

int pc_advance(PlantCore *pc, long long n, double w_target, int stalled, double dens_base_now)
{
    pc->dens_base = dens_base_now;
    const PcDrive d = pc->d;
    const PcMeter m = pc->m;
    const double dt = pc->dt;
    const int rows = pc->rows;
    const double dens_base = pc->dens_base;
    const double alpha = pc->alpha;
    const long line_len = pc->line_len, to_exit = pc->to_exit;
    NormalBlock *z = pc->z;

    double w = pc->w, w_ref = pc->w_ref, xi = pc->xi, cur = pc->cur;
    double i2t = pc->i2t;
    int derated = pc->derated;
    double i_lim = derated ? d.i_cont : d.i_peak;
    double rev = pc->rev, hopper = pc->hopper;
    double wander = pc->wander;
    double density = dens_base + wander;
    long countdown = pc->countdown;
    double n_map = pc->n_map, q_map = pc->q_map;
    long pos = pc->line_pos;
    double den = 0.0, dwf = 0.0;

    for (long long step = 0; step < n; ++step) {
        /* ---- slow processes */
        if (countdown <= 0) {
            countdown = m.slow_steps;
            wander = m.ou_a * wander + m.ou_b * nb_next(z);
            if (z->failed) {
                return -1;
            }
            density = dens_base + wander;
        }
        countdown -= 1;

        /* ---- speed reference ramp */
        if (w_ref < w_target) {
            w_ref += d.ramp;
            if (w_ref > w_target) {
                w_ref = w_target;
            }
        } else if (w_ref > w_target) {
            w_ref -= d.ramp;
            if (w_ref < w_target) {
                w_ref = w_target;
            }
        }
        if (stalled) {
            w = 0.0;
        }

        /* ---- current: PI, current limit, voltage limit */
        double err = w_ref - w;
        double i_cmd = d.kp * err + xi;
        double back_emf = d.ke * w;
        double i_hi = (d.vs - back_emf) / d.ra;
        if (i_cmd > i_hi || i_cmd > i_lim) {
            if (i_hi < i_lim) {
                cur = i_hi;
                den = d.den_emf;
                dwf = d.dwf_emf;
            } else {
                cur = i_lim;
                den = d.den_lim;
                dwf = d.dwf_lim;
            }
            if (err < 0.0) {
                xi += d.ki_dt * err;
            }
        } else {
            double i_lo = (-d.vs - back_emf) / d.ra;
            if (i_cmd < i_lo || i_cmd < -i_lim) {
                if (i_lo > -i_lim) {
                    cur = i_lo;
                    den = d.den_emf;
                    dwf = d.dwf_emf;
                } else {
                    cur = -i_lim;
                    den = d.den_lim;
                    dwf = d.dwf_lim;
                }
                if (err > 0.0) {
                    xi += d.ki_dt * err;
                }
            } else {
                cur = i_cmd;
                den = d.den_pi;
                dwf = d.dwf_pi;
                xi += d.ki_dt * err;
            }
        }

        /* ---- mechanics */
        if (!stalled) {
            double w_free = w + dt * (d.kt * cur - d.bl * w) * d.inv_j / den;
            if (w_free > dwf) {
                w = w_free - dwf;
            } else if (w_free < -dwf) {
                w = w_free + dwf;
            } else {
                w = 0.0;
            }
        }

        /* ---- I2t protection */
        i2t += (cur * cur - d.i_cont2) * dt;
        if (i2t <= 0.0) {
            i2t = 0.0;
            derated = 0;
            i_lim = d.i_peak;
        } else if (i2t >= d.budget) {
            derated = 1;
            i_lim = d.i_cont;
        }

        /* ---- meter */
        double n_shaft = w * m.shaft_rpm_per_w;
        rev += w * m.rev_per_w_step;
        if (n_shaft != n_map) {
            n_map = n_shaft;
            if (n_shaft >= m.knee) {
                q_map = m.coeff * pow(n_shaft, m.expo);
            } else if (n_shaft > 0.0) {
                q_map = m.lin_slope * n_shaft;
            } else {
                q_map = 0.0;
            }
        }
        double fill = hopper * m.inv_cap;
        double level;
        if (fill >= m.starve) {
            level = 1.0 - m.lsens * (1.0 - fill);
        } else if (fill > 0.0) {
            level = sqrt(fill * m.inv_starve) * m.starve_level;
        } else {
            level = 0.0;
        }
        double q0 = q_map * (density * level);
        double fpos = m.flutes * rev;
        if (!(pc->flute_lo < fpos && fpos < pc->flute_hi)) {
            next_flutes(pc, fpos);
            if (z->failed) {
                return -1;
            }
        }
        double theta = m.two_pi_flutes * rev;
        double c1 = cos(theta);
        double s1 = sin(theta);
        double q_total = 0.0;
        /* ---- transport (physics._transport, one step of every row): the value written
         * line_len steps ago leaves the tube, the one written to_sensor steps ago passes
         * the sensor */
        long sens = pos + to_exit;
        if (sens >= line_len) {
            sens -= line_len;
        }
        for (int r = 0; r < rows; ++r) {
            double c = c1 * pc->cos_off[r] - s1 * pc->sin_off[r];
            double q = q0 * pc->gain[r] * pc->charge[r]
                       * (1.0 + m.a1 * c + m.a2 * (2.0 * c * c - 1.0));
            q_total += q;
            double *line = pc->lines + (size_t)r * (size_t)line_len;
            double q_exit = line[pos];
            double q_sens = line[sens];
            double y = pc->disp[r];
            pc->metered[r] += q;
            y += alpha * (q - y);
            pc->disp[r] = y;
            line[pos] = y;
            pc->passed[r] += q_sens;
            pc->delivered[r] += q_exit;
            pc->flow_at_meter[r] = q;
            pc->flow_at_sensor[r] = q_sens;
        }
        if (++pos == line_len) {
            pos = 0;
        }
        hopper -= q_total * dt;
    }

    pc->w = w;
    pc->w_ref = w_ref;
    pc->xi = xi;
    pc->cur = cur;
    pc->i2t = i2t;
    pc->derated = derated;
    pc->rev = rev;
    pc->hopper = hopper;
    pc->wander = wander;
    pc->countdown = countdown;
    pc->n_map = n_map;
    pc->q_map = q_map;
    pc->line_pos = pos;
    return 0;
}

void pc_free(PlantCore *pc)
{
    double **arrays[] = {&pc->gain, &pc->charge, &pc->cos_off, &pc->sin_off, &pc->offsets,
                         &pc->metered, &pc->disp, &pc->passed, &pc->delivered,
                         &pc->flow_at_meter, &pc->flow_at_sensor, &pc->lines};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; ++i) {
        free(*arrays[i]);
        *arrays[i] = NULL;
    }
    free(pc->flute_index);
    pc->flute_index = NULL;
}
