/* Piecewise PID core: hand-computed cases (docs/reference-controllers.md section 1). */
#include "check.h"
#include "piecewise_pid.h"

#define TOL 1e-12

/* easy numbers: ff(Q) = (Q / 4)^2 / 2, so ff(8) = 2 V and ff(10) = 3.125 V (the power law all
 * the way down: no knee) */
static ppid_params_t easy(ppid_law_t law)
{
    ppid_params_t p;
    ppid_defaults(&p, law);
    p.ff_coeff = 4.0;
    p.ff_exponent = 0.5;
    p.shaft_rpm_per_v = 2.0;
    p.v_max = 10.0;
    p.ff_linear_below_rpm = 0.0;
    return p;
}

static void test_defaults(void)
{
    ppid_params_t p;
    ppid_defaults(&p, PPID_LAW_PAPER_LITERAL);
    CHECK_NEAR(p.kp1, 0.038, 0);
    CHECK_NEAR(p.kp2, 2.089, 0);
    CHECK_NEAR(p.kp3, 212.016, 0);
    CHECK_NEAR(p.ki1, 0.167, 0);
    CHECK_NEAR(p.ki2, 0.015, 0);
    CHECK_NEAR(p.kd, 1.317, 0);
    CHECK_NEAR(p.e1, 1.0, 0);
    CHECK_NEAR(p.e2, 5.0, 0);
    CHECK_NEAR(p.km, 0.1, 0);
    ppid_defaults(&p, PPID_LAW_PHYSICAL);
    CHECK_NEAR(p.e1, 0.02, 0);
    CHECK_NEAR(p.e2, 0.10, 0);
    CHECK_NEAR(p.c_max, 0.5, 0);
    CHECK_NEAR(p.shaft_rpm_per_v, 6.0, 0);
    CHECK_NEAR(p.v_max, 10.0, 0);
}

static void test_feedforward_knee(void)
{
    /* knee at 4 r/min: q(4) = 4 * 4^0.5 = 8 g/s; above it the power law, below it linear in
     * the shaft speed: 4 g/s -> 2 r/min -> 1 V (the power law would say 0.5 V) */
    ppid_params_t p = easy(PPID_LAW_OPEN_LOOP);
    p.ff_linear_below_rpm = 4.0;
    CHECK_NEAR(ppid_feedforward(&p, 10.0), 3.125, TOL);
    CHECK_NEAR(ppid_feedforward(&p, 8.0), 2.0, TOL);
    CHECK_NEAR(ppid_feedforward(&p, 4.0), 1.0, TOL);
    CHECK_NEAR(ppid_feedforward(&p, 2.0), 0.5, TOL);
    ppid_defaults(&p, PPID_LAW_PHYSICAL);
    CHECK_NEAR(p.ff_linear_below_rpm, 5.0, 0);
}

static void test_feedforward(void)
{
    ppid_params_t p = easy(PPID_LAW_OPEN_LOOP);
    CHECK_NEAR(ppid_feedforward(&p, 8.0), 2.0, TOL);
    CHECK_NEAR(ppid_feedforward(&p, 10.0), 3.125, TOL);
    CHECK_NEAR(ppid_feedforward(&p, 0.0), 0.0, 0);
    CHECK_NEAR(ppid_feedforward(&p, -3.0), 0.0, 0);
    CHECK_NEAR(ppid_feedforward(&p, 40.0), 10.0, 0); /* (10)^2 / 2 = 50 V clamps to v_max */
    /* the doc's defaults: 23 g/s -> (23 / 4.586)^(1 / 0.6537) / 6 */
    ppid_defaults(&p, PPID_LAW_PHYSICAL);
    CHECK_NEAR(ppid_feedforward(&p, 23.0), pow(23.0 / 4.586, 1.0 / 0.6537) / 6.0, 0);
}

static void test_open_loop_ignores_sensor(void)
{
    ppid_params_t p = easy(PPID_LAW_OPEN_LOOP);
    ppid_state_t s;
    ppid_reset(&s);
    ppid_output_t o = ppid_step(&p, &s, 8.0, 1.0, true, true);
    CHECK_NEAR(o.volts, 2.0, TOL);
    CHECK_INT(o.segment, 0);
    o = ppid_step(&p, &s, 8.0, 50.0, true, true);
    CHECK_NEAR(o.volts, 2.0, TOL);
    o = ppid_step(&p, &s, 0.0, 50.0, true, true);
    CHECK_NEAR(o.volts, 0.0, 0);
}

