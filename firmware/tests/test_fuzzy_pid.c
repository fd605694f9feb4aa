/* Fuzzy self-tuning PID core: hand-computed cases (docs/reference-controllers.md section 2). */
#include "check.h"
#include "fuzzy_pid.h"

#define TOL 1e-12

static void test_defaults(void)
{
    fpid_params_t p;
    fpid_defaults(&p);
    CHECK_NEAR(p.ke, 0.03, 0);
    CHECK_NEAR(p.kec, 0.12, 0);
    CHECK_NEAR(p.kp_scale, 0.30, 0);
    CHECK_NEAR(p.ki_scale, 0.02, 0);
    CHECK_NEAR(p.kd_scale, 0.50, 0);
    CHECK_NEAR(p.v_max, 50.0, 0);
    CHECK_NEAR(p.period_s, 0.01, 0);
}

static void test_fuzzy_at_zero(void)
{
    /* only rule (ZE, ZE) fires: dKp = ZE, dKi = ZE (centroid 0), dKd = NS (centroid -1) */
    fpid_fuzzy_t f = fpid_fuzzy(0.0, 0.0);
    CHECK_NEAR(f.up, 0.0, TOL);
    CHECK_NEAR(f.ui, 0.0, TOL);
    CHECK_NEAR(f.ud, -1.0, TOL);
}

static void test_fuzzy_two_rules(void)
{
    /* E = 1: ZE 0.5, PS 0.5; EC = 0: ZE 1. Kp: ZE and NS clipped at 0.5, symmetric about
     * -0.5; Ki: ZE and PS about 0.5; Kd: NS and ZE about -0.5 */
    fpid_fuzzy_t f = fpid_fuzzy(1.0, 0.0);
    CHECK_NEAR(f.up, -0.5, TOL);
    CHECK_NEAR(f.ui, 0.5, TOL);
    CHECK_NEAR(f.ud, -0.5, TOL);
}

static void test_fuzzy_corner_and_clamp(void)
{
    /* E = EC = 6: one rule (PB, PB) at weight 1: Kp NB, Ki PB, Kd PB. The centroid of a full
     * edge triangle on the grid: sum (-3 + 0.1 k)(1 - 0.1 k) / sum (1 - 0.1 k) = -14.85 / 5.5 */
    fpid_fuzzy_t f = fpid_fuzzy(6.0, 6.0);
    CHECK_NEAR(f.up, -2.7, TOL);
    CHECK_NEAR(f.ui, 2.7, TOL);
    CHECK_NEAR(f.ud, 2.7, TOL);
    fpid_fuzzy_t g = fpid_fuzzy(250.0, 1e9); /* inputs clamp to the universe */
    CHECK_NEAR(g.up, f.up, 0);
    CHECK_NEAR(g.ui, f.ui, 0);
    CHECK_NEAR(g.ud, f.ud, 0);
    /* E = -6, EC = 6: (NB, PB): Kp ZE, Ki ZE, Kd PS */
    f = fpid_fuzzy(-6.0, 6.0);
    CHECK_NEAR(f.up, 0.0, TOL);
    CHECK_NEAR(f.ui, 0.0, TOL);
    CHECK_NEAR(f.ud, 1.0, TOL);
}

static void test_fuzzy_symmetry(void)
{
    /* the tables' ZE row (E = 0) is odd in ec for dKp and dKi and even for dKd; the ZE column
     * (EC = 0) is odd in e for dKi. With only that row or column firing, mirrored inputs give
     * mirrored outputs. (The full tables are not odd: no symmetry off these lines.) */
    const double pts[] = {0.0, 0.25, 0.9, 1.0, 1.7, 2.0, 3.3, 4.0, 5.5, 6.0, 9.0};
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        double x = pts[i];
        fpid_fuzzy_t a = fpid_fuzzy(0.0, x);
        fpid_fuzzy_t b = fpid_fuzzy(0.0, -x);
        CHECK_NEAR(a.up, -b.up, 1e-12);
        CHECK_NEAR(a.ui, -b.ui, 1e-12);
        CHECK_NEAR(a.ud, b.ud, 1e-12);
        fpid_fuzzy_t c = fpid_fuzzy(x, 0.0);
        fpid_fuzzy_t d = fpid_fuzzy(-x, 0.0);
        CHECK_NEAR(c.ui, -d.ui, 1e-12);
        CHECK(a.up >= -3.0 && a.up <= 3.0 && c.ud >= -3.0 && c.ud <= 3.0);
    }
    /* the ZE row: EC = 2 fires (ZE, PS) alone: dKp NS, dKi PS, dKd NS */
    fpid_fuzzy_t f = fpid_fuzzy(0.0, 2.0);
    CHECK_NEAR(f.up, -1.0, TOL);
    CHECK_NEAR(f.ui, 1.0, TOL);
    CHECK_NEAR(f.ud, -1.0, TOL);
}

