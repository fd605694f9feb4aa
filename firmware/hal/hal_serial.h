/* Serial port abstraction for the GNSS receiver: open raw and non-blocking, read what is there.
 * To port to an MCU: a UART receive ring buffer filled by its interrupt; hal_serial_read drains
 * it. */
#ifndef AGRIHIL_HAL_SERIAL_H
#define AGRIHIL_HAL_SERIAL_H

#include <stddef.h>

#define HAL_SERIAL_ERRLEN 256

typedef struct {
    int fd;
    char error[HAL_SERIAL_ERRLEN];
} hal_serial_t;

/* Open `path` (e.g. /dev/ttyUSB0, a pty) in raw mode, 8N1 at `baud`, non-blocking.
 * 0 on success, -1 with port->error set. */
int hal_serial_open(hal_serial_t *port, const char *path, unsigned baud);

/* Read up to cap bytes without blocking: the count (0 when nothing is waiting), -1 on error. */
long hal_serial_read(hal_serial_t *port, char *buf, size_t cap);

void hal_serial_close(hal_serial_t *port);

#endif
