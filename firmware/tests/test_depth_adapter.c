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

static hal_can_frame_t tpdo1_at(uint16_t statusword, int32_t position_inc)
{
    struct servo_cylinder_pdo_tpdo1_t m = {0};
    m.statusword = statusword;
    m.position_actual_value = position_inc;
    hal_can_frame_t f = std_frame(0x182, 6, (const uint8_t *)"\0\0\0\0\0\0");
    servo_cylinder_pdo_tpdo1_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t tpdo1(uint16_t statusword)
{
    return tpdo1_at(statusword, 0);
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

/* Two speeds as fresh as each other: the source that reported first counts (the Python
 * reference's rule: its sources keep the order of their first report, and it reads the GNSS
 * at the start of a step, after the step's frames); a fresher one always counts. A GBSD
 * below the 0.1 m/s control threshold against a GNSS above it tells which. */
static void test_equally_fresh_speeds(void)
{
    make_ready(0.05); /* GBSD reports first, below the threshold */
    depth_on_gnss(&a, true, 1.2, 0.0);
    depth_step(&a, 0.0, out);
    CHECK(a.last.speed_known && !a.last.enabled);
    depth_on_gnss(&a, true, 1.2, 0.01); /* fresher: the GNSS counts */
    depth_step(&a, 0.01, out);
    CHECK(a.last.enabled);
    make_ready(-1.0); /* no GBSD yet */
    hal_can_frame_t g = gbsd(0.05);
    depth_on_gnss(&a, true, 1.2, 0.0); /* read at the step, after the GBSD frame */
    depth_on_frame(&a, &g, 0.0, out);
    depth_step(&a, 0.0, out);
    CHECK(a.last.speed_known && !a.last.enabled);
    make_ready(-1.0);
    depth_on_gnss(&a, true, 1.2, 0.0); /* the GNSS reports a step before the GBSD */
    depth_step(&a, 0.0, out);
    CHECK(a.last.enabled);
    depth_on_frame(&a, &g, 0.01, out);
    depth_on_gnss(&a, true, 1.2, 0.01);
    depth_step(&a, 0.01, out);
    CHECK(a.last.enabled);
    depth_on_frame(&a, &g, 0.02, out); /* fresher: the GBSD counts */
    depth_step(&a, 0.02, out);
    CHECK(!a.last.enabled);
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
    CHECK(param_set(refs, n, "hold_time_constant_s", "3") == PARAM_OK &&
          cfg.hold.time_constant_s == 3);
    CHECK(param_set(refs, n, "hold_gain_per_s", "4") == PARAM_OK && cfg.hold.gain_per_s == 4);
    CHECK(param_set(refs, n, "hold_speed_mm_s", "8") == PARAM_OK && cfg.hold.speed_mm_s == 8);
    CHECK(param_set(refs, n, "kp1", "1") == PARAM_UNKNOWN);
}

/* One step at i * 10 ms with the rod at position_inc (TPDO1, 0.01 mm, statusword sw), an
 * inclinometer frame (X = 3700 + i % 2, status x_status) and a ground speed of speed_mps;
 * returns the RPDO2's target velocity, *command the status frame's roller position command
 * (-1 on steps without one). */
static long long hold_step(int i, uint16_t sw, int32_t position_inc, uint8_t x_status,
                           double speed_mps, long long *command)
{
    double t = (double)i * 0.01;
    hal_can_frame_t pos = tpdo1_at(sw, position_inc);
    depth_on_frame(&a, &pos, t, out);
    hal_can_frame_t inc = inclinometer((uint16_t)(3700 + i % 2), x_status);
    depth_on_frame(&a, &inc, t, out);
    hal_can_frame_t g = gbsd(speed_mps);
    depth_on_frame(&a, &g, t, out);
    size_t n = depth_step(&a, t, out);
    struct servo_cylinder_pdo_rpdo2_t pdo;
    const hal_can_frame_t *p = find(n, 0x302);
    servo_cylinder_pdo_rpdo2_unpack(&pdo, p->data, p->len);
    const hal_can_frame_t *st = find(n, SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID);
    *command = -1;
    if (st != NULL) {
        struct sowing_depth_depth_controller_status_t m;
        sowing_depth_depth_controller_status_unpack(&m, st->data, st->len);
        *command = m.dc_roller_position_command;
        CHECK_INT(m.dc_sensor_fault, x_status != 0);
    }
    return pdo.target_velocity;
}

static void test_hold_at_mean_position(void)
{
    make_ready(1.0);
    long long cmd;
    /* 10 s of valid control with the rod swinging 40.00 / 42.00 mm: the mean settles at 41 mm
     * (first sample 40 mm, tau = 2 s: 1 mm * e^-5 = 0.007 mm left) and no hold acts */
    for (int i = 0; i < 1000; i++) {
        hold_step(i, 0x0237, i % 2 ? 4200 : 4000, 0, 1.0, &cmd);
        CHECK(!a.last.holding);
        if (cmd >= 0) {
            CHECK_INT(cmd, 0); /* regulating: no position command */
        }
    }
    CHECK(a.hold.has_mean && a.hold.has_target);
    CHECK_NEAR(a.hold.mean_mm, 41.0, 0.01);
    /* the target: the mean when the last new X voltage came (before step 999's tracking) */
    double mean = a.hold.target_mm;
    CHECK_NEAR(mean, 41.0, 0.01);
    /* the sensor fails with the rod at 39.00 mm: drive back at 5/s * (h - p), ~10 mm/s */
    double last_mean = a.hold.mean_mm;
    long long v = hold_step(1000, 0x0237, 3900, 1, 1.0, &cmd);
    CHECK(a.last.holding && !a.last.valid);
    CHECK_INT(v, (long long)rint(5.0 * (mean - 39.0) * 100.0));
    CHECK_INT(cmd, (long long)rint(mean * 100.0)); /* the status carries the hold target */
    CHECK_NEAR(a.hold.mean_mm, last_mean, 0); /* no tracking while the depth is invalid */
    CHECK_NEAR(a.hold.target_mm, mean, 0);
    /* past the mean: back the other way; far off: bounded at 10 mm/s */
    CHECK_INT(hold_step(1001, 0x0237, 4150, 1, 1.0, &cmd),
              (long long)rint(5.0 * (mean - 41.5) * 100.0));
    CHECK_INT(hold_step(1002, 0x0237, 2000, 1, 1.0, &cmd), 1000);
    CHECK_INT(hold_step(1003, 0x0237, 9000, 1, 1.0, &cmd), -1000);
    /* the drive not in Operation enabled (Switched on): nothing to drive, 0 */
    CHECK_INT(hold_step(1004, 0x0233, 3900, 1, 1.0, &cmd), 0);
    CHECK(!a.last.holding);
    /* standstill (control disabled): 0 as before, and the mean is forgotten, so a machine
     * that drives off again with the sensor still dead holds where the roller is */
    CHECK_INT(hold_step(1005, 0x0237, 3900, 1, 0.0, &cmd), 0);
    CHECK(!a.last.holding && !a.hold.has_mean && !a.hold.has_target);
    CHECK_INT(hold_step(1006, 0x0237, 3900, 1, 1.0, &cmd), 0);
    CHECK(!a.last.holding);
    /* valid again: tracking starts afresh from the rod's position */
    hold_step(1007, 0x0237, 4321, 0, 1.0, &cmd);
    CHECK(a.last.valid && a.hold.has_mean);
    CHECK_NEAR(a.hold.mean_mm, 43.21, 0);
}

/* A frozen X voltage: the loop steers on the dead reading for 0.2 s and the mean follows the
 * rod it moves; the hold target is the mean at the last new X voltage, before any of that. */
static void test_hold_target_at_last_sign_of_life(void)
{
    make_ready(1.0);
    int fault;
    for (int i = 0; i < 300; i++) { /* live X, the rod at 40.00 mm */
        hal_can_frame_t pos = tpdo1_at(0x0237, 4000);
        depth_on_frame(&a, &pos, (double)i * 0.01, out);
        step_at(i, 3700 + i % 2, 0, &fault);
    }
    CHECK_NEAR(a.hold.mean_mm, 40.0, 0);
    for (int i = 300; i < 322; i++) { /* X frozen at 3701 since 2.99 s, the rod at 38 mm */
        hal_can_frame_t pos = tpdo1_at(0x0237, 3800);
        depth_on_frame(&a, &pos, (double)i * 0.01, out);
        step_at(i, 3701, 0, &fault);
    }
    CHECK(a.last.frozen && a.last.holding);
    CHECK(a.hold.mean_mm < 39.99); /* the mean took 0.2 s of steering on a dead reading */
    CHECK_NEAR(a.hold.target_mm, 40.0, 0);
    CHECK_INT(a.last.target_velocity, 1000); /* 5/s * (40 - 38) = 10 mm/s */
}

/* The hold loop against a rod that follows its speed command with the position one step old
 * (TPDO1 of the previous SYNC): from 2 mm off it comes back without overshoot, within 0.05 mm
 * in under 1 s. */
static void test_hold_loop_no_overshoot(void)
{
    rhold_params_t p;
    rhold_defaults(&p);
    rhold_state_t s;
    rhold_reset(&s);
    rhold_track(&p, &s, 41.0, 0.01);
    rhold_mark(&s);
    double x = 39.0, seen = 39.0, max_x = x;
    int settled_at = -1;
    for (int k = 0; k < 300; k++) {
        double v = rhold_speed(&p, &s, seen);
        CHECK(fabs(v) <= p.speed_mm_s);
        seen = x; /* the next step sees this step's position */
        x += v * 0.01;
        max_x = fmax(max_x, x);
        if (settled_at < 0 && fabs(x - 41.0) <= 0.05) {
            settled_at = k;
        }
    }
    CHECK(max_x <= 41.0);
    CHECK(settled_at > 0 && settled_at < 100);
}

static void test_hold_off_and_config(void)
{
    depth_config_t cfg;
    depth_config_defaults(&cfg);
    param_ref_t refs[DEPTH_PARAM_COUNT];
    size_t n = depth_param_refs(&cfg, refs);
    CHECK(param_set(refs, n, "hold_gain_per_s", "0") == PARAM_OK);
    make_ready_with(&cfg, 1.0);
    long long cmd;
    for (int i = 0; i < 100; i++) {
        hold_step(i, 0x0237, 4000, 0, 1.0, &cmd);
    }
    /* k = 0: the roller holds where it is (the behaviour before issue #16) */
    CHECK_INT(hold_step(100, 0x0237, 3000, 1, 1.0, &cmd), 0);
    CHECK(a.last.holding);

    char err[128];
    depth_config_defaults(&cfg);
    n = depth_param_refs(&cfg, refs);
    CHECK(param_set(refs, n, "hold_time_constant_s", "0") == PARAM_OK);
    CHECK_INT(depth_config_check(&cfg, err, sizeof err), -1);
    CHECK(strstr(err, "hold_time_constant_s") != NULL);
    depth_config_defaults(&cfg);
    CHECK(param_set(refs, n, "hold_gain_per_s", "-1") == PARAM_OK);
    CHECK_INT(depth_config_check(&cfg, err, sizeof err), -1);
    CHECK(strstr(err, "hold_gain_per_s") != NULL);
    depth_config_defaults(&cfg);
    CHECK(param_set(refs, n, "hold_speed_mm_s", "60") == PARAM_OK);
    CHECK_INT(depth_config_check(&cfg, err, sizeof err), -1);
    CHECK(strstr(err, "hold_speed_mm_s") != NULL);
}

TEST_MAIN("depth_adapter", test_nmt_start, test_controlwords, test_depth_filter,
          test_control_step, test_enable_conditions, test_equally_fresh_speeds,
          test_frozen_inclinometer,
          test_frozen_check_off, test_bad_status_holds, test_config_check,
          test_hold_at_mean_position, test_hold_target_at_last_sign_of_life,
          test_hold_loop_no_overshoot, test_hold_off_and_config)