static void test_paper_literal_sequence(void)
{
    ppid_params_t p = easy(PPID_LAW_PAPER_LITERAL);
    p.kp1 = 0.5;
    p.ki1 = 0.25;
    p.kp2 = 2.0;
    p.ki2 = 0.125;
    p.kp3 = 10.0;
    p.kd = 1.0;
    p.e1 = 1.0;
    p.e2 = 5.0;
    p.km = 0.1; /* u in [0, 100] */
    ppid_state_t s;
    ppid_reset(&s);
    /* e = 0.5, fine, first update: no derivative kick; du = 0.25 * 0.5 */
    ppid_output_t o = ppid_step(&p, &s, 10.0, 9.5, true, true);
    CHECK_NEAR(o.volts, 0.0125, TOL);
    CHECK_INT(o.segment, 1);
    /* no new report: state held */
    o = ppid_step(&p, &s, 10.0, 3.0, true, false);
    CHECK_NEAR(o.volts, 0.0125, TOL);
    CHECK_INT(o.segment, 1);
    /* e = 2, medium: du = 2 (2 - 0.5) + 0.125 * 2 + (2 - 1 + 0.5) = 4.75 -> u = 4.875 */
    o = ppid_step(&p, &s, 10.0, 8.0, true, true);
    CHECK_NEAR(o.volts, 0.4875, TOL);
    CHECK_INT(o.segment, 2);
    /* e = -6, coarse (Ki = 0): du = 10 (-8) + (-6 - 4 + 0.5) = -89.5 -> clamps at 0 */
    o = ppid_step(&p, &s, 10.0, 16.0, true, true);
    CHECK_NEAR(o.volts, 0.0, TOL);
    CHECK_INT(o.segment, 3);
    /* e = 10: du = 10 (16) + (10 + 12 - 6... ) -> large -> clamps at v_max / km */
    o = ppid_step(&p, &s, 10.0, 0.0, true, true);
    CHECK_NEAR(o.volts, 10.0, TOL);
    CHECK_INT(o.segment, 3);
    /* target 0: reset */
    o = ppid_step(&p, &s, 0.0, 0.0, true, true);
    CHECK_NEAR(o.volts, 0.0, 0);
    CHECK_INT(o.segment, 0);
    CHECK(!s.primed);
    /* a report without a valid measurement does not update */
    o = ppid_step(&p, &s, 10.0, 0.0, false, true);
    CHECK_NEAR(o.volts, 0.0, 0);
    CHECK_INT(o.segment, 0);
    /* e = 0 after the reset: fine, du = 0 */
    o = ppid_step(&p, &s, 10.0, 10.0, true, true);
    CHECK_NEAR(o.volts, 0.0, 0);
    CHECK_INT(o.segment, 1);
}

static void test_segment_boundaries(void)
{
    ppid_params_t p = easy(PPID_LAW_PAPER_LITERAL);
    struct {
        double measured;
        int segment;
    } cases[] = {{10.0, 1}, {9.5, 1}, {10.5, 1}, {9.0, 2}, {11.0, 2}, {6.0, 2},
                 {5.0, 3},  {15.0, 3}, {0.0, 3}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        ppid_state_t s;
        ppid_reset(&s);
        ppid_output_t o = ppid_step(&p, &s, 10.0, cases[i].measured, true, true);
        CHECK_INT(o.segment, cases[i].segment);
    }
    /* physical: the same on r = e / Q with e1 = 2 %, e2 = 10 % (no settle: update at once) */
    p = easy(PPID_LAW_PHYSICAL);
    p.settle_periods = 0.0;
    struct {
        double measured;
        int segment;
    } rel[] = {{49.5, 1}, {49.0, 2}, {51.0, 2}, {45.5, 2}, {45.0, 3}, {60.0, 3}};
    for (size_t i = 0; i < sizeof rel / sizeof rel[0]; i++) {
        ppid_state_t s;
        ppid_reset(&s);
        ppid_output_t o = ppid_step(&p, &s, 50.0, rel[i].measured, true, true);
        CHECK_INT(o.segment, rel[i].segment);
    }
}

