/* Bus spec strings, the same syntax as hil.bus (TRANSPORT[:CHANNEL][,key=value...]), for the
 * transports the firmware speaks. Pure: no I/O, no allocation. Options are key=value; the
 * firmware reads busy_poll_us (socketcand) and ignores the others (bitrate and the like belong
 * to the interface). */
#ifndef AGRIHIL_BUS_SPEC_H
#define AGRIHIL_BUS_SPEC_H

#include <stddef.h>
#include <stdint.h>

typedef enum { BUS_SOCKETCAN = 1, BUS_SOCKETCAND = 2 } bus_transport_t;

#define BUS_SPEC_TEXT 128

typedef struct {
    bus_transport_t transport;
    char iface[BUS_SPEC_TEXT];   /* socketcan: interface name */
    char host[BUS_SPEC_TEXT];    /* socketcand: host name or address */
    uint16_t port;               /* socketcand: TCP port */
    char channel[BUS_SPEC_TEXT]; /* socketcand: channel to open (default can0) */
    uint32_t busy_poll_us;       /* socketcand: ",busy_poll_us=N" (0: off), see hal_can.h */
} bus_spec_t;

/* Parse `text`; 0 on success, -1 with a message naming the bad part in `err`. */
int bus_spec_parse(const char *text, bus_spec_t *out, char *err, size_t errlen);

#endif
