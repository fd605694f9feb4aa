/* socketcand backend: the socketcand text protocol over TCP (TCP_NODELAY), raw mode.
 * agrihil's software bus speaks it, so the firmware joins a rig on machines without kernel CAN.
 * Sends are written behind (one write per burst, by the next receive) and receiving may busy
 * poll (",busy_poll_us=N"): see hal_can.h. */
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include "hal_can.h"
#include "hal_time.h"
#include "socketcand_proto.h"

#define HANDSHAKE_TIMEOUT_US 5000000

/* Set bus->error (messages longer than the buffer are cut, which is fine for a message) */
static void set_error(hal_can_t *bus, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(bus->error, sizeof bus->error, fmt, ap);
    va_end(ap);
}

/* Wait until fd is readable or timeout_us passed: 1 readable, 0 timeout/signal, -1 error. */
static int wait_readable(int fd, int64_t timeout_us)
{
    if (timeout_us < 0) {
        timeout_us = 0;
    }
    fd_set set;
    FD_ZERO(&set);
    FD_SET(fd, &set);
    struct timespec ts = {(time_t)(timeout_us / 1000000), (long)(timeout_us % 1000000) * 1000L};
    int rc = pselect(fd + 1, &set, NULL, NULL, &ts, NULL);
    if (rc < 0) {
        return errno == EINTR ? 0 : -1;
    }
    return rc > 0 ? 1 : 0;
}

/* Read what is available into the receive buffer: 1 got bytes, -1 error/closed. */
static int fill(hal_can_t *bus)
{
    if (bus->rx_len >= sizeof bus->rx) {
        bus->rx_len = 0; /* cannot happen with scd_next_message's limit; stay safe */
    }
    ssize_t n = recv(bus->fd, bus->rx + bus->rx_len, sizeof bus->rx - bus->rx_len, 0);
    if (n > 0) {
        bus->rx_len += (size_t)n;
        return 1;
    }
    if (n == 0) {
        set_error(bus, "socketcand server closed the connection");
    } else if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK) {
        return 1;
    } else {
        set_error(bus, "socketcand: recv failed: %s", strerror(errno));
    }
    return -1;
}

static int send_all(hal_can_t *bus, const char *text, size_t len)
{
    while (len > 0) {
        ssize_t n = send(bus->fd, text, len, MSG_NOSIGNAL);
        if (n < 0) {
            if (errno == EINTR) {
                continue;
            }
            set_error(bus, "socketcand: send failed: %s",
                     strerror(errno));
            return -1;
        }
        text += n;
        len -= (size_t)n;
    }
    return 0;
}

/* Busy polling: the adaptive window, in the manner of Linux's guest halt polling. When the
 * receive slept and data woke it within the limit of the previous data, the window grows to
 * cover that gap (a quarter more, at least double, at most the limit); a longer gap or a spin
 * that caught nothing halves it, and below a quarter of the limit it is off, so an idle bus
 * costs no CPU. */
static void busy_shrink(hal_can_t *bus)
{
    int64_t half = bus->busy_poll_window_ns / 2;
    bus->busy_poll_window_ns = half >= bus->busy_poll_limit_ns / 4 ? half : 0;
}

static void busy_woke(hal_can_t *bus, int64_t gap_ns)
{
    if (gap_ns > bus->busy_poll_limit_ns) {
        busy_shrink(bus);
        return;
    }
    int64_t w = bus->busy_poll_window_ns * 2;
    if (w < bus->busy_poll_limit_ns / 4) {
        w = bus->busy_poll_limit_ns / 4;
    }
    if (w < gap_ns + gap_ns / 4) {
        w = gap_ns + gap_ns / 4;
    }
    bus->busy_poll_window_ns = w < bus->busy_poll_limit_ns ? w : bus->busy_poll_limit_ns;
}

/* Poll without blocking until data comes or the window (or the deadline) ends, yielding the
 * CPU between polls: 1 got bytes, 0 nothing came, -1 error/closed. */
