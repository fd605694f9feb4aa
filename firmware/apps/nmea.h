/* A tiny NMEA 0183 reader: ground speed from RMC and VTG sentences (any talker: GN, GP, BD, GB).
 * Bytes go in as they arrive from the serial port; each complete, checksummed sentence that
 * carries a valid speed yields it. Pure: no I/O, no allocation. */
#ifndef AGRIHIL_NMEA_H
#define AGRIHIL_NMEA_H

#include <stdbool.h>
#include <stddef.h>

#define NMEA_MAX_SENTENCE 96 /* NMEA 0183 allows 82 characters */

typedef struct {
    char line[NMEA_MAX_SENTENCE];
    size_t len;
    bool overflow;        /* the current line is too long: drop it */
    unsigned bad_checksum; /* sentences dropped for a wrong or missing checksum */
} nmea_reader_t;

typedef enum {
    NMEA_NONE = 0,      /* nothing usable (other sentence, no fix, malformed) */
    NMEA_SPEED = 1,     /* *speed_mps holds a ground speed from a valid fix */
    NMEA_NO_FIX = 2,    /* an RMC/VTG said the speed is not valid (status V / mode N) */
    NMEA_BAD_CHECKSUM = 3 /* missing or wrong checksum (nmea_parse_sentence only) */
} nmea_result_t;

void nmea_init(nmea_reader_t *r);

/* Feed one byte; returns a result when it completes a sentence. */
nmea_result_t nmea_feed(nmea_reader_t *r, char c, double *speed_mps);

/* Parse one complete sentence ("$GNRMC,...*hh", with or without CR LF). */
nmea_result_t nmea_parse_sentence(const char *sentence, double *speed_mps);

#endif
