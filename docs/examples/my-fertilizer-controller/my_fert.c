/* my-fert: a fertilizer flow controller for the agrihil fertilizer rig, written from
 * docs/guide/writing-a-fertilizer-controller.md alone (no agrihil code): its own socketcand
 * client, its own frame decoding and its own control law.
 *
 * Law: feedforward from the meter's map q = ff_coeff * n^ff_exponent (n in shaft r/min,
 * 6 r/min per volt, proportional below 5 r/min), on a target scaled by a meter factor that a slow integral learns from the
 * flow modules once the target has been steady for settle_s.
 *
 * Build: cc -std=c11 -O2 -Wall -Wextra -o my-fert my_fert.c -lm
 * Run:   my-fert --bus socketcand:127.0.0.1:29536/can0 [--param key=value ...]
 * Exit:  0 on SIGTERM/SIGINT, 2 on a bad argument, 3 on a bus failure.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define NODE_ID 0x10
#define ID_SYNC 0x080
#define ID_FLOW1 0x181 /* ... 0x184, one per row */
#define ID_HALL 0x185
#define ID_SETPOINT 0x210
#define ID_COMMAND 0x220
#define ID_HEARTBEAT (0x700 + NODE_ID)
#define ID_WBSD 0x0CFE48F0u /* 29-bit */
#define ID_GBSD 0x0CFE49F0u /* 29-bit */
#define ID_STEP_END 0x1FFFFFF0u /* 29-bit, no data: "my answer to this SYNC is complete" */
#define ROWS 4

static volatile sig_atomic_t stop;
static void on_signal(int sig) { (void)sig; stop = 1; }

/* ---- parameters (--param key=value) ------------------------------------------------------ */
static struct {
    double ff_coeff, ff_exponent, linear_below_rpm, rpm_per_volt, ki, settle_s, period_s, stale_s;
} P = {4.586, 0.6537, 5.0, 6.0, 0.25, 1.5, 0.1, 2.5};

static int set_param(const char *kv)
{
    const char *eq = strchr(kv, '=');
    if (eq == NULL) {
        return -1;
    }
    size_t n = (size_t)(eq - kv);
    char *end;
    double v = strtod(eq + 1, &end);
    if (*end != '\0' || end == eq + 1) {
        return -1;
    }
    static const struct { const char *name; double *ref; } table[] = {
        {"ff_coeff", &P.ff_coeff},   {"ff_exponent", &P.ff_exponent},
        {"linear_below_rpm", &P.linear_below_rpm},
        {"rpm_per_volt", &P.rpm_per_volt}, {"ki", &P.ki},
        {"settle_s", &P.settle_s},   {"period_s", &P.period_s},
        {"stale_s", &P.stale_s},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++) {
        if (strlen(table[i].name) == n && strncmp(kv, table[i].name, n) == 0) {
            *table[i].ref = v;
            return 0;
        }
    }
    return -1;
}

/* ---- the socketcand client ---------------------------------------------------------------- */
static int sock = -1;
static char rbuf[8192];
static size_t rlen;

/* The next "< ... >" message into msg (without the brackets); 1 got one, 0 closed, -1 error. */
static int next_message(char *msg, size_t cap)
{
    for (;;) {
        char *open = memchr(rbuf, '<', rlen);
        char *close = open ? memchr(open, '>', rlen - (size_t)(open - rbuf)) : NULL;
        if (close != NULL) {
            size_t len = (size_t)(close - open - 1);
            if (len >= cap) {
                len = cap - 1;
            }
            memcpy(msg, open + 1, len);
            msg[len] = '\0';
            size_t used = (size_t)(close + 1 - rbuf);
            memmove(rbuf, rbuf + used, rlen - used);
            rlen -= used;
            return 1;
        }
        if (rlen == sizeof rbuf) {
            return -1; /* no message fits: not socketcand */
        }
        ssize_t got = recv(sock, rbuf + rlen, sizeof rbuf - rlen, 0);
        if (got == 0) {
            return 0;
        }
        if (got < 0) {
            if (errno == EINTR && !stop) {
                continue;
            }
            return -1;
        }
        rlen += (size_t)got;
    }
}

static int send_text(const char *text)
{
    size_t len = strlen(text);
    while (len > 0) {
        ssize_t put = send(sock, text, len, MSG_NOSIGNAL);
        if (put < 0) {
            if (errno == EINTR) {
                continue;
            }
            return -1;
        }
        text += put;
        len -= (size_t)put;
    }
    return 0;
}

static int expect(const char *want)
{
    char msg[600];
    if (next_message(msg, sizeof msg) != 1) {
        return -1;
    }
    char a[32] = "", b[32] = "";
    sscanf(msg, "%31s %31s", a, b);
    return strcmp(a, want) == 0 ? 0 : -1;
}