static int busy_fill(hal_can_t *bus, int64_t deadline_ns)
{
    int64_t now = hal_time_now_ns();
    int64_t end = now + bus->busy_poll_window_ns;
    if (end > deadline_ns) {
        end = deadline_ns;
    }
    while (now < end) {
        ssize_t n = recv(bus->fd, bus->rx + bus->rx_len, sizeof bus->rx - bus->rx_len,
                         MSG_DONTWAIT);
        if (n > 0) {
            bus->rx_len += (size_t)n;
            bus->busy_poll_last_ns = hal_time_now_ns();
            return 1;
        }
        if (n == 0) {
            set_error(bus, "socketcand server closed the connection");
            return -1;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
            set_error(bus, "socketcand: recv failed: %s", strerror(errno));
            return -1;
        }
        sched_yield(); /* a process sharing this CPU runs now, not at the end of the spin */
        now = hal_time_now_ns();
    }
    busy_shrink(bus);
    return 0;
}

/* Next message body within the deadline: 1 got one, 0 timed out, -1 error. */
static int next_message(hal_can_t *bus, char *body, size_t cap, int64_t deadline_ns)
{
    for (;;) {
        int got = scd_next_message(bus->rx, &bus->rx_len, body, cap);
        if (got != 0) {
            if (got < 0) {
                continue; /* an overlong message was dropped: keep reading */
            }
            return 1;
        }
        if (bus->rx_len >= sizeof bus->rx) {
            bus->rx_len = 0; /* cannot happen with scd_next_message's limit; stay safe */
        }
        int64_t start_ns = hal_time_now_ns();
        if (bus->busy_poll_window_ns > 0 && start_ns < deadline_ns) {
            int spun = busy_fill(bus, deadline_ns);
            if (spun < 0) {
                return -1;
            }
            if (spun > 0) {
                continue;
            }
            /* nothing came: report a timeout so that the caller looks at its flags (a signal
             * that came during the spin interrupted no wait) and calls again, to block */
            return 0;
        }
        int64_t left_us = (deadline_ns - start_ns) / 1000;
        int ready = wait_readable(bus->fd, left_us);
        if (ready < 0) {
            set_error(bus, "socketcand: select failed: %s",
                     strerror(errno));
            return -1;
        }
        if (ready == 0) {
            return 0; /* timed out, or a signal came: the caller checks its flags */
        }
        if (fill(bus) < 0) {
            return -1;
        }
        if (bus->busy_poll_limit_ns > 0) {
            int64_t now = hal_time_now_ns();
            busy_woke(bus, now - bus->busy_poll_last_ns);
            bus->busy_poll_last_ns = now;
        }
    }
}

static int expect(hal_can_t *bus, const char *want, const char *step, const bus_spec_t *spec)
{
    char body[SCD_MAX_MESSAGE];
    int64_t deadline = hal_time_now_ns() + (int64_t)HANDSHAKE_TIMEOUT_US * 1000;
    for (;;) {
        int got = next_message(bus, body, sizeof body, deadline);
        if (got < 0) {
            char why[HAL_CAN_ERRLEN];
            snprintf(why, sizeof why, "%s", bus->error);
            set_error(bus, "socketcand %s:%u: %s while waiting for "
                     "'< %s >' (%s)", spec->host, (unsigned)spec->port, why, want, step);
            return -1;
        }
        if (got == 0) {
            if (hal_time_now_ns() < deadline) {
                continue; /* a signal: keep waiting for the handshake */
            }
            set_error(bus, "socketcand %s:%u: no '< %s >' within "
                     "%d s (%s)", spec->host, (unsigned)spec->port, want,
                     HANDSHAKE_TIMEOUT_US / 1000000, step);
            return -1;
        }
        if (strcmp(body, want) == 0) {
            return 0;
        }
        if (strncmp(body, "error", 5) == 0 || strcmp(step, "greeting") == 0) {
            set_error(bus, "socketcand %s:%u: expected '< %s >' (%s), "
                     "got '< %.200s >'", spec->host, (unsigned)spec->port, want, step, body);
            return -1;
        }
        /* anything else (e.g. an early frame) is ignored during the handshake */
    }
}

