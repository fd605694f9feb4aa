/* The cross-row plausibility check (core/cross_row.c): the cases of
 * tests/reference_controllers/test_refctl_cross_row.py, on the C build. */
#include <stdbool.h>

#include "check.h"
#include "cross_row.h"

#define PERIOD_S 0.1
#define DWELL 30

static const bool ALL4[4] = {true, true, true, true};

/* One step over four rows; returns the excluded rows as a bit mask (bit i = row i + 1). */
static int step4(xrow_state_t *s, double f1, double f2, double f3, double f4,
                 const bool passed[4])
{
    double flows[4] = {f1, f2, f3, f4};
    bool excluded[4];
    xrow_step(s, 4, flows, passed, excluded);
    int mask = 0;
    for (int i = 0; i < 4; i++) {
        mask |= excluded[i] ? 1 << i : 0;
    }
    return mask;
}

static void test_dwell_in_steps(void)
{
    xrow_state_t s;
    xrow_init(&s, PERIOD_S);
    CHECK_INT(s.dwell_steps, DWELL);
    xrow_init(&s, 10.0);
    CHECK_INT(s.dwell_steps, 1);
}

static void test_stuck_row_excluded_after_the_dwell_and_readmitted_after_as_long(void)
{
    xrow_state_t s;
    xrow_init(&s, PERIOD_S);
    for (int k = 0; k < DWELL - 1; k++) {
        CHECK_INT(step4(&s, 34.0, 20.4, 33.5, 34.6, ALL4), 0);
    }
    CHECK_INT(step4(&s, 34.0, 20.4, 33.5, 34.6, ALL4), 2);
    for (int k = 0; k < DWELL - 1; k++) {
        CHECK_INT(step4(&s, 34.0, 33.8, 33.5, 34.6, ALL4), 2);
    }
    CHECK_INT(step4(&s, 34.0, 33.8, 33.5, 34.6, ALL4), 0);
}

static void test_healthy_spread_and_short_transient_not_excluded(void)
{
    xrow_state_t s;
    xrow_init(&s, PERIOD_S);
    for (int k = 0; k < 5 * DWELL; k++) {
        CHECK_INT(step4(&s, 34.0 * 1.08, 34.0 * 0.95, 34.0, 34.0 * 0.97, ALL4), 0);
    }
    for (int k = 0; k < DWELL - 1; k++) {
        CHECK_INT(step4(&s, 34.0, 23.0, 34.0, 34.0, ALL4), 0);
    }
    CHECK_INT(step4(&s, 34.0 * 1.08, 34.0 * 0.95, 34.0, 34.0 * 0.97, ALL4), 0);
}

static void test_noise_agreeing_as_often_as_not_keeps_a_row_in(void)
{
    static const bool three[4] = {true, true, true, false};
    xrow_state_t s;
    xrow_init(&s, PERIOD_S);
    for (int k = 0; k < 10 * DWELL; k++) {
        CHECK_INT(step4(&s, 34.0, k % 2 ? 45.0 : 35.0, 34.0, 0.0, three), 0);
    }
}

static void test_two_rows_or_a_standstill_exclude_nothing(void)
{
    static const bool two[4] = {true, true, false, false};
    xrow_state_t s;
    xrow_init(&s, PERIOD_S);
    for (int k = 0; k < 2 * DWELL; k++) {
        CHECK_INT(step4(&s, 34.0, 10.0, 0.0, 0.0, two), 0);
        CHECK_INT(step4(&s, 0.3, 0.0, 0.9, 0.1, ALL4), 0);
    }
}

static void test_a_row_that_drops_out_starts_afresh(void)
{
    static const bool no2[4] = {true, false, true, true};
    xrow_state_t s;
    xrow_init(&s, PERIOD_S);
    for (int k = 0; k < DWELL; k++) {
        step4(&s, 34.0, 20.4, 33.5, 34.6, ALL4);
    }
    CHECK_INT(step4(&s, 34.0, 20.4, 33.5, 34.6, no2), 0);
    for (int k = 0; k < DWELL - 1; k++) {
        CHECK_INT(step4(&s, 34.0, 20.4, 33.5, 34.6, ALL4), 0);
    }
    CHECK_INT(step4(&s, 34.0, 20.4, 33.5, 34.6, ALL4), 2);
}

TEST_MAIN("cross_row", test_dwell_in_steps,
          test_stuck_row_excluded_after_the_dwell_and_readmitted_after_as_long,
          test_healthy_spread_and_short_transient_not_excluded,
          test_noise_agreeing_as_often_as_not_keeps_a_row_in,
          test_two_rows_or_a_standstill_exclude_nothing, test_a_row_that_drops_out_starts_afresh)