/* "socketcand:HOST:PORT/CHANNEL": connect, open the channel, raw mode. */
static int bus_open(const char *spec)
{
    char host[256], port[16], channel[64];
    if (sscanf(spec, "socketcand:%255[^:]:%15[0-9]/%63s", host, port, channel) != 3) {
        fprintf(stderr, "my-fert: bus spec must be socketcand:HOST:PORT/CHANNEL, got %s\n", spec);
        return -1;
    }
    struct addrinfo hints = {0}, *res;
    hints.ai_socktype = SOCK_STREAM;
    if (getaddrinfo(host, port, &hints, &res) != 0) {
        return -1;
    }
    sock = socket(res->ai_family, res->ai_socktype, 0);
    int rc = sock < 0 ? -1 : connect(sock, res->ai_addr, res->ai_addrlen);
    freeaddrinfo(res);
    if (rc != 0) {
        return -1;
    }
    int one = 1; /* small writes go out at once (the guide: TCP_NODELAY) */
    setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    char open_cmd[96];
    snprintf(open_cmd, sizeof open_cmd, "< open %s >", channel);
    if (expect("hi") || send_text(open_cmd) || expect("ok") || send_text("< rawmode >") ||
        expect("ok")) {
        fprintf(stderr, "my-fert: socketcand handshake failed on %s\n", spec);
        return -1;
    }
    return 0;
}

/* An id of more than three hex digits is a 29-bit id. */
static int bus_send(uint32_t id, bool extended, const uint8_t *data, int len)
{
    char text[80];
    int n = snprintf(text, sizeof text, extended ? "< send %08X %X" : "< send %03X %X",
                     (unsigned)id, len);
    for (int i = 0; i < len; i++) {
        n += snprintf(text + n, sizeof text - (size_t)n, " %02X", data[i]);
    }
    snprintf(text + n, sizeof text - (size_t)n, " >");
    return send_text(text);
}

/* ---- what the controller knows ------------------------------------------------------------ */
static struct {
    bool seen, enable;
    int mode, speed_source, active_rows;
    double rate, width, target_flow;
} setpoint;
static struct { bool ok; double flow; double at_s; bool fresh; } row[ROWS];
static struct { bool ok; double mps; } speed[3]; /* 0 Hall wheel, 1 wheel-based, 2 ground-based */

static unsigned le16(const uint8_t *d) { return (unsigned)d[0] | (unsigned)d[1] << 8; }

static void on_frame(uint32_t id, bool extended, const uint8_t *d, int len, double now_s)
{
    if (extended) {
        int src = id == ID_WBSD ? 1 : id == ID_GBSD ? 2 : -1;
        if (src > 0 && len >= 2) {
            unsigned raw = le16(d);
            speed[src].ok = raw <= 0xFAFF; /* above: error or not available */
            speed[src].mps = speed[src].ok ? raw * 0.001 : 0.0;
        }
        return;
    }
    if (id >= ID_FLOW1 && id < ID_FLOW1 + ROWS && len >= 6) {
        int r = (int)(id - ID_FLOW1);
        bool baseline_ready = d[5] & 0x01, overrange = d[5] & 0x04;
        row[r].ok = baseline_ready && !overrange;
        row[r].flow = le16(d) * 0.01;
        row[r].at_s = now_s;
        row[r].fresh = true;
    } else if (id == ID_HALL && len >= 2) {
        speed[0].ok = true;
        speed[0].mps = le16(d) * 0.001;
    } else if (id == ID_SETPOINT && len >= 7) {
        setpoint.seen = true;
        setpoint.rate = le16(d) * 0.1;
        setpoint.width = le16(d + 2) * 0.001;
        setpoint.target_flow = le16(d + 4) * 0.01;
        setpoint.mode = d[6] & 0x03;
        setpoint.enable = (d[6] >> 2) & 0x01;
        setpoint.speed_source = (d[6] >> 3) & 0x03;
        setpoint.active_rows = (d[6] >> 5) & 0x07;
    }
}

/* ---- the control law ---------------------------------------------------------------------- */
static double factor = 1.0;
static double history[64]; /* the targets of the last steps, newest at steps % 64 */
static long n_steps;

static double target_gps(void)
{
    if (!setpoint.seen || !setpoint.enable) {
        return 0.0;
    }
    if (setpoint.mode == 1 || setpoint.mode == 2) {
        return setpoint.target_flow;
    }
    if (setpoint.mode == 0 && setpoint.speed_source < 3 && speed[setpoint.speed_source].ok) {
        int rows = setpoint.active_rows > 0 ? setpoint.active_rows : 1;
        return 0.1 * setpoint.rate * setpoint.width * speed[setpoint.speed_source].mps / rows;
    }
    return 0.0;
}