int hal_socketcand_open(hal_can_t *bus, const bus_spec_t *spec)
{
    char port_text[8];
    snprintf(port_text, sizeof port_text, "%u", (unsigned)spec->port);
    struct addrinfo hints;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    struct addrinfo *res = NULL;
    int gai = getaddrinfo(spec->host, port_text, &hints, &res);
    if (gai != 0) {
        set_error(bus, "socketcand: cannot resolve host '%s': %s",
                 spec->host, gai_strerror(gai));
        return -1;
    }
    int fd = -1;
    int last_errno = 0;
    for (struct addrinfo *ai = res; ai != NULL; ai = ai->ai_next) {
        fd = socket(ai->ai_family, ai->ai_socktype, ai->ai_protocol);
        if (fd < 0) {
            last_errno = errno;
            continue;
        }
        if (connect(fd, ai->ai_addr, ai->ai_addrlen) == 0) {
            break;
        }
        last_errno = errno;
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd < 0) {
        set_error(bus, "cannot connect to socketcand server %s:%u: %s",
                 spec->host, (unsigned)spec->port, strerror(last_errno));
        return -1;
    }
    int one = 1;
    /* small frames must not wait for Nagle (up to 40 ms per frame otherwise) */
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    bus->fd = fd;
    bus->rx_len = 0;
    bus->tx_len = 0;
    bus->busy_poll_limit_ns = (int64_t)spec->busy_poll_us * 1000;
    bus->busy_poll_window_ns = 0;

    char cmd[BUS_SPEC_TEXT + 16];
    int n = snprintf(cmd, sizeof cmd, "< open %s >", spec->channel);
    if (expect(bus, "hi", "greeting", spec) != 0 || send_all(bus, cmd, (size_t)n) != 0 ||
        expect(bus, "ok", "open channel", spec) != 0 ||
        send_all(bus, "< rawmode >", 11) != 0 || expect(bus, "ok", "rawmode", spec) != 0 ||
        /* Any message after rawmode tells agrihil's software bus that the '< ok >' has been
         * read, so it stops holding back frames for this client (it holds them 50 ms for
         * clients that read '< ok >' with one exact recv). A standard socketcand server
         * answers '< echo >', which hal_socketcand_recv skips as it skips any non-frame. */
        send_all(bus, "< echo >", 8) != 0) {
        close(fd);
        bus->fd = -1;
        return -1;
    }
    return 0;
}

int hal_socketcand_flush(hal_can_t *bus)
{
    if (bus->tx_len == 0) {
        return 0;
    }
    size_t n = bus->tx_len;
    bus->tx_len = 0;
    return send_all(bus, bus->tx, n);
}

int hal_socketcand_send(hal_can_t *bus, const hal_can_frame_t *frame)
{
    char line[64];
    int n = scd_format_send(frame, line, sizeof line);
    if (n < 0) {
        set_error(bus, "socketcand: cannot send frame id 0x%X len %u",
                 (unsigned)frame->id, (unsigned)frame->len);
        return -1;
    }
    if (bus->tx_len + (size_t)n > sizeof bus->tx && hal_socketcand_flush(bus) != 0) {
        return -1;
    }
    memcpy(bus->tx + bus->tx_len, line, (size_t)n);
    bus->tx_len += (size_t)n;
    return 0;
}

int hal_socketcand_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us)
{
    if (hal_socketcand_flush(bus) != 0) {
        return HAL_CAN_ERROR;
    }
    char body[SCD_MAX_MESSAGE];
    int64_t deadline = hal_time_now_ns() + (timeout_us > 0 ? timeout_us : 0) * 1000;
    for (;;) {
        int got = next_message(bus, body, sizeof body, deadline);
        if (got < 0) {
            return HAL_CAN_ERROR;
        }
        if (got == 0) {
            return HAL_CAN_TIMEOUT;
        }
        int parsed = scd_parse_frame(body, frame);
        if (parsed == 1) {
            return HAL_CAN_FRAME;
        }
        /* "< error ... >" frames, echoes and malformed lines are not data frames: skip */
    }
}
