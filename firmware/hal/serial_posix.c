#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include "hal_serial.h"

static speed_t baud_constant(unsigned baud)
{
    switch (baud) {
    case 4800:
        return B4800;
    case 9600:
        return B9600;
    case 19200:
        return B19200;
    case 38400:
        return B38400;
    case 57600:
        return B57600;
    case 115200:
    default:
        return B115200;
    }
}

int hal_serial_open(hal_serial_t *port, const char *path, unsigned baud)
{
    memset(port, 0, sizeof *port);
    port->fd = open(path, O_RDONLY | O_NOCTTY | O_NONBLOCK);
    if (port->fd < 0) {
        snprintf(port->error, sizeof port->error, "cannot open serial port %s: %s", path,
                 strerror(errno));
        return -1;
    }
    struct termios tio;
    if (tcgetattr(port->fd, &tio) != 0) {
        snprintf(port->error, sizeof port->error, "%s is not a serial port: %s", path,
                 strerror(errno));
        close(port->fd);
        port->fd = -1;
        return -1;
    }
    /* raw mode, as cfmakeraw (not POSIX) would set it */
    tio.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
    tio.c_oflag &= ~(tcflag_t)OPOST;
    tio.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    tio.c_cflag &= ~(tcflag_t)(CSIZE | PARENB | CSTOPB);
    tio.c_cflag |= CS8 | CREAD | CLOCAL;
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    cfsetispeed(&tio, baud_constant(baud));
    cfsetospeed(&tio, baud_constant(baud));
    if (tcsetattr(port->fd, TCSANOW, &tio) != 0) {
        snprintf(port->error, sizeof port->error, "cannot configure serial port %s: %s", path,
                 strerror(errno));
        close(port->fd);
        port->fd = -1;
        return -1;
    }
    return 0;
}

long hal_serial_read(hal_serial_t *port, char *buf, size_t cap)
{
    for (;;) {
        ssize_t n = read(port->fd, buf, cap);
        if (n >= 0) {
            return (long)n;
        }
        if (errno == EINTR) {
            continue;
        }
        if (errno == EAGAIN || errno == EWOULDBLOCK) {
            return 0;
        }
        /* EIO: the other side of a pty closed; no data, report once as an error */
        snprintf(port->error, sizeof port->error, "serial read failed: %s", strerror(errno));
        return -1;
    }
}

void hal_serial_close(hal_serial_t *port)
{
    if (port->fd >= 0) {
        close(port->fd);
        port->fd = -1;
    }
}
