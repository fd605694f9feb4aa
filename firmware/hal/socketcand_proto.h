/* The socketcand ASCII protocol, the raw-mode subset: message splitting, frame parsing and
 * formatting. Pure: no I/O, no allocation (the socket side is can_socketcand.c).
 *
 *   server -> client   < hi >  < ok >  < frame ID SEC.USEC HEXDATA >  < error ... >
 *   client -> server   < open CHANNEL >  < rawmode >  < send ID LEN B0 B1 ... >
 *
 * ID is hex; it is a 29-bit (extended) identifier when written with more than three digits
 * (socketcand writes eight) or when its value exceeds 0x7FF. */
#ifndef AGRIHIL_SOCKETCAND_PROTO_H
#define AGRIHIL_SOCKETCAND_PROTO_H

#include <stddef.h>

#include "hal_can.h"

#define SCD_MAX_MESSAGE 512

/* Take the next complete "< ... >" message out of buf[0..*len): copy its body, without the
 * angle brackets and surrounding spaces, NUL-terminated, to `body` (capacity `cap`), remove it
 * (and anything before it) from the buffer, and return 1. Return 0 when no complete message
 * is buffered (a partial one is kept), -1 when the buffer holds more than SCD_MAX_MESSAGE
 * bytes without a '>' or a body does not fit `cap` (the offending bytes are dropped). */
int scd_next_message(char *buf, size_t *len, char *body, size_t cap);

/* Parse a message body. Returns 1 and fills *frame for "frame ID SEC.USEC [HEXDATA]" (data as
 * contiguous hex or as space-separated bytes), 0 for any other word, -1 for a malformed frame. */
int scd_parse_frame(const char *body, hal_can_frame_t *frame);

/* Render "< send ID LEN B0 B1 ... >" into out (capacity cap); returns its length, or -1 if the
 * frame is invalid (id out of range, len > 8) or out is too small. */
int scd_format_send(const hal_can_frame_t *frame, char *out, size_t cap);

#endif