static void test_physical_sequence(void)
{
    ppid_params_t p = easy(PPID_LAW_PHYSICAL);
    p.kp1 = 0.5;
    p.ki1 = 0.25;
    p.kp2 = 1.0;
    p.ki2 = 0.125;
    p.kp3 = 2.0;
    p.kd = 0.5;
    p.settle_periods = 1.0;
    p.ki_first = 0.5;
    ppid_state_t s;
    ppid_reset(&s);
    /* target 0 -> 8 is a jump: no update on this step; feedforward alone */
    ppid_output_t o = ppid_step(&p, &s, 8.0, 0.0, false, false);
    CHECK_NEAR(o.volts, 2.0, TOL);
    CHECK_INT(o.segment, 0);
    /* one period later, r = 0.01, fine, first update learns with ki_first:
     * I = 0.005, c = 0.005 + 0.005 = 0.01 */
    o = ppid_step(&p, &s, 8.0, 7.92, true, true);
    CHECK_NEAR(o.volts, 2.02, TOL);
    CHECK_INT(o.segment, 1);
    /* 8 -> 10 is a jump (> e2 of 8): c falls back to I, the feedforward acts at once */
    o = ppid_step(&p, &s, 10.0, 0.0, true, false);
    CHECK_NEAR(o.volts, 3.125 * 1.005, TOL);
    CHECK_INT(o.segment, 1);
    /* r = 0.1, coarse (Ki = 0), first update after the jump (no D kick): c = 0.2 + 0.005 */
    o = ppid_step(&p, &s, 10.0, 9.0, true, true);
    CHECK_NEAR(o.volts, 3.765625, TOL);
    CHECK_INT(o.segment, 3);
    /* r = 0.5: c = 1 + 0.005 + 0.2 clamps at c_max = 0.5 */
    o = ppid_step(&p, &s, 10.0, 5.0, true, true);
    CHECK_NEAR(o.volts, 4.6875, TOL);
    CHECK_INT(o.segment, 3);
    /* r = -0.05, medium: I = 0.005 - 0.00625, c = -0.05 - 0.00125 + 0.5 (-0.55) */
    o = ppid_step(&p, &s, 10.0, 10.5, true, true);
    CHECK_NEAR(o.volts, 3.125 * (1.0 - 0.32625), TOL);
    CHECK_INT(o.segment, 2);
    /* target 0 resets; 0 -> 10 is a jump: the report of this step is ignored */
    o = ppid_step(&p, &s, 0.0, 10.5, true, true);
    CHECK_NEAR(o.volts, 0.0, 0);
    CHECK_INT(o.segment, 0);
    o = ppid_step(&p, &s, 10.0, 9.9, true, true);
    CHECK_NEAR(o.volts, 3.125, TOL);
    CHECK_INT(o.segment, 0);
    o = ppid_step(&p, &s, 10.0, 9.9, true, true); /* r = 0.01: c = 0.005 + 0.005 */
    CHECK_NEAR(o.volts, 3.125 * 1.01, TOL);
}

static void test_physical_settle_gate(void)
{
    ppid_params_t p = easy(PPID_LAW_PHYSICAL);
    p.kp1 = 0.5;
    p.settle_periods = 3.0;
    ppid_state_t s;
    ppid_reset(&s);
    /* reports during the 3 periods after the jump hold the old flow: ignored */
    for (int k = 0; k < 3; k++) {
        ppid_output_t o = ppid_step(&p, &s, 8.0, 7.92, true, true);
        CHECK_NEAR(o.volts, 2.0, TOL);
    }
    /* from the 3rd period on they count: r = 0.01, c = 0.005 + ki_first * 0.01 */
    ppid_output_t o = ppid_step(&p, &s, 8.0, 7.92, true, true);
    CHECK_NEAR(o.volts, 2.0 * (1.0 + 0.005 + p.ki_first * 0.01), TOL);
    /* a slow change (<= e2 per period) is no jump: updates go on */
    o = ppid_step(&p, &s, 8.4, 8.4, true, true);
    CHECK(o.segment == PPID_SEG_FINE);
}

