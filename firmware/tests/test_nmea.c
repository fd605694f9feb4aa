/* NMEA RMC/VTG speed reader. Sentences as plant_emulators/sowing_depth/nmea.py prints them. */
#include <string.h>

#include "check.h"
#include "nmea.h"

#define KN (1852.0 / 3600.0)

static void test_vtg(void)
{
    double v = -1.0;
    CHECK_INT(nmea_parse_sentence("$GNVTG,90.00,T,,M,2.160,N,4.000,K,A*1B", &v), NMEA_SPEED);
    CHECK_NEAR(v, 4.0 / 3.6, 1e-15);
    /* no fix: empty fields, mode N */
    CHECK_INT(nmea_parse_sentence("$GNVTG,,,,,,,,,N*2E", &v), NMEA_NO_FIX);
    /* wrong checksum */
    CHECK_INT(nmea_parse_sentence("$GNVTG,90.00,T,,M,2.160,N,4.000,K,A*1C", &v),
              NMEA_BAD_CHECKSUM);
    CHECK_INT(nmea_parse_sentence("$GNVTG,90.00,T,,M,2.160,N,4.000,K,A", &v),
              NMEA_BAD_CHECKSUM);
}

static void test_rmc(void)
{
    double v = -1.0;
    /* checksums computed as XOR of the body */
    CHECK_INT(nmea_parse_sentence(
                  "$GNRMC,120000.00,A,3954.12345,N,11623.12345,E,2.160,90.00,150125,,,A*41",
                  &v),
              NMEA_SPEED);
    CHECK_NEAR(v, 2.160 * KN, 1e-15);
    CHECK_INT(nmea_parse_sentence("$GNRMC,120000.00,V,,,,,,,150125,,,N*62", &v), NMEA_NO_FIX);
    /* other sentences are ignored */
    CHECK_INT(nmea_parse_sentence("$GNGGA,120000.00,,,,,0,00,99.99,,,,,,*7B", &v), NMEA_NONE);
}

static void test_feed_stream(void)
{
    nmea_reader_t r;
    nmea_init(&r);
    const char *stream = "noise$GNRMC,120000.00,A,3954.12345,N,11623.12345,E,2.160,90.00,"
                         "150125,,,A*41\r\n$GNVTG,90.00,T,,M,2.160,N,4.000,K,A*1B\r\n"
                         "$GNVTG,90.00,T,,M,2.160,N,9.000,K,A*1B\r\n$GNVTG,,,,,,,,,N*2E\r\n";
    int speeds = 0, nofix = 0;
    double last = 0.0;
    for (const char *p = stream; *p != '\0'; p++) {
        double v;
        nmea_result_t res = nmea_feed(&r, *p, &v);
        if (res == NMEA_SPEED) {
            speeds++;
            last = v;
        } else if (res == NMEA_NO_FIX) {
            nofix++;
        }
    }
    CHECK_INT(speeds, 2);
    CHECK_NEAR(last, 4.0 / 3.6, 1e-15);
    CHECK_INT(nofix, 1);
    CHECK_INT(r.bad_checksum, 1);
    /* an overlong line is dropped, the next one is read */
    nmea_init(&r);
    double v = 0.0;
    for (int i = 0; i < 200; i++) {
        nmea_feed(&r, i == 0 ? '$' : 'A', &v);
    }
    CHECK_INT(nmea_feed(&r, '\n', &v), NMEA_NONE);
    const char *ok = "$GNVTG,90.00,T,,M,2.160,N,4.000,K,A*1B\n";
    nmea_result_t res = NMEA_NONE;
    for (const char *p = ok; *p != '\0'; p++) {
        res = nmea_feed(&r, *p, &v);
    }
    CHECK_INT(res, NMEA_SPEED);
}

TEST_MAIN("nmea", test_vtg, test_rmc, test_feed_stream)
