/* The DP-200 adapter and its generated bus layer: the database's layout (big endian, cm, V,
 * a multiplexed sensor hub, enums) reaches the law as the Python build reads it, and the
 * drive's configuration is the Python build's, its refusals and timeouts errors that say
 * which object. */
#include <string.h>

#include "check.h"
#include "depth_dp200_adapter.h"

static void init(dp200_adapter_t *a)
{
    dp200_config_t cfg;
    dp200_config_defaults(&cfg);
    dp200_init(a, &cfg);
}

static hal_can_frame_t std_frame(uint32_t id, uint8_t len)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    return f;
}

static hal_can_frame_t drive_heartbeat(uint8_t state)
{
    hal_can_frame_t f = std_frame(0x702, 1);
    f.data[0] = state;
    return f;
}

/* The drive's answer to an SDO request: confirmation (0x60) or abort (0x80, code). */
static hal_can_frame_t answer(const hal_can_frame_t *request, uint8_t command, uint32_t code)
{
    struct depthpro_dp200_dp_drive_sdo_request_t q;
    CHECK_INT(depthpro_dp200_dp_drive_sdo_request_unpack(&q, request->data, request->len), 0);
    struct depthpro_dp200_dp_drive_sdo_response_t r = {command, q.index, q.sub_index, code};
    hal_can_frame_t f = std_frame(0x582, 8);
    depthpro_dp200_dp_drive_sdo_response_pack(f.data, &r, sizeof f.data);
    return f;
}

static int status_state(const hal_can_frame_t *out, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (out[i].id == 0x18A) {
            struct depthpro_dp200_dp_status_t st;
            CHECK_INT(depthpro_dp200_dp_status_unpack(&st, out[i].data, out[i].len), 0);
            return st.state;
        }
    }
    return -1;
}

static void test_python_rounding(void)
{
    CHECK(dp200_py_round(0.15, 1) == 0.1); /* 0.1499999... */
    CHECK(dp200_py_round(-0.15, 1) == -0.1);
    CHECK(dp200_py_round(12.25, 1) == 12.2); /* an exact tie: half to even */
    CHECK(dp200_py_round(12.35, 1) == 12.3); /* 12.3499999... */
    CHECK(dp200_py_round(2.675, 2) == 2.67);
    CHECK(dp200_py_round(2.5, 0) == 2.0 && dp200_py_round(3.5, 0) == 4.0);
    CHECK(dp200_py_round(3698 * 0.001, 3) * 1000.0 != 3698.0 ||
          dp200_py_round(dp200_py_round(3698 * 0.001, 3) * 1000.0, 0) == 3698.0);
}

static void test_the_layout_reaches_the_law(void)
{
    dp200_adapter_t a;
    init(&a);
    hal_can_frame_t out[DP200_MAX_OUT];
    /* the job: 3.57 cm, On, AutoDepth; big endian: raw 357 = 0x0165 high byte first */
    struct depthpro_dp200_dp_setpoint_t sp = {357, 0, 2, 2, 1};
    hal_can_frame_t f = std_frame(0x20A, 8);
    depthpro_dp200_dp_setpoint_pack(f.data, &sp, sizeof f.data);
    CHECK_INT(f.data[0], 0x01);
    CHECK_INT(f.data[1], 0x65);
    CHECK_INT(dp200_on_frame(&a, &f, out), 0);
    CHECK(a.law.target_mm == 35.7); /* the double Python's round(3.57 x 10, 1) gives */
    CHECK(a.law.terminal_on && a.law.automatic && !a.law.manual);
    /* the inclinometer: 3.698 V on channel 0, Valid */
    struct depthpro_dp200_dp_sensor_hub_t hub;
    memset(&hub, 0, sizeof hub);
    hub.channel = 0;
    hub.arm_tilt_x = 3698;
    hub.tilt_x_state = 1;
    f = std_frame(0x1A5, 8);
    depthpro_dp200_dp_sensor_hub_pack(f.data, &hub, sizeof f.data);
    dp200_on_frame(&a, &f, out);
    CHECK(a.law.have_depth && a.law.depth_ok);
    CHECK(a.law.last_x_mv == 3698.0);
    CHECK(a.law.depth_mm == -0.065 * 3698.0 + 270.35);
    /* the draw-wire channel, an undefined channel and a short frame leave the law as it was */
    dp200_adapter_t before = a;
    hub.channel = 1;
    hub.roller_travel = 12345;
    depthpro_dp200_dp_sensor_hub_pack(f.data, &hub, sizeof f.data);
    dp200_on_frame(&a, &f, out);
    f.data[0] = 5;
    dp200_on_frame(&a, &f, out);
    f.data[0] = 0;
    f.len = 7;
    dp200_on_frame(&a, &f, out);
    CHECK(memcmp(&before.law, &a.law, sizeof a.law) == 0);
    /* OpenCircuit: invalid */
    hub.channel = 0;
    hub.tilt_x_state = 2;
    f = std_frame(0x1A5, 8);
    depthpro_dp200_dp_sensor_hub_pack(f.data, &hub, sizeof f.data);
    dp200_on_frame(&a, &f, out);
    CHECK(!a.law.depth_ok);
}