/* The meter map inverted: q = c n^p above 5 r/min; below, the grams per revolution stay those
 * of 5 r/min (q proportional to n). */
static double volts_for(double q)
{
    if (q <= 0.0) {
        return 0.0;
    }
    double n = pow(q / P.ff_coeff, 1.0 / P.ff_exponent);
    if (n < P.linear_below_rpm) {
        n = q / (P.ff_coeff * pow(P.linear_below_rpm, P.ff_exponent)) * P.linear_below_rpm;
    }
    double v = n / P.rpm_per_volt;
    return v > 10.0 ? 10.0 : v;
}

static double step(double now_s)
{
    double q = target_gps();
    history[n_steps % 64] = q;
    n_steps++;
    /* the sensed flow is a 1 s mean that lags the target: learn from it only while the target
     * has stayed within 3 % for the last settle_s */
    long span = lround(P.settle_s / P.period_s);
    span = span < 1 ? 1 : span > 63 ? 63 : span;
    bool steady = n_steps > span;
    for (long k = 0; steady && k < span; k++) {
        steady = fabs(history[(n_steps - 1 - k) % 64] - q) <= 0.03 * q;
    }
    double sum = 0.0;
    int valid = 0;
    bool fresh = false;
    for (int r = 0; r < ROWS; r++) {
        if (row[r].ok && now_s - row[r].at_s <= P.stale_s + 1e-9 && row[r].flow <= 3 * q + 5) {
            sum += row[r].flow;
            valid++;
            fresh = fresh || row[r].fresh;
        }
        row[r].fresh = false;
    }
    if (setpoint.mode != 2 && q > 0.0 && valid > 0 && fresh && steady) {
        factor += P.ki * (q - sum / valid) / q;
        factor = fmin(fmax(factor, 0.7), 1.3);
    }
    return setpoint.mode == 2 ? volts_for(q) : volts_for(q * factor);
}

/* ---- main --------------------------------------------------------------------------------- */
int main(int argc, char **argv)
{
    const char *spec = getenv("AGRIHIL_BUS");
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--bus") == 0 && i + 1 < argc) {
            spec = argv[++i];
        } else if (strcmp(argv[i], "--param") == 0 && i + 1 < argc) {
            if (set_param(argv[++i]) != 0) {
                fprintf(stderr, "my-fert: bad or unknown parameter %s\n", argv[i]);
                return 2;
            }
        } else {
            fprintf(stderr, "usage: my-fert --bus socketcand:HOST:PORT/CH [--param K=V]...\n");
            return 2;
        }
    }
    if (spec == NULL) {
        fprintf(stderr, "my-fert: no bus (--bus or AGRIHIL_BUS)\n");
        return 2;
    }
    struct sigaction sa = {0};
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    if (bus_open(spec) != 0) {
        return 3;
    }
    const uint8_t bootup = 0x00, operational = 0x05;
    /* boot-up, then one step-end frame: it tells the rig that this controller ends each of
     * its lockstep steps with one, so it may send its frames in any order */
    if (bus_send(ID_HEARTBEAT, false, &bootup, 1) != 0 ||
        bus_send(ID_STEP_END, true, NULL, 0) != 0) {
        return 3;
    }
    long steps = 0;
    char msg[600];
    while (!stop) {
        int rc = next_message(msg, sizeof msg);
        if (rc != 1) {
            break;
        }
        char kind[16], id_text[16], stamp[32], hex[40] = "";
        if (sscanf(msg, "%15s %15s %31s %39s", kind, id_text, stamp, hex) < 3 ||
            strcmp(kind, "frame") != 0) {
            continue; /* "< error ... >" and anything else */
        }
        uint32_t id = (uint32_t)strtoul(id_text, NULL, 16);
        bool extended = strlen(id_text) > 3;
        double now_s = steps * P.period_s;
        if (!extended && id == ID_SYNC) {
            double volts = step(now_s);
            steps++;
            int mv = (int)lround(volts * 1000.0);
            uint8_t cmd[4] = {(uint8_t)(mv & 0xFF), (uint8_t)(mv >> 8), 0, 0};
            if (bus_send(ID_COMMAND, false, cmd, 4) != 0 ||
                bus_send(ID_HEARTBEAT, false, &operational, 1) != 0 ||
                bus_send(ID_STEP_END, true, NULL, 0) != 0) {
                return 3;
            }
            continue;
        }
        uint8_t data[8];
        int len = (int)strlen(hex) / 2;
        len = len > 8 ? 8 : len;
        for (int i = 0; i < len; i++) {
            unsigned byte;
            sscanf(hex + 2 * i, "%2x", &byte);
            data[i] = (uint8_t)byte;
        }
        on_frame(id, extended, data, len, now_s);
    }
    close(sock);
    return stop ? 0 : 3;
}
