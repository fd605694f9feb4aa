/* Bus spec strings. */
#include <string.h>

#include "bus_spec.h"
#include "check.h"

static void test_socketcand(void)
{
    bus_spec_t s;
    char err[256];
    CHECK_INT(bus_spec_parse("socketcand:127.0.0.1:29536/can0", &s, err, sizeof err), 0);
    CHECK_INT(s.transport, BUS_SOCKETCAND);
    CHECK(strcmp(s.host, "127.0.0.1") == 0);
    CHECK_INT(s.port, 29536);
    CHECK(strcmp(s.channel, "can0") == 0);
    CHECK_INT(bus_spec_parse("socketcand:localhost:1234", &s, err, sizeof err), 0);
    CHECK(strcmp(s.host, "localhost") == 0 && s.port == 1234 && strcmp(s.channel, "can0") == 0);
    CHECK_INT(bus_spec_parse("SocketCAND:rig-pc.local:29536/vcan1,tcp_tune=true", &s, err,
                             sizeof err), 0);
    CHECK(strcmp(s.host, "rig-pc.local") == 0 && strcmp(s.channel, "vcan1") == 0);
    CHECK_INT(bus_spec_parse("socketcand:::1:29536/can0", &s, err, sizeof err), 0);
    CHECK(strcmp(s.host, "::1") == 0 && s.port == 29536);
    /* busy polling: off unless asked; other options are ignored */
    CHECK_INT(s.busy_poll_us, 0);
    CHECK_INT(bus_spec_parse("socketcand:h:1/can0,client=agrihil,busy_poll_us=300", &s, err,
                             sizeof err), 0);
    CHECK_INT(s.busy_poll_us, 300);
    CHECK(strcmp(s.channel, "can0") == 0);
}

static void test_socketcan(void)
{
    bus_spec_t s;
    char err[256];
    CHECK_INT(bus_spec_parse("socketcan:vcan0", &s, err, sizeof err), 0);
    CHECK_INT(s.transport, BUS_SOCKETCAN);
    CHECK(strcmp(s.iface, "vcan0") == 0);
    CHECK_INT(bus_spec_parse("socketcan:can0,bitrate=250000", &s, err, sizeof err), 0);
    CHECK(strcmp(s.iface, "can0") == 0);
}

static void test_errors(void)
{
    bus_spec_t s;
    char err[256];
    CHECK_INT(bus_spec_parse("", &s, err, sizeof err), -1);
    CHECK(strstr(err, "empty") != NULL);
    CHECK_INT(bus_spec_parse("virtual", &s, err, sizeof err), -1);
    CHECK(strstr(err, "unsupported transport 'virtual'") != NULL);
    CHECK_INT(bus_spec_parse("socketcan", &s, err, sizeof err), -1);
    CHECK(strstr(err, "interface") != NULL);
    CHECK_INT(bus_spec_parse("socketcan:a/b", &s, err, sizeof err), -1);
    CHECK_INT(bus_spec_parse("socketcand:127.0.0.1", &s, err, sizeof err), -1);
    CHECK(strstr(err, "HOST:PORT") != NULL);
    CHECK_INT(bus_spec_parse("socketcand:127.0.0.1:http", &s, err, sizeof err), -1);
    CHECK(strstr(err, "port") != NULL);
    CHECK_INT(bus_spec_parse("socketcand:127.0.0.1:70000", &s, err, sizeof err), -1);
    CHECK_INT(bus_spec_parse("socketcand::29536", &s, err, sizeof err), -1);
    CHECK(strstr(err, "host") != NULL);
    CHECK_INT(bus_spec_parse("socketcand:h:1/", &s, err, sizeof err), -1);
    CHECK(strstr(err, "channel") != NULL);
    CHECK_INT(bus_spec_parse("socketcand:h:1,oops", &s, err, sizeof err), -1);
    CHECK(strstr(err, "key=value") != NULL);
    CHECK_INT(bus_spec_parse("socketcand:h:1,busy_poll_us=fast", &s, err, sizeof err), -1);
    CHECK(strstr(err, "busy_poll_us") != NULL);
    CHECK_INT(bus_spec_parse("socketcand:h:1,busy_poll_us=-5", &s, err, sizeof err), -1);
}

TEST_MAIN("bus_spec", test_socketcand, test_socketcan, test_errors)
