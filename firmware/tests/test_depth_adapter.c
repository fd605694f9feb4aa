/* Depth CAN adapter: CANopen master of the drive, depth filter, speed, frames out. */
#include <string.h>

#include "check.h"
#include "depth_adapter.h"
#include "servo_cylinder_pdo.h"
#include "sowing_depth.h"

static depth_adapter_t a;
static hal_can_frame_t out[DEPTH_MAX_OUT];

static void start_with(const depth_config_t *cfg)
{
    depth_init(&a, cfg);
}

static void start(void)
{
    depth_config_t cfg;
    depth_config_defaults(&cfg);
    start_with(&cfg);
}

static hal_can_frame_t std_frame(uint32_t id, uint8_t len, const uint8_t *data)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    memcpy(f.data, data, len);
    return f;
}

static hal_can_frame_t heartbeat(uint8_t state)
{
    return std_frame(0x702, 1, &state);
}

static hal_can_frame_t tpdo1(uint16_t statusword)
{
    struct servo_cylinder_pdo_tpdo1_t m = {0};
    m.statusword = statusword;
    hal_can_frame_t f = std_frame(0x182, 6, (const uint8_t *)"\0\0\0\0\0\0");
    servo_cylinder_pdo_tpdo1_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t inclinometer(uint16_t x_mv, uint8_t status)
{
    struct sowing_depth_inclinometer_t m;
    memset(&m, 0, sizeof m);
    m.inc_x_voltage = x_mv;
    m.inc_y_voltage = 2500;
    m.inc_x_status = status;
    hal_can_frame_t f = {SOWING_DEPTH_INCLINOMETER_FRAME_ID, true, 8, {0}};
    sowing_depth_inclinometer_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t depth_setpoint(double target_mm, uint8_t enable, uint8_t mode)
{
    struct sowing_depth_depth_setpoint_t m;
    memset(&m, 0, sizeof m);
    m.ds_target_depth = sowing_depth_depth_setpoint_ds_target_depth_encode(target_mm);
    m.ds_enable = enable;
    m.ds_mode = mode;
    hal_can_frame_t f = {SOWING_DEPTH_DEPTH_SETPOINT_FRAME_ID, true, 8, {0}};
    sowing_depth_depth_setpoint_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t gbsd(double mps)
{
    struct sowing_depth_gbsd_t m;
    memset(&m, 0, sizeof m);
    m.gbsd_ground_speed = sowing_depth_gbsd_gbsd_ground_speed_encode(mps);
    m.gbsd_direction = 1;
    hal_can_frame_t f = {SOWING_DEPTH_GBSD_FRAME_ID, true, 8, {0}};
    sowing_depth_gbsd_pack(f.data, &m, sizeof f.data);
    return f;
}

static const hal_can_frame_t *find(size_t n, uint32_t id)
{
    for (size_t i = 0; i < n; i++) {
        if (out[i].id == id) {
            return &out[i];
        }
    }
    return NULL;
}

static void test_nmt_start(void)
{
    start();
    hal_can_frame_t hb = heartbeat(0x00);
    size_t n = depth_on_frame(&a, &hb, 0.0, out);
    CHECK_INT(n, 1);
    CHECK(out[0].id == 0x000 && !out[0].extended && out[0].len == 2);
    CHECK(out[0].data[0] == 0x01 && out[0].data[1] == 2);
    hb = heartbeat(0x7F);
    CHECK_INT(depth_on_frame(&a, &hb, 0.0, out), 1);
    hb = heartbeat(0x05);
    CHECK_INT(depth_on_frame(&a, &hb, 0.0, out), 0);
    /* operational: RPDO3 mode 3 once, RPDO2 every step */
    n = depth_step(&a, 0.0, out);
    const hal_can_frame_t *mode = find(n, 0x402);
    CHECK(mode != NULL && mode->len == 1 && mode->data[0] == 3);
    CHECK(find(n, 0x302) != NULL);
    /* the command closes the step: status and heartbeat (step 0) come before it */
    CHECK(find(n, 0x701) != NULL && out[n - 1].id == 0x302);
    n = depth_step(&a, 0.01, out);
    CHECK(out[n - 1].id == 0x302);
    CHECK(find(n, 0x402) == NULL);
    CHECK(find(n, 0x302) != NULL);
    /* a drive that drops out of Operational gets its mode again */
    hb = heartbeat(0x7F);
    depth_on_frame(&a, &hb, 0.02, out);
    hb = heartbeat(0x05);
    depth_on_frame(&a, &hb, 0.02, out);
    n = depth_step(&a, 0.02, out);
    CHECK(find(n, 0x402) != NULL);
    hal_can_frame_t boot = depth_bootup();
    CHECK(boot.id == 0x701 && boot.len == 1 && boot.data[0] == 0);
}

static uint16_t controlword_after(uint16_t statusword, double t)
{
    hal_can_frame_t f = tpdo1(statusword);
    depth_on_frame(&a, &f, t, out);
    size_t n = depth_step(&a, t, out);
    struct servo_cylinder_pdo_rpdo2_t m;
    const hal_can_frame_t *p = find(n, 0x302);
    servo_cylinder_pdo_rpdo2_unpack(&m, p->data, p->len);
    return m.controlword;
}

static void test_controlwords(void)
{
    start();
    CHECK_INT(depth_next_controlword(0x0000), 0x06); /* not ready to switch on */
    CHECK_INT(controlword_after(0x0250, 0.00), 0x06); /* switch on disabled */
    CHECK_INT(controlword_after(0x0231, 0.01), 0x07); /* ready to switch on */
    CHECK_INT(controlword_after(0x0233, 0.02), 0x0F); /* switched on */
    CHECK_INT(controlword_after(0x0237, 0.03), 0x0F); /* operation enabled */
    CHECK_INT(controlword_after(0x0218, 0.04), 0x80); /* fault: reset ... */
    CHECK_INT(controlword_after(0x0218, 0.05), 0x00); /* ... as a rising edge */
    CHECK_INT(controlword_after(0x0218, 0.06), 0x80);
    CHECK_INT(controlword_after(0x0217, 0.07), 0x06); /* quick stop active */
}

static void test_depth_filter(void)
{
    start();
    hal_can_frame_t f = inclinometer(3700, 0); /* -0.065 * 3700 + 270.35 = 29.85 mm */
    depth_on_frame(&a, &f, 0.0, out);
    CHECK_NEAR(a.depth_mm, 29.85, 1e-9);
    f = inclinometer(3600, 0); /* 36.35 mm: d = 29.85 + 0.2 * 6.5 */
    depth_on_frame(&a, &f, 0.01, out);
    CHECK_NEAR(a.depth_mm, 31.15, 1e-9);
    f = inclinometer(100, 1); /* status not ok: value ignored, sensor fault reported */
    depth_on_frame(&a, &f, 0.02, out);
    CHECK_NEAR(a.depth_mm, 31.15, 1e-9);
    size_t n = depth_step(&a, 0.02, out);
    const hal_can_frame_t *st = find(n, SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID);
    CHECK(st != NULL);
    struct sowing_depth_depth_controller_status_t m;
    sowing_depth_depth_controller_status_unpack(&m, st->data, st->len);
    CHECK_INT(m.dc_sensor_fault, 1);
    CHECK_INT(m.dc_speed_lost, 1);
    CHECK(m.dc_measured_depth == 311 || m.dc_measured_depth == 312); /* 31.15 mm, 0.1 mm */
    /* J1939 padding: unused bits are 1 */
    CHECK_INT(st->data[6], 0xFF);
    CHECK_INT(st->data[7], 0xFF);
    CHECK_INT(st->data[5] & 0xF0, 0xF0);
    CHECK(find(n, 0x701) != NULL);
    /* the next good frame goes on filtering from the held value and clears the fault */
    f = inclinometer(3700, 0);
    depth_on_frame(&a, &f, 0.6, out);
    CHECK_NEAR(a.depth_mm, 31.15 + 0.2 * (29.85 - 31.15), 1e-9);
    for (int k = 1; k < 10; k++) {
        depth_step(&a, 0.6 + 0.01 * k, out);
    }
    n = depth_step(&a, 0.7, out);
    st = find(n, SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID);
    CHECK(st != NULL);
    sowing_depth_depth_controller_status_unpack(&m, st->data, st->len);
    CHECK_INT(m.dc_sensor_fault, 0);
    CHECK_INT(m.dc_counter, 1);
}

static void make_ready_with(const depth_config_t *cfg, double speed_mps)
{
    start_with(cfg);
    hal_can_frame_t hb = heartbeat(0x05);
    depth_on_frame(&a, &hb, 0.0, out);
    hal_can_frame_t sw = tpdo1(0x0237);
    depth_on_frame(&a, &sw, 0.0, out);
    hal_can_frame_t inc = inclinometer(3700, 0); /* 29.85 mm */
    depth_on_frame(&a, &inc, 0.0, out);
    hal_can_frame_t sp = depth_setpoint(30.0, 1, 1);
    depth_on_frame(&a, &sp, 0.0, out);
    if (speed_mps >= 0.0) {
        hal_can_frame_t g = gbsd(speed_mps);
        depth_on_frame(&a, &g, 0.0, out);
    }
}

static void make_ready(double speed_mps)
{
    depth_config_t cfg;
    depth_config_defaults(&cfg);
    make_ready_with(&cfg, speed_mps);
}

static void test_control_step(void)
{
    make_ready(1.0);
    size_t n = depth_step(&a, 0.0, out);
    CHECK(a.last.valid && a.last.enabled);
    /* first step: e = 0.15, ec = 0; the core decides the speed, the PDO carries it */
    fpid_state_t s;
    fpid_reset(&s);
    fpid_output_t want = fpid_step(&a.cfg.core, &s, 30.0, a.depth_mm, true, true);
    CHECK_NEAR(a.last.out.speed_mm_s, want.speed_mm_s, 0);
    CHECK_NEAR(a.depth_mm, 29.85, 1e-9);
    const hal_can_frame_t *p = find(n, 0x302);
    struct servo_cylinder_pdo_rpdo2_t m;
    servo_cylinder_pdo_rpdo2_unpack(&m, p->data, p->len);
    CHECK_INT(m.controlword, 0x0F);
    CHECK_INT(m.target_velocity, (long long)rint(want.speed_mm_s * 100.0));
    CHECK(m.target_velocity != 0);
    const hal_can_frame_t *st = find(n, SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID);
    struct sowing_depth_depth_controller_status_t sm;
    sowing_depth_depth_controller_status_unpack(&sm, st->data, st->len);
    CHECK_INT(sm.dc_state, 2);
    CHECK_INT(sm.dc_sensor_fault, 0);
    CHECK_INT(sm.dc_speed_lost, 0);
}

static void test_enable_conditions(void)
{
    make_ready(0.05); /* below 0.1 m/s */
    depth_step(&a, 0.0, out);
    CHECK(a.last.valid && !a.last.enabled);
    CHECK_NEAR(a.last.out.speed_mm_s, 0.0, 0);
    make_ready(-1.0); /* no speed at all */
    depth_step(&a, 0.0, out);
    CHECK(!a.last.speed_known && !a.last.enabled);
    /* the GNSS alone is enough */
    depth_on_gnss(&a, true, 1.2, 0.0);
    depth_step(&a, 0.01, out);
    CHECK(a.last.speed_known && a.last.enabled);
    /* a no-fix report withdraws the GNSS speed */
    depth_on_gnss(&a, false, 0.0, 0.02);
    depth_step(&a, 0.02, out);
    CHECK(!a.last.speed_known);
    /* manual mode: not enabled */
    make_ready(1.0);
    hal_can_frame_t sp = depth_setpoint(30.0, 1, 0);
    depth_on_frame(&a, &sp, 0.0, out);
    depth_step(&a, 0.0, out);
    CHECK(!a.last.enabled);
    /* drive not in Operation enabled: not valid */
    make_ready(1.0);
    hal_can_frame_t sw = tpdo1(0x0233);
    depth_on_frame(&a, &sw, 0.0, out);
    depth_step(&a, 0.0, out);
    CHECK(!a.last.valid);
    /* speed stale after 1 s */
    make_ready(1.0);
    hal_can_frame_t inc = inclinometer(3700, 0);
    depth_on_frame(&a, &inc, 1.01, out);
    depth_step(&a, 1.01, out);
    CHECK(!a.last.speed_known);
}

/* One step at i * 10 ms (the lockstep clock), after an inclinometer frame with X = x_mv
 * (none if x_mv < 0) and a fresh 1 m/s ground speed; returns the target velocity of the RPDO2
 * and sets *fault to the status frame's SensorFault (-1 on steps without a status frame). */
static long long step_at(int i, int x_mv, uint8_t x_status, int *fault)
{
    double t = (double)i * 0.01;
    if (x_mv >= 0) {
        hal_can_frame_t inc = inclinometer((uint16_t)x_mv, x_status);
        depth_on_frame(&a, &inc, t, out);
    }
    hal_can_frame_t g = gbsd(1.0);
    depth_on_frame(&a, &g, t, out);
    size_t n = depth_step(&a, t, out);
    struct servo_cylinder_pdo_rpdo2_t pdo;
    const hal_can_frame_t *p = find(n, 0x302);
    servo_cylinder_pdo_rpdo2_unpack(&pdo, p->data, p->len);
    const hal_can_frame_t *st = find(n, SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID);
    *fault = -1;
    if (st != NULL) {
        struct sowing_depth_depth_controller_status_t m;
        sowing_depth_depth_controller_status_unpack(&m, st->data, st->len);
        *fault = m.dc_sensor_fault;
    }
    return pdo.target_velocity;
}

/* Runs steps first..last; counts the steps that controlled (valid, velocity != 0) and the
 * status frames that said SensorFault. x_mv < 0: no inclinometer frames; alternate: X goes
 * x_mv, x_mv + 1, x_mv, ... */
static void run_steps(int first, int last, int x_mv, bool alternate, uint8_t x_status,
                      int *controlled, int *faults)
{
    *controlled = 0;
    *faults = 0;
    for (int i = first; i <= last; i++) {
        int x = x_mv < 0 ? -1 : x_mv + (alternate ? i % 2 : 0);
        int fault;
        long long v = step_at(i, x, x_status, &fault);
        if (a.last.valid && v != 0) {
            (*controlled)++;
        }
        if (fault == 1) {
            (*faults)++;
        }
    }
}

static void test_frozen_inclinometer(void)
{
    make_ready(1.0); /* X = 3700 at 0 s */
    CHECK_NEAR(a.cfg.frozen_after_s, 0.2, 0);
    int controlled, faults, fault;
    /* a live sensor (X changes every frame) controls for 3 s, no SensorFault */
    run_steps(0, 299, 3700, true, 0, &controlled, &faults);
    CHECK_INT(controlled, 300);
    CHECK_INT(faults, 0);
    /* X changes to 3710 at 3.00 s, then repeats: control up to 3.20 s (0.2 s, not more) */
    run_steps(300, 320, 3710, false, 0, &controlled, &faults);
    CHECK_INT(controlled, 21);
    CHECK_INT(faults, 0); /* the status frame of 3.20 s included */
    CHECK(!a.last.frozen);
    /* 3.21 s: frozen; the roller holds and the status says SensorFault */
    CHECK_INT(step_at(321, 3710, 0, &fault), 0);
    CHECK(a.last.frozen && !a.last.valid);
    run_steps(322, 399, 3710, false, 0, &controlled, &faults);
    CHECK_INT(controlled, 0);
    CHECK_INT(faults, 7); /* 3.30 ... 3.90 s */
    /* a changed X is a live sensor again */
    CHECK(step_at(400, 3711, 0, &fault) != 0);
    CHECK_INT(fault, 0);
    CHECK(a.last.valid && !a.last.frozen);
    /* frames stop at 4.00 s: the held depth controls up to 4.20 s, then the roller holds */
    run_steps(401, 420, -1, false, 0, &controlled, &faults);
    CHECK_INT(controlled, 20);
    CHECK_INT(faults, 0);
    run_steps(421, 470, -1, false, 0, &controlled, &faults);
    CHECK_INT(controlled, 0);
    CHECK_INT(faults, 5); /* 4.30 ... 4.70 s */
    CHECK(a.last.frozen);
    /* a bad status meanwhile does not count as a change: still frozen */
    run_steps(471, 480, 3900, false, 1, &controlled, &faults);
    CHECK_INT(controlled, 0);
    /* a good frame with the last good X (3711) is no change either */
    run_steps(481, 490, 3711, false, 0, &controlled, &faults);
    CHECK_INT(controlled, 0);
    CHECK_INT(faults, 1);
}

static void test_frozen_check_off(void)
{
    static const char *const offs[] = {"0", "-1"};
    for (int k = 0; k < 2; k++) {
        depth_config_t cfg;
        depth_config_defaults(&cfg);
        param_ref_t refs[DEPTH_PARAM_COUNT];
        size_t n = depth_param_refs(&cfg, refs);
        CHECK(param_set(refs, n, "frozen_after_s", offs[k]) == PARAM_OK);
        make_ready_with(&cfg, 1.0);
        /* the same X for 3 s, then no frames for 2 s: the held depth controls throughout */
        int controlled, faults;
        run_steps(0, 299, 3700, false, 0, &controlled, &faults);
        CHECK_INT(controlled, 300);
        CHECK_INT(faults, 0);
        run_steps(300, 499, -1, false, 0, &controlled, &faults);
        CHECK_INT(controlled, 200);
        CHECK_INT(faults, 0);
        CHECK(!a.last.frozen);
    }
}

static void test_bad_status_holds(void)
{
    make_ready(1.0);
    int fault;
    CHECK(step_at(0, 3701, 0, &fault) != 0);
    CHECK_INT(fault, 0);
    /* X status not ok: the depth is invalid at once, the roller holds, SensorFault */
    int controlled, faults;
    run_steps(1, 10, 3702, true, 1, &controlled, &faults);
    CHECK_INT(controlled, 0);
    CHECK_INT(faults, 1); /* the status frame of 0.10 s */
    CHECK(!a.last.valid && !a.last.frozen);
    CHECK_INT(step_at(11, 3705, 2, &fault), 0); /* above range as well as below */
    /* a good frame (a new X) controls again */
    run_steps(12, 20, 3700, true, 0, &controlled, &faults);
    CHECK_INT(controlled, 9);
    CHECK_INT(faults, 0);
}

static void test_config_check(void)
{
    depth_config_t cfg;
    char err[128];
    depth_config_defaults(&cfg);
    CHECK_INT(depth_config_check(&cfg, err, sizeof err), 0);
    cfg.core.period_s = 0;
    CHECK_INT(depth_config_check(&cfg, err, sizeof err), -1);
    CHECK(strstr(err, "period_s") != NULL);
    param_ref_t refs[DEPTH_PARAM_COUNT];
    size_t n = depth_param_refs(&cfg, refs);
    CHECK_INT(n, DEPTH_PARAM_COUNT);
    CHECK(param_set(refs, n, "kp_scale", "0.4") == PARAM_OK && cfg.core.kp_scale == 0.4);
    CHECK(param_set(refs, n, "speed_timeout_s", "2") == PARAM_OK && cfg.speed_timeout_s == 2);
    CHECK(param_set(refs, n, "frozen_after_s", "0.25") == PARAM_OK && cfg.frozen_after_s == 0.25);
    CHECK(param_set(refs, n, "kp1", "1") == PARAM_UNKNOWN);
}

TEST_MAIN("depth_adapter", test_nmt_start, test_controlwords, test_depth_filter,
          test_control_step, test_enable_conditions, test_frozen_inclinometer,
          test_frozen_check_off, test_bad_status_holds, test_config_check)
