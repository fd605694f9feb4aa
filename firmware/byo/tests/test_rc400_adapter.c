/* The RC-400 adapter and its generated bus layer: the database's layout (big endian, kg/h,
 * multiplexed rows, enums) round-trips, and each rule of dbc_adapter.py holds. */
#include <string.h>

#include "check.h"
#include "fertilizer_rc400_adapter.h"

static hal_can_frame_t command(uint8_t program, uint8_t run, double target_gps, double rate,
                               double width_mm, uint8_t source, uint8_t sections)
{
    struct ratemaster_rc400_rc_command_t m;
    memset(&m, 0, sizeof m);
    m.rate_kg_ha = ratemaster_rc400_rc_command_rate_kg_ha_encode(rate);
    m.width_mm = ratemaster_rc400_rc_command_width_mm_encode(width_mm);
    m.target_kg_h = ratemaster_rc400_rc_command_target_kg_h_encode(target_gps * 3.6);
    m.program = program;
    m.run = run;
    m.speed_src = source;
    m.sections = sections;
    hal_can_frame_t f = {RATEMASTER_RC400_RC_COMMAND_FRAME_ID, false, 8, {0}};
    ratemaster_rc400_rc_command_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t row(uint8_t row_no, double gps, uint8_t state, uint8_t diag)
{
    struct ratemaster_rc400_rh_row_flow_t m;
    memset(&m, 0, sizeof m);
    m.row_no = row_no;
    uint16_t raw = ratemaster_rc400_rh_row_flow_flow_kg_h_1_encode(gps * 3.6);
    /* the multiplexer decides which row's signals are packed */
    m.flow_kg_h_1 = m.flow_kg_h_2 = m.flow_kg_h_3 = m.flow_kg_h_4 = raw;
    m.state_1 = m.state_2 = m.state_3 = m.state_4 = state;
    m.diag_1 = m.diag_2 = m.diag_3 = m.diag_4 = diag;
    hal_can_frame_t f = {RATEMASTER_RC400_RH_ROW_FLOW_FRAME_ID, false, 8, {0}};
    ratemaster_rc400_rh_row_flow_pack(f.data, &m, sizeof f.data);
    return f;
}

static hal_can_frame_t radar(uint32_t source_address, uint16_t raw)
{
    struct ratemaster_rc400_ground_based_speed_dist_t m = {raw};
    hal_can_frame_t f = {(RATEMASTER_RC400_GROUND_BASED_SPEED_DIST_FRAME_ID & ~0xFFu) |
                             source_address,
                         true, 8, {0}};
    ratemaster_rc400_ground_based_speed_dist_pack(f.data, &m, sizeof f.data);
    return f;
}

static void init(rc400_adapter_t *a, ppid_law_t law)
{
    rc400_config_t cfg;
    rc400_config_defaults(&cfg, law);
    rc400_init(a, &cfg);
}

static int16_t drive_mv(const hal_can_frame_t *out, size_t n)
{
    CHECK(n >= 2);
    const hal_can_frame_t *f = &out[n - 1]; /* the command ends every step */
    CHECK_INT(f->id, 0x220);
    struct ratemaster_rc400_drive_command_t m;
    CHECK_INT(ratemaster_rc400_drive_command_unpack(&m, f->data, f->len), 0);
    return m.speed_ref;
}

static void test_the_layout_is_big_endian_and_round_trips(void)
{
    hal_can_frame_t f = command(2, 1, 23.0, 200.0, 2400.0, 0, 4);
    /* RateKgHa 200.0 kg/ha = raw 2000 = 0x07D0, Motorola: high byte first */
    CHECK_INT(f.data[0], 0x07);
    CHECK_INT(f.data[1], 0xD0);
    CHECK_INT(f.data[2] << 8 | f.data[3], 2400);
    struct ratemaster_rc400_rc_command_t m;
    CHECK_INT(ratemaster_rc400_rc_command_unpack(&m, f.data, f.len), 0);
    CHECK_NEAR(ratemaster_rc400_rc_command_target_kg_h_decode(m.target_kg_h), 82.8, 0.018);
    CHECK_INT(m.program, 2);
    CHECK_INT(m.run, 1);
    CHECK_INT(m.sections, 4);
    CHECK(ratemaster_rc400_rc_command_unpack(&m, f.data, 7) < 0); /* too short */
}

static void test_rows_come_by_multiplexer_in_kg_per_hour(void)
{
    rc400_adapter_t a;
    init(&a, PPID_LAW_PHYSICAL);
    hal_can_frame_t f = row(2, 12.34, 1, 0);
    CHECK_INT(f.data[0], 2);
    rc400_on_frame(&a, &f);
    CHECK(a.rows[2].seen && !a.rows[0].seen && !a.rows[1].seen && !a.rows[3].seen);
    CHECK_NEAR(a.rows[2].flow_gps, 12.34, 1e-12);
    CHECK(a.rows[2].measuring && !a.rows[2].overrange);
    f = row(0, 5.0, 0, 1); /* Warmup, CapOverrange */
    rc400_on_frame(&a, &f);
    CHECK(a.rows[0].seen && !a.rows[0].measuring && a.rows[0].overrange);
    rc400_adapter_t before = a;
    f = row(7, 5.0, 1, 0); /* no such multiplexer value: ignored */
    f.data[0] = 7;
    rc400_on_frame(&a, &f);
    f = row(1, 5.0, 1, 0);
    f.len = 4; /* short: ignored */
    rc400_on_frame(&a, &f);
    CHECK(memcmp(&before, &a, sizeof a) == 0);
}

static void test_field_target_from_the_chosen_speed(void)
{
    rc400_adapter_t a;
    init(&a, PPID_LAW_PHYSICAL);
    hal_can_frame_t f = command(1, 1, 0.0, 200.0, 2400.0, 0, 4); /* SpeedRelated, Radar */
    rc400_on_frame(&a, &f);
    CHECK_INT(rc400_mode(&a), RC400_MODE_FIELD);
    CHECK_NEAR(rc400_target_gps(&a), 0.0, 0.0); /* no speed yet */
    f = radar(0x2A, 1500);                       /* any source address */
    rc400_on_frame(&a, &f);
    CHECK_NEAR(rc400_target_gps(&a), 0.1 * 200.0 * 2.4 * 1.5 / 4.0, 1e-12);
    f = radar(0xF0, 0xFFFF); /* J1939 not available: no speed */
    rc400_on_frame(&a, &f);
    CHECK_NEAR(rc400_target_gps(&a), 0.0, 0.0);
    /* the ground wheel in km/h; Sections 0 counts as 1 row */
    struct ratemaster_rc400_ws_ground_speed_t ws = {
        ratemaster_rc400_ws_ground_speed_speed_kmh_encode(7.2)};
    f = (hal_can_frame_t){RATEMASTER_RC400_WS_GROUND_SPEED_FRAME_ID, false, 8, {0}};
    ratemaster_rc400_ws_ground_speed_pack(f.data, &ws, sizeof f.data);
    CHECK_INT(f.data[0] << 8 | f.data[1], 2000); /* 7.2 km/h in 0.0036 km/h */
    rc400_on_frame(&a, &f);
    f = command(1, 1, 0.0, 200.0, 2400.0, 1, 0); /* WheelSensor */
    rc400_on_frame(&a, &f);
    CHECK_NEAR(rc400_target_gps(&a), 0.1 * 200.0 * 2.4 * 2.0, 1e-12);
    f = command(1, 1, 0.0, 200.0, 2400.0, 3, 4); /* None */
    rc400_on_frame(&a, &f);
    CHECK_NEAR(rc400_target_gps(&a), 0.0, 0.0);
    f = command(1, 0, 0.0, 200.0, 2400.0, 1, 4); /* Run = 0 */
    rc400_on_frame(&a, &f);
    CHECK_NEAR(rc400_target_gps(&a), 0.0, 0.0);
}

static void test_programs_select_the_law_and_the_status_says_which(void)
{
    rc400_adapter_t a;
    init(&a, PPID_LAW_PHYSICAL);
    hal_can_frame_t out[RC400_MAX_OUT];
    CHECK_INT(rc400_mode(&a), RC400_MODE_BENCH); /* before any set-point */
    hal_can_frame_t f = command(3, 1, 23.0, 0.0, 0.0, 0, 4); /* FixedSpeed: open loop */
    rc400_on_frame(&a, &f);
    size_t n = rc400_step(&a, out);
    CHECK_INT(n, 3);
    CHECK_INT(a.last.law, PPID_LAW_OPEN_LOOP);
    CHECK(!a.last.alarm); /* open loop needs no sensor */
    struct ratemaster_rc400_rc_status_t st;
    CHECK_INT(out[0].id, 0x292);
    CHECK_INT(ratemaster_rc400_rc_status_unpack(&st, out[0].data, out[0].len), 0);
    CHECK_INT(st.program_active, RATEMASTER_RC400_RC_STATUS_PROGRAM_ACTIVE_FIXED_SPEED_CHOICE);
    CHECK_INT(st.running, 1);
    CHECK_NEAR(ratemaster_rc400_rc_status_target_kg_h_decode(st.target_kg_h), 82.8, 0.018);
    CHECK_INT(drive_mv(out, n), st.drive_mv);
    CHECK(st.drive_mv > 1000);
    f = command(0, 1, 23.0, 0.0, 0.0, 0, 4); /* Off: bench flow, closed loop */
    rc400_on_frame(&a, &f);
    rc400_step(&a, out);
    CHECK_INT(a.last.mode, RC400_MODE_BENCH);
    CHECK_INT(a.last.law, PPID_LAW_PHYSICAL);
    CHECK(a.last.alarm); /* enabled, closed loop, no row */
}

static void test_rows_are_valid_while_fresh_and_plausible(void)
{
    rc400_adapter_t a;
    init(&a, PPID_LAW_PHYSICAL);
    hal_can_frame_t out[RC400_MAX_OUT];
    hal_can_frame_t f = command(2, 1, 20.0, 0.0, 0.0, 0, 4);
    rc400_on_frame(&a, &f);
    f = row(0, 19.0, 1, 0);
    rc400_on_frame(&a, &f);
    f = row(1, 80.0, 1, 0); /* above 3 Q + 5: implausible */
    rc400_on_frame(&a, &f);
    rc400_step(&a, out);
    CHECK(a.last.has_measurement && a.last.new_report);
    CHECK_NEAR(a.last.measured_gps, 19.0, 1e-12);
    for (int i = 0; i < 25; i++) { /* 2.5 s at 0.1 s: still valid at 25 steps old */
        rc400_step(&a, out);
        CHECK(!a.last.new_report);
    }
    CHECK(a.last.has_measurement);
    rc400_step(&a, out);
    CHECK(!a.last.has_measurement);
}

static void test_boot_frames_and_status_cadence(void)
{
    hal_can_frame_t boot[RC400_BOOT_FRAMES];
    CHECK_INT(rc400_boot_frames(boot), 2);
    CHECK_INT(boot[0].id, 0x712);
    CHECK_INT(boot[0].len, 1);
    CHECK_INT(boot[0].data[0], 0x00);
    static const uint8_t sdo[8] = {0x23, 0x16, 0x10, 0x01, 0x2C, 0x01, 0x12, 0x00};
    CHECK_INT(boot[1].id, 0x620);
    CHECK(boot[1].len == 8 && memcmp(boot[1].data, sdo, 8) == 0);
    rc400_adapter_t a;
    init(&a, PPID_LAW_PHYSICAL);
    hal_can_frame_t out[RC400_MAX_OUT];
    static const size_t want[6] = {3, 2, 2, 2, 2, 3}; /* status every 5th step, 500 ms */
    for (int i = 0; i < 6; i++) {
        size_t n = rc400_step(&a, out);
        CHECK_INT(n, want[i]);
        CHECK_INT(out[n - 2].id, 0x712);
        CHECK_INT(out[n - 2].data[0], 0x05);
        CHECK_INT(drive_mv(out, n), 0);
    }
}

TEST_MAIN("rc400_adapter", test_the_layout_is_big_endian_and_round_trips,
          test_rows_come_by_multiplexer_in_kg_per_hour, test_field_target_from_the_chosen_speed,
          test_programs_select_the_law_and_the_status_says_which,
          test_rows_are_valid_while_fresh_and_plausible, test_boot_frames_and_status_cadence)