static void test_the_configuration_is_the_python_builds(void)
{
    dp200_adapter_t a;
    init(&a);
    CHECK_INT(a.drive_node, 2);
    /* invalidations first, RPDO1 at 0x302 mapped, ..., the heartbeat time last */
    CHECK_INT(a.configuration[0].index, 0x1400);
    CHECK_INT(a.configuration[0].value, 0x80000202u);
    CHECK_INT(a.configuration[5].index, 0x1802);
    CHECK_INT(a.configuration[5].value, 0x80000382u);
    CHECK_INT(a.configuration[6].index, 0x1600);
    CHECK_INT(a.configuration[7].value, 0x60FF0020u);
    CHECK_INT(a.configuration[11].index, 0x1400);
    CHECK_INT(a.configuration[11].value, 0x302);
    CHECK_INT(a.configuration[20].value, 0x1A2);
    CHECK_INT(a.configuration[26].value, 100); /* TPDO3 event timer, ms */
    CHECK_INT(a.configuration[29].index, 0x1017);
    CHECK_INT(a.configuration[29].size, 2);
    hal_can_frame_t out[DP200_MAX_OUT];
    hal_can_frame_t f = drive_heartbeat(0x00);
    size_t n = dp200_on_frame(&a, &f, out);
    CHECK_INT(n, 30);
    static const uint8_t first[8] = {0x23, 0x00, 0x14, 0x01, 0x02, 0x02, 0x00, 0x80};
    CHECK(out[0].id == 0x602 && out[0].len == 8 && memcmp(out[0].data, first, 8) == 0);
    static const uint8_t count[8] = {0x2F, 0x00, 0x16, 0x00, 0x02, 0x00, 0x00, 0x00};
    CHECK(memcmp(out[9].data, count, 8) == 0); /* RPDO1's mapping count: 1 byte, ccs 0x2F */
    hal_can_frame_t requests[DP200_MAX_OUT];
    memcpy(requests, out, sizeof requests);
    hal_can_frame_t step_out[DP200_MAX_OUT];
    for (size_t i = 0; i < 29; i++) {
        hal_can_frame_t r = answer(&requests[i], 0x60, 0);
        CHECK_INT(dp200_on_frame(&a, &r, out), 0);
    }
    n = dp200_step(&a, step_out); /* one write unconfirmed: no start */
    CHECK(step_out[0].id != 0x000);
    hal_can_frame_t r = answer(&requests[29], 0x60, 0);
    dp200_on_frame(&a, &r, out);
    n = dp200_step(&a, step_out);
    CHECK(step_out[0].id == 0x000 && step_out[0].len == 2 && step_out[0].data[0] == 0x01 &&
          step_out[0].data[1] == 0x02);
    CHECK_INT(step_out[n - 1].id, 0x302); /* the command last */
    f = drive_heartbeat(0x05);
    dp200_on_frame(&a, &f, out);
    n = dp200_step(&a, step_out);
    static const uint8_t mode[8] = {0x2F, 0x60, 0x60, 0x00, 0x03, 0x00, 0x00, 0x00};
    CHECK(step_out[0].id == 0x602 && memcmp(step_out[0].data, mode, 8) == 0);
    r = answer(&step_out[0], 0x60, 0);
    dp200_on_frame(&a, &r, out);
    CHECK(dp200_error(&a) == NULL);
    for (int i = 0; i < 100; i++) { /* no further writes while the drive runs */
        n = dp200_step(&a, step_out);
        CHECK(step_out[0].id != 0x602 && step_out[0].id != 0x000);
    }
    CHECK(dp200_error(&a) == NULL);
}

