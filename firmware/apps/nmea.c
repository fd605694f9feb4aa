#include "nmea.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#define MAX_FIELDS 20
#define KNOTS_TO_MPS (1852.0 / 3600.0)

void nmea_init(nmea_reader_t *r)
{
    memset(r, 0, sizeof *r);
}

static int hex_digit(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    return -1;
}

/* A non-negative decimal number field ("4.000"); false if empty or malformed. */
static bool parse_number(const char *field, size_t len, double *out)
{
    char text[24];
    if (len == 0 || len >= sizeof text) {
        return false;
    }
    int dots = 0;
    for (size_t i = 0; i < len; i++) {
        if (field[i] == '.') {
            dots++;
        } else if (!isdigit((unsigned char)field[i])) {
            return false;
        }
    }
    if (dots > 1) {
        return false;
    }
    memcpy(text, field, len);
    text[len] = '\0';
    *out = strtod(text, NULL);
    return true;
}

nmea_result_t nmea_parse_sentence(const char *s, double *speed_mps)
{
    if (s[0] != '$') {
        return NMEA_NONE;
    }
    const char *star = strchr(s, '*');
    if (star == NULL || hex_digit(star[1]) < 0 || hex_digit(star[2]) < 0) {
        return NMEA_BAD_CHECKSUM;
    }
    unsigned sum = 0;
    for (const char *p = s + 1; p < star; p++) {
        sum ^= (unsigned char)*p;
    }
    if (sum != (unsigned)(hex_digit(star[1]) * 16 + hex_digit(star[2]))) {
        return NMEA_BAD_CHECKSUM;
    }
    /* split the body into fields: field[i] starts at start[i], len[i] characters */
    const char *start[MAX_FIELDS];
    size_t len[MAX_FIELDS];
    size_t nfields = 0;
    const char *p = s + 1;
    for (;;) {
        const char *comma = memchr(p, ',', (size_t)(star - p));
        const char *end = comma ? comma : star;
        if (nfields == MAX_FIELDS) {
            return NMEA_NONE;
        }
        start[nfields] = p;
        len[nfields] = (size_t)(end - p);
        nfields++;
        if (comma == NULL) {
            break;
        }
        p = comma + 1;
    }
    if (len[0] != 5) {
        return NMEA_NONE; /* talker (2) + type (3) */
    }
    const char *type = start[0] + 2;
    double value;
    if (strncmp(type, "RMC", 3) == 0) {
        if (nfields < 10) {
            return NMEA_NONE;
        }
        bool active = len[2] == 1 && start[2][0] == 'A';
        bool mode_ok = nfields <= 12 || len[12] == 0 || start[12][0] != 'N';
        if (!active || !mode_ok) {
            return NMEA_NO_FIX;
        }
        if (!parse_number(start[7], len[7], &value)) {
            return NMEA_NO_FIX;
        }
        *speed_mps = value * KNOTS_TO_MPS;
        return NMEA_SPEED;
    }
    if (strncmp(type, "VTG", 3) == 0) {
        if (nfields < 9) {
            return NMEA_NONE;
        }
        bool mode_ok = nfields <= 9 || (len[9] > 0 && start[9][0] != 'N');
        if (!mode_ok) {
            return NMEA_NO_FIX;
        }
        if (parse_number(start[7], len[7], &value)) {
            *speed_mps = value / 3.6;
            return NMEA_SPEED;
        }
        if (parse_number(start[5], len[5], &value)) {
            *speed_mps = value * KNOTS_TO_MPS;
            return NMEA_SPEED;
        }
        return NMEA_NO_FIX;
    }
    return NMEA_NONE;
}

nmea_result_t nmea_feed(nmea_reader_t *r, char c, double *speed_mps)
{
    if (c == '$') { /* a new sentence starts, whatever came before */
        r->len = 0;
        r->overflow = false;
    }
    if (c == '\r' || c == '\n') {
        nmea_result_t result = NMEA_NONE;
        if (r->len > 0 && !r->overflow) {
            r->line[r->len] = '\0';
            result = nmea_parse_sentence(r->line, speed_mps);
            if (result == NMEA_BAD_CHECKSUM) {
                r->bad_checksum++;
                result = NMEA_NONE;
            }
        }
        r->len = 0;
        r->overflow = false;
        return result;
    }
    if (r->len + 1 >= sizeof r->line) {
        r->overflow = true;
        return NMEA_NONE;
    }
    if (r->len > 0 || c == '$') {
        r->line[r->len++] = c;
    }
    return NMEA_NONE;
}
