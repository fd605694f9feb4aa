/* Fertilizer CAN adapter: frames in, validity and target worked out, frames out. */
#include <math.h>
#include <string.h>

#include "check.h"
#include "fertilizer.h"
#include "fertilizer_adapter.h"

static hal_can_frame_t setpoint(uint8_t mode, bool enable, double target_flow, double rate,
                                double width, uint8_t source, uint8_t rows)
{
    struct fertilizer_fert_setpoint_t m;
    memset(&m, 0, sizeof m);
    m.mode = mode;
    m.enable = enable ? 1 : 0;
    m.target_flow = fertilizer_fert_setpoint_target_flow_encode(target_flow);
    m.target_rate = fertilizer_fert_setpoint_target_rate_encode(rate);
    m.working_width = fertilizer_fert_setpoint_working_width_encode(width);
    m.speed_source = source;
    m.active_rows = rows;
    hal_can_frame_t f = {FERTILIZER_FERT_SETPOINT_FRAME_ID, false, 8, {0}};
    fertilizer_fert_setpoint_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t flow(int row, double gps, bool ready, bool overrange)
{
    struct fertilizer_flow_module1_t m;
    memset(&m, 0, sizeof m);
    m.flow = fertilizer_flow_module1_flow_encode(gps);
    m.baseline_ready = ready ? 1 : 0;
    m.adc_overrange = overrange ? 1 : 0;
    m.window_length = 1000;
    hal_can_frame_t f = {FERTILIZER_FLOW_MODULE1_FRAME_ID + (uint32_t)row, false, 8, {0}};
    fertilizer_flow_module1_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t hall(double mps)
{
    struct fertilizer_ground_wheel_speed_t m;
    memset(&m, 0, sizeof m);
    m.wheel_speed = fertilizer_ground_wheel_speed_wheel_speed_encode(mps);
    m.moving = 1;
    hal_can_frame_t f = {FERTILIZER_GROUND_WHEEL_SPEED_FRAME_ID, false, 8, {0}};
    fertilizer_ground_wheel_speed_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t gbsd(uint16_t raw)
{
    struct fertilizer_ground_based_speed_dist_t m;
    memset(&m, 0, sizeof m);
    m.ground_based_machine_speed = raw;
    hal_can_frame_t f = {FERTILIZER_GROUND_BASED_SPEED_DIST_FRAME_ID, true, 8, {0}};
    fertilizer_ground_based_speed_dist_pack(f.data, &m, sizeof f.data);
    return f;
}

static int16_t ch1_mv(const hal_can_frame_t *out, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (out[i].id == FERTILIZER_ANALOG_OUTPUT_COMMAND_FRAME_ID) {
            struct fertilizer_analog_output_command_t m;
            fertilizer_analog_output_command_unpack(&m, out[i].data, out[i].len);
            return m.ch1_output;
        }
    }
    return -1;
}

static fert_adapter_t a;

static void start(ppid_law_t law)
{
    fert_config_t cfg;
    fert_config_defaults(&cfg, law);
    cfg.core.settle_periods = 0.0; /* these tests look at the adapter, not the settle gate */
    fert_init(&a, &cfg);
}

static void test_idle_frames(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    size_t n = fert_step(&a, 0.0, out);
    CHECK_INT(n, 3); /* status (first step), heartbeat, then the command: it closes a step */
    CHECK_INT(out[0].id, 0x190);
    CHECK_INT(out[1].id, 0x710);
    CHECK_INT(out[1].len, 1);
    CHECK_INT(out[1].data[0], 0x05);
    CHECK_INT(out[2].id, 0x220);
    CHECK_INT(out[2].len, 4);
    CHECK_INT(ch1_mv(out, n), 0);
    for (int k = 1; k < 10; k++) {
        CHECK_INT(fert_step(&a, 0.1 * k, out), 2); /* no status on steps 1-9 */
        CHECK_INT(out[1].id, 0x220);               /* the command still last */
    }
    n = fert_step(&a, 1.0, out);
    CHECK_INT(n, 3);
    struct fertilizer_controller_status_t st;
    fertilizer_controller_status_unpack(&st, out[0].data, out[0].len);
    CHECK_INT(st.counter, 10); /* the step count, as the Python build */
    hal_can_frame_t boot = fert_bootup();
    CHECK(boot.id == 0x710 && boot.len == 1 && boot.data[0] == 0x00);
}

static void test_bench_feedforward(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t sp = setpoint(1, true, 23.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    hal_can_frame_t out[FERT_MAX_OUT];
    size_t n = fert_step(&a, 0.0, out);
    double ff = ppid_feedforward(&a.cfg.core, 23.0);
    CHECK_INT(ch1_mv(out, n), (long long)rint(ff * 1000.0));
    CHECK_NEAR(a.last.target_gps, 23.0, 1e-12);
    CHECK(a.last.sensor_fault); /* enabled, no valid row */
    struct fertilizer_controller_status_t st;
    fertilizer_controller_status_unpack(&st, out[0].data, out[0].len);
    CHECK_INT(st.target_flow, 2300);
    CHECK_INT(st.active_mode, 1);
    CHECK_INT(st.enabled, 1);
    CHECK_INT(st.sensor_fault, 1);
    CHECK_INT(st.command_voltage, (long long)round(ff * 1000.0));
    /* disabled: 0 V */
    sp = setpoint(1, false, 23.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.1);
    n = fert_step(&a, 0.1, out);
    CHECK_INT(ch1_mv(out, n), 0);
    CHECK(!a.last.sensor_fault);
}

static void test_row_validity(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    hal_can_frame_t sp = setpoint(1, true, 20.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    hal_can_frame_t f1 = flow(0, 19.0, true, false);
    hal_can_frame_t f2 = flow(1, 21.5, true, false);
    hal_can_frame_t f3 = flow(2, 30.0, false, false); /* no baseline yet */
    hal_can_frame_t f4 = flow(3, 30.0, true, true);   /* overrange */
    fert_on_frame(&a, &f1, 0.0);
    fert_on_frame(&a, &f2, 0.0);
    fert_on_frame(&a, &f3, 0.0);
    fert_on_frame(&a, &f4, 0.0);
    fert_step(&a, 0.0, out);
    CHECK(a.last.has_measurement);
    CHECK(a.last.new_report);
    CHECK_NEAR(a.last.measured_gps, 20.25, 1e-12);
    CHECK(!a.last.sensor_fault);
    /* next step without reports: measurement held, no new report */
    fert_step(&a, 0.1, out);
    CHECK(a.last.has_measurement && !a.last.new_report);
    CHECK_NEAR(a.last.measured_gps, 20.25, 1e-12);
    /* implausible: Flow > 3 Q + 5 = 65 */
    hal_can_frame_t f5 = flow(1, 66.0, true, false);
    fert_on_frame(&a, &f5, 0.2);
    fert_step(&a, 0.2, out);
    CHECK_NEAR(a.last.measured_gps, 19.0, 1e-12);
    CHECK(!a.last.new_report); /* the only fresh report was not valid */
    /* stale: row 1 reported at 0.0, invalid after 2.5 s */
    fert_step(&a, 2.5, out);
    CHECK(a.last.has_measurement);
    fert_step(&a, 2.6, out);
    CHECK(!a.last.has_measurement);
    CHECK(a.last.sensor_fault);
}

static void test_mode_change_resets(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    hal_can_frame_t sp = setpoint(1, true, 20.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    hal_can_frame_t f1 = flow(0, 19.0, true, false);
    fert_on_frame(&a, &f1, 0.0);
    fert_step(&a, 0.0, out);
    CHECK(a.core.primed && a.core.integral > 0.0);
    sp = setpoint(2, true, 20.0, 0, 0, 0, 4); /* constant speed: open loop */
    fert_on_frame(&a, &sp, 0.1);
    fert_step(&a, 0.1, out);
    CHECK(!a.core.primed);
    sp = setpoint(1, true, 20.0, 0, 0, 0, 4); /* back: the closed loop starts clean */
    fert_on_frame(&a, &sp, 0.2);
    size_t n = fert_step(&a, 0.2, out);
    CHECK(!a.core.primed);
    CHECK_INT(ch1_mv(out, n), (long long)rint(ppid_feedforward(&a.cfg.core, 20.0) * 1000.0));
}

static void test_param_names(void)
{
    fert_config_t cfg;
    fert_config_defaults(&cfg, PPID_LAW_PHYSICAL);
    param_ref_t refs[FERT_PARAM_COUNT];
    size_t n = fert_param_refs(&cfg, refs);
    CHECK_INT(n, FERT_PARAM_COUNT);
    CHECK(param_set(refs, n, "ff_coeff", "4.45") == PARAM_OK && cfg.core.ff_coeff == 4.45);
    CHECK(param_set(refs, n, "shaft_rpm_per_v", "5") == PARAM_OK);
    CHECK(param_set(refs, n, "stale_after_s", "3") == PARAM_OK && cfg.stale_after_s == 3.0);
    CHECK(param_set(refs, n, "period_s", "0.05") == PARAM_OK && cfg.period_s == 0.05);
    CHECK(param_set(refs, n, "ground_speed_first_s", "0") == PARAM_OK &&
          cfg.ground_speed_first_s == 0.0);
    CHECK(param_set(refs, n, "ki1", "0.5") == PARAM_OK);
    /* the ISOBUS implement's share leaves the terminal-only key out */
    param_ref_t common[FERT_COMMON_PARAM_COUNT];
    size_t nc = fert_common_param_refs(&cfg, common);
    CHECK_INT(nc, FERT_COMMON_PARAM_COUNT);
    CHECK(param_set(common, nc, "ground_speed_first_s", "0") == PARAM_UNKNOWN);
    CHECK(param_set(refs, n, "use_calibration", "0") == PARAM_OK && cfg.use_calibration == 0.0);
    CHECK(param_set(common, nc, "use_calibration", "0") == PARAM_UNKNOWN);
    /* the open-loop law takes only the feedforward keys (and the adapter's) */
    fert_config_defaults(&cfg, PPID_LAW_OPEN_LOOP);
    n = fert_param_refs(&cfg, refs);
    CHECK_INT(n, 9); /* 5 feedforward keys, stale_after_s, period_s, ground_speed_first_s, use_calibration */
    CHECK(param_set(refs, n, "ki1", "0.5") == PARAM_UNKNOWN);
    CHECK(param_set(refs, n, "v_max", "8") == PARAM_OK);
    CHECK(param_set(refs, n, "ff_linear_below_rpm", "4") == PARAM_OK
          && cfg.core.ff_linear_below_rpm == 4.0);
}

static void test_field_target(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    /* Q = 0.1 * 200 * 3 * v / 4 rows: 4 km/h -> 1.111 m/s -> 16.665 g/s */
    hal_can_frame_t sp = setpoint(0, true, 0, 200.0, 3.0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    fert_step(&a, 0.0, out);
    CHECK_NEAR(a.last.target_gps, 0.0, 0); /* no speed yet */
    hal_can_frame_t h = hall(1.111);
    fert_on_frame(&a, &h, 0.05);
    fert_step(&a, 0.1, out);
    CHECK_NEAR(a.last.target_gps, 0.1 * 200.0 * 3.0 * 1.111 / 4.0, 1e-9);
    fert_step(&a, 30.0, out); /* a speed is held until the next frame */
    CHECK(a.last.target_gps > 0.0);
    /* PGN 65097 as the source; 0xFFFF = not available */
    sp = setpoint(0, true, 0, 200.0, 3.0, 2, 4);
    fert_on_frame(&a, &sp, 1.2);
    hal_can_frame_t g = gbsd(2000);
    fert_on_frame(&a, &g, 1.2);
    fert_step(&a, 1.3, out);
    CHECK_NEAR(a.last.target_gps, 0.1 * 200.0 * 3.0 * 2.0 / 4.0, 1e-9);
    g = gbsd(0xFFFF);
    fert_on_frame(&a, &g, 1.3);
    fert_step(&a, 1.4, out);
    CHECK_NEAR(a.last.target_gps, 0.0, 0);
}

/* A fresh ground-based speed is used whatever SpeedSource names; the terminal's source once it
 * is older than ground_speed_first_s, or not available; 0 s obeys SpeedSource alone. */
static void test_ground_speed_first(void)
{
    hal_can_frame_t out[FERT_MAX_OUT];
    const double q_per_mps = 0.1 * 200.0 * 3.0 / 4.0;
    for (int first = 1; first >= 0; first--) {
        start(PPID_LAW_PHYSICAL);
        a.cfg.ground_speed_first_s = first ? 0.3 : 0.0;
        hal_can_frame_t sp = setpoint(0, true, 0, 200.0, 3.0, 0, 4); /* Hall wheel */
        fert_on_frame(&a, &sp, 0.0);
        hal_can_frame_t h = hall(1.5);
        fert_on_frame(&a, &h, 0.0);
        hal_can_frame_t g = gbsd(1450); /* 1.45 m/s: the wheel reads 3.4 % fast */
        fert_on_frame(&a, &g, 0.0);
        fert_step(&a, 0.0, out);
        CHECK_NEAR(a.last.target_gps, q_per_mps * (first ? 1.45 : 1.5), 1e-9);
        fert_step(&a, 0.3, out); /* 0.3 s old: still fresh */
        CHECK_NEAR(a.last.target_gps, q_per_mps * (first ? 1.45 : 1.5), 1e-9);
        fert_step(&a, 0.4, out); /* older: the terminal's source again */
        CHECK_NEAR(a.last.target_gps, q_per_mps * 1.5, 1e-9);
        fert_on_frame(&a, &g, 0.4);
        fert_step(&a, 0.4, out);
        CHECK_NEAR(a.last.target_gps, q_per_mps * (first ? 1.45 : 1.5), 1e-9);
        g = gbsd(0xFFFF); /* not available: not a speed to prefer */
        fert_on_frame(&a, &g, 0.5);
        fert_step(&a, 0.5, out);
        CHECK_NEAR(a.last.target_gps, q_per_mps * 1.5, 1e-9);
    }
}

static void test_constant_speed_mode_is_open_loop(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    hal_can_frame_t sp = setpoint(2, true, 34.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    hal_can_frame_t f1 = flow(0, 20.0, true, false);
    fert_on_frame(&a, &f1, 0.0);
    size_t n = fert_step(&a, 0.0, out);
    CHECK_INT(a.last.law, PPID_LAW_OPEN_LOOP);
    CHECK_INT(a.last.out.segment, 0);
    CHECK_INT(ch1_mv(out, n), (long long)rint(ppid_feedforward(&a.cfg.core, 34.0) * 1000.0));
    CHECK(!a.last.sensor_fault);
}

static void test_paper_literal_starts_at_zero(void)
{
    start(PPID_LAW_PAPER_LITERAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    hal_can_frame_t sp = setpoint(1, true, 23.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    size_t n = fert_step(&a, 0.0, out);
    CHECK_INT(ch1_mv(out, n), 0); /* no feedforward in [F]'s law */
    hal_can_frame_t f1 = flow(0, 22.5, true, false);
    fert_on_frame(&a, &f1, 0.05);
    n = fert_step(&a, 0.1, out);
    /* e = 0.5: fine, du = Ki1 * e = 0.0835 units -> 8.35 mV */
    CHECK_INT(ch1_mv(out, n), 8);
    CHECK_INT(a.last.out.segment, 1);
}

static hal_can_frame_t calibration(double grams_per_rev, double shaft_rpm)
{
    struct fertilizer_meter_calibration_t m;
    memset(&m, 0, sizeof m);
    m.grams_per_rev = fertilizer_meter_calibration_grams_per_rev_encode(grams_per_rev);
    m.test_shaft_speed = fertilizer_meter_calibration_test_shaft_speed_encode(shaft_rpm);
    m.revolutions = 50;
    hal_can_frame_t f = {FERTILIZER_METER_CALIBRATION_FRAME_ID, false, 8, {0}};
    fertilizer_meter_calibration_pack(f.data, &m, sizeof f.data);
    return f;
}

/* MeterCalibration: the test's grams per revolution fix ff_coeff (the same expression as
 * calibration.py), the feedforward follows; a frame without a test changes nothing; with
 * use_calibration = 0 the frame is ignored. */
static void test_calibration_replaces_ff_coeff(void)
{
    start(PPID_LAW_PHYSICAL);
    hal_can_frame_t out[FERT_MAX_OUT];
    double nominal = a.cfg.core.ff_coeff;
    /* the nominal map's own grams per revolution at 20 r/min: the coefficient comes back */
    double g_rev = 60.0 * nominal * pow(20.0, a.cfg.core.ff_exponent) / 20.0;
    CHECK_NEAR(fert_ff_coeff_from_test(g_rev, 20.0, a.cfg.core.ff_exponent, 5.0), nominal, 1e-12);
    /* below the knee the grams per revolution are the knee's */
    double g_knee = 60.0 * nominal * pow(5.0, a.cfg.core.ff_exponent) / 5.0;
    CHECK_NEAR(fert_ff_coeff_from_test(g_knee, 3.0, a.cfg.core.ff_exponent, 5.0), nominal, 1e-12);
    CHECK(fert_ff_coeff_from_test(0.0, 20.0, 0.6537, 5.0) == 0.0);
    CHECK(fert_ff_coeff_from_test(93.0, 0.0, 0.6537, 5.0) == 0.0);
    CHECK(fert_ff_coeff_from_test(650.0, 100.0, 0.6537, 5.0) > 0.0);

    hal_can_frame_t sp = setpoint(1, true, 23.0, 0, 0, 0, 4);
    fert_on_frame(&a, &sp, 0.0);
    size_t n = fert_step(&a, 0.0, out);
    long long before = ch1_mv(out, n);
    hal_can_frame_t cal = calibration(93.5, 20.0); /* a lot ~3.5 % lighter than the map */
    fert_on_frame(&a, &cal, 0.05);
    double expect = fert_ff_coeff_from_test(93.5, 20.0, a.cfg.core.ff_exponent, 5.0);
    CHECK(a.cfg.core.ff_coeff == expect);
    n = fert_step(&a, 0.1, out);
    CHECK(ch1_mv(out, n) > before); /* a lighter lot: the shaft turns faster for 23 g/s */
    CHECK_INT(ch1_mv(out, n), (long long)rint(ppid_feedforward(&a.cfg.core, 23.0) * 1000.0));
    hal_can_frame_t none = calibration(0.0, 20.0);
    fert_on_frame(&a, &none, 0.15);
    CHECK(a.cfg.core.ff_coeff == expect);

    fert_config_t cfg;
    fert_config_defaults(&cfg, PPID_LAW_PHYSICAL);
    cfg.use_calibration = 0.0;
    fert_init(&a, &cfg);
    fert_on_frame(&a, &cal, 0.0);
    CHECK(a.cfg.core.ff_coeff == nominal);
}

TEST_MAIN("fertilizer_adapter", test_calibration_replaces_ff_coeff, test_idle_frames, test_bench_feedforward, test_row_validity,
          test_field_target, test_ground_speed_first, test_constant_speed_mode_is_open_loop,
          test_paper_literal_starts_at_zero, test_mode_change_resets, test_param_names)