static void test_physical_integral_clamp(void)
{
    ppid_params_t p = easy(PPID_LAW_PHYSICAL);
    p.kp1 = 0.5;
    p.ki1 = 100.0;
    p.ki_first = 1.0;
    p.kd = 0.0;
    p.settle_periods = 0.0;
    ppid_state_t s;
    ppid_reset(&s);
    /* r = 0.01, first update: I = 0.01; c = 0.005 + 0.01 */
    ppid_output_t o = ppid_step(&p, &s, 8.0, 7.92, true, true);
    CHECK_NEAR(o.volts, 2.0 * 1.015, TOL);
    /* r = 0.01: I = 0.01 + 1 clamps to 0.5; c = 0.005 + 0.5 clamps to 0.5 */
    o = ppid_step(&p, &s, 8.0, 7.92, true, true);
    CHECK_NEAR(o.volts, 3.0, TOL);
    CHECK_NEAR(s.integral, 0.5, TOL);
    /* r = -0.01: I = 0.5 - 1 = -0.5 (an unclamped I would be 0.01): c = -0.505 -> -0.5 */
    o = ppid_step(&p, &s, 8.0, 8.08, true, true);
    CHECK_NEAR(o.volts, 1.0, TOL);
    CHECK_NEAR(s.integral, -0.5, TOL);
}

static void test_physical_volts_clamp(void)
{
    ppid_params_t p = easy(PPID_LAW_PHYSICAL);
    p.kp3 = 10.0;
    p.settle_periods = 0.0;
    ppid_state_t s;
    ppid_reset(&s);
    /* ff(12) = 4.5 V; r = 1 -> c = 0.5 -> 6.75 V (the first update also learns I = 0.5);
     * 12 -> 16 is a jump: c = I = 0.5, ff(16) = 8 V -> 12 V clamps to 10 */
    ppid_output_t o = ppid_step(&p, &s, 12.0, 0.0, true, true);
    CHECK_NEAR(o.volts, 6.75, TOL);
    o = ppid_step(&p, &s, 16.0, 0.0, true, false);
    CHECK_NEAR(o.volts, 10.0, 0);
}

static void test_physical_anti_windup(void)
{
    ppid_params_t p = easy(PPID_LAW_PHYSICAL);
    p.ki1 = 0.25;
    p.ki2 = 0.25;
    p.kp1 = p.kp2 = p.kp3 = 0.0;
    p.e2 = 0.9;
    p.settle_periods = 0.0;
    ppid_state_t s;
    ppid_reset(&s);
    /* ff(40) clamps at 10 V: the command already sits at its limit, so a positive error
     * is not integrated (the first update included) */
    for (int k = 0; k < 5; k++) {
        ppid_step(&p, &s, 40.0, 30.0, true, true);
    }
    CHECK_NEAR(s.integral, 0.0, 0);
    /* a negative error still is: r = -0.25 -> I = ki_first * r */
    ppid_step(&p, &s, 40.0, 50.0, true, true);
    CHECK_NEAR(s.integral, -0.25 * p.ki_first, TOL);
}

static void test_law_names(void)
{
    ppid_law_t law;
    CHECK(ppid_law_parse("physical", &law) && law == PPID_LAW_PHYSICAL);
    CHECK(ppid_law_parse("paper-literal", &law) && law == PPID_LAW_PAPER_LITERAL);
    CHECK(ppid_law_parse("paper_literal", &law) && law == PPID_LAW_PAPER_LITERAL);
    CHECK(ppid_law_parse("open-loop", &law) && law == PPID_LAW_OPEN_LOOP);
    CHECK(!ppid_law_parse("pid", &law));
    CHECK(ppid_law_name(PPID_LAW_OPEN_LOOP)[0] == 'o');
}

TEST_MAIN("piecewise_pid", test_defaults, test_feedforward, test_feedforward_knee, test_open_loop_ignores_sensor,
          test_paper_literal_sequence, test_segment_boundaries, test_physical_sequence,
          test_physical_settle_gate, test_physical_integral_clamp, test_physical_volts_clamp,
          test_physical_anti_windup, test_law_names)