/* fuzzy layer held at E = EC = 0 (ke = kec = 0): Kp = kp0, Ki = ki0, Kd = kd0 - 0.5 */
static fpid_params_t flat(void)
{
    fpid_params_t p;
    fpid_defaults(&p);
    p.kp0 = 1.0;
    p.ki0 = 0.5;
    p.kd0 = 1.0;
    p.ke = 0.0;
    p.kec = 0.0;
    return p;
}

static void check_out(fpid_output_t o, double speed, double kp, double ki, double kd)
{
    CHECK_NEAR(o.speed_mm_s, speed, 1e-9);
    CHECK_NEAR(o.kp, kp, TOL);
    CHECK_NEAR(o.ki, ki, TOL);
    CHECK_NEAR(o.kd, kd, TOL);
}

static void test_step_sequence(void)
{
    fpid_params_t p = flat();
    fpid_state_t s;
    fpid_reset(&s);
    /* e = 10, ec = 0 (first step): u = 10; I = 0.1 */
    check_out(fpid_step(&p, &s, 30.0, 20.0, true, true), 10.0, 1.0, 0.5, 0.5);
    /* e = 9, ec = -100: u = 9 + 0.05 - 50; I = 0.19 */
    check_out(fpid_step(&p, &s, 30.0, 21.0, true, true), -40.95, 1.0, 0.5, 0.5);
    CHECK_NEAR(s.integral, 0.19, TOL);
    /* e = 80, ec = 7100: saturated +50 with e > 0: I frozen */
    check_out(fpid_step(&p, &s, 30.0, -50.0, true, true), 50.0, 1.0, 0.5, 0.5);
    CHECK_NEAR(s.integral, 0.19, TOL);
    /* e = -70: saturated -50 with e < 0: frozen */
    check_out(fpid_step(&p, &s, 30.0, 100.0, true, true), -50.0, 1.0, 0.5, 0.5);
    CHECK_NEAR(s.integral, 0.19, TOL);
    /* e = 80 again (ec > 0), then e = 1 with ec = -7900: saturated -50 against e > 0:
     * integrates, I = 0.2 */
    fpid_step(&p, &s, 30.0, -50.0, true, true);
    check_out(fpid_step(&p, &s, 30.0, 29.0, true, true), -50.0, 1.0, 0.5, 0.5);
    CHECK_NEAR(s.integral, 0.2, TOL);
    /* not valid: reset, speed 0, preset gains */
    check_out(fpid_step(&p, &s, 30.0, 29.0, false, true), 0.0, 1.0, 0.5, 1.0);
    CHECK_NEAR(s.integral, 0.0, 0);
    CHECK(!s.has_prev);
    /* e = 0 on the first step after the reset: 0 */
    check_out(fpid_step(&p, &s, 30.0, 30.0, true, true), 0.0, 1.0, 0.5, 0.5);
    /* e = 0.1, ec = 10: u = 0.1 + 0.5 * 10 */
    check_out(fpid_step(&p, &s, 30.0, 29.9, true, true), 5.1, 1.0, 0.5, 0.5);
    /* not enabled: reset as well */
    check_out(fpid_step(&p, &s, 30.0, 29.9, true, false), 0.0, 1.0, 0.5, 1.0);
}

static void test_gains_never_negative(void)
{
    fpid_params_t p;
    fpid_defaults(&p);
    p.kp0 = 0.1; /* Kp = max(0, 0.1 + 0.3 Up): Up = -2.7 at E = EC = 6 */
    p.ki0 = 0.0;
    p.kd0 = 0.0;
    fpid_state_t s;
    fpid_reset(&s);
    fpid_output_t o = fpid_step(&p, &s, 300.0, 0.0, true, true); /* E = 9 -> 6, EC = 0 */
    CHECK(o.kp >= 0.0 && o.ki >= 0.0 && o.kd >= 0.0);
    /* E = 6, EC = 0: rule (PB, ZE): Kp NM (centroid -2), Ki PM (2), Kd PM (2) */
    CHECK_NEAR(o.kp, 0.0, 0);
    CHECK_NEAR(o.ki, 0.04, TOL);
    CHECK_NEAR(o.kd, 1.0, TOL);
}

TEST_MAIN("fuzzy_pid", test_defaults, test_fuzzy_at_zero, test_fuzzy_two_rules,
          test_fuzzy_corner_and_clamp, test_fuzzy_symmetry, test_step_sequence,
          test_gains_never_negative)
