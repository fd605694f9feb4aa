/* Dispatch hal_can_* to the backend the bus spec names. */
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "hal_can.h"

int hal_can_open(hal_can_t *bus, const char *spec_text)
{
    memset(bus, 0, sizeof *bus);
    bus->fd = -1;
    bus_spec_t spec;
    if (bus_spec_parse(spec_text, &spec, bus->error, sizeof bus->error) != 0) {
        return -1;
    }
    bus->transport = spec.transport;
    switch (spec.transport) {
    case BUS_SOCKETCAN:
        return hal_socketcan_open(bus, &spec);
    case BUS_SOCKETCAND:
        return hal_socketcand_open(bus, &spec);
    default:
        snprintf(bus->error, sizeof bus->error, "unsupported bus transport");
        return -1;
    }
}

int hal_can_send(hal_can_t *bus, const hal_can_frame_t *frame)
{
    return bus->transport == BUS_SOCKETCAN ? hal_socketcan_send(bus, frame)
                                           : hal_socketcand_send(bus, frame);
}

int hal_can_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us)
{
    return bus->transport == BUS_SOCKETCAN ? hal_socketcan_recv(bus, frame, timeout_us)
                                           : hal_socketcand_recv(bus, frame, timeout_us);
}

void hal_can_close(hal_can_t *bus)
{
    if (bus->fd >= 0 && bus->transport == BUS_SOCKETCAND) {
        (void)hal_socketcand_flush(bus); /* the last frames still go out; errors: closing */
    }
    if (bus->fd >= 0) {
        close(bus->fd);
        bus->fd = -1;
    }
}