static void test_an_abort_names_the_object_and_the_code(void)
{
    dp200_adapter_t a;
    init(&a);
    hal_can_frame_t out[DP200_MAX_OUT], requests[DP200_MAX_OUT], step_out[DP200_MAX_OUT];
    hal_can_frame_t f = drive_heartbeat(0x00);
    dp200_on_frame(&a, &f, requests);
    for (size_t i = 0; i < 30; i++) { /* 0x1600:01 confirmed, then 0x1600:02 refused */
        hal_can_frame_t r = answer(&requests[i], i == 8 ? 0x80 : 0x60,
                                   i == 8 ? 0x06040041u : 0);
        dp200_on_frame(&a, &r, out);
    }
    const char *why = dp200_error(&a);
    CHECK(why != NULL);
    CHECK(why != NULL && strstr(why, "0x1600:02 = 0x60400010 refused (SDO abort 0x06040041: "
                                     "object cannot be mapped to the PDO)") != NULL);
    size_t n = dp200_step(&a, step_out); /* no start, Fault, the drive commanded nothing */
    CHECK(step_out[0].id != 0x000);
    CHECK_INT(status_state(step_out, n), DEPTHPRO_DP200_DP_STATUS_STATE_FAULT_CHOICE);
    f = drive_heartbeat(0x7F); /* refused: nothing more until the drive boots */
    CHECK_INT(dp200_on_frame(&a, &f, out), 0);
    f = drive_heartbeat(0x00);
    CHECK_INT(dp200_on_frame(&a, &f, out), 30);
    CHECK(dp200_error(&a) == NULL);
}

static void test_answers_out_of_turn_are_errors(void)
{
    dp200_adapter_t a;
    init(&a);
    hal_can_frame_t out[DP200_MAX_OUT], requests[DP200_MAX_OUT];
    hal_can_frame_t f = drive_heartbeat(0x00);
    dp200_on_frame(&a, &f, requests);
    hal_can_frame_t r = answer(&requests[1], 0x60, 0); /* for 0x1401:01, not 0x1400:01 */
    dp200_on_frame(&a, &r, out);
    CHECK(dp200_error(&a) != NULL &&
          strstr(dp200_error(&a), "0x1400:01: answered for 0x1401:01") != NULL);
    init(&a);
    dp200_on_frame(&a, &f, requests);
    r = answer(&requests[0], 0x4B, 0); /* an upload response */
    dp200_on_frame(&a, &r, out);
    CHECK(dp200_error(&a) != NULL &&
          strstr(dp200_error(&a), "0x1400:01: unexpected answer 0x4B") != NULL);
}

static void test_a_silent_drive_times_out(void)
{
    dp200_adapter_t a;
    init(&a);
    hal_can_frame_t out[DP200_MAX_OUT], requests[DP200_MAX_OUT];
    hal_can_frame_t f = drive_heartbeat(0x00);
    dp200_on_frame(&a, &f, requests);
    for (int i = 0; i < 3; i++) {
        hal_can_frame_t r = answer(&requests[i], 0x60, 0);
        dp200_on_frame(&a, &r, out);
    }
    for (int i = 0; i <= 50; i++) { /* 0.5 s at 10 ms: still waiting */
        dp200_step(&a, out);
    }
    CHECK(dp200_error(&a) == NULL);
    size_t n = dp200_step(&a, out);
    const char *why = dp200_error(&a);
    CHECK(why != NULL && strstr(why, "0x1403") == NULL);
    CHECK(why != NULL && strstr(why, "0x1800:01 = 0x80000182: no answer from the drive "
                                     "(node 2) within 0.5 s") != NULL);
    CHECK(why != NULL && strstr(why, "3 of 30 writes confirmed") != NULL);
    (void)n;
}

TEST_MAIN("dp200_adapter", test_python_rounding, test_the_layout_reaches_the_law,
          test_the_configuration_is_the_python_builds,
          test_an_abort_names_the_object_and_the_code, test_answers_out_of_turn_are_errors,
          test_a_silent_drive_times_out)
