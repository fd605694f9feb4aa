/* socketcand transport against a scripted server (a child process on loopback): the handshake
 * ends with '< echo >' (so agrihil's software bus holds nothing back), sends are written
 * behind until the next receive (one write per burst) or close, and busy polling receives. */
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "check.h"
#include "hal_can.h"
#include "hal_time.h"

/* Read from fd until `want` has been seen (appending to buf); 0 on success. */
static int read_until(int fd, char *buf, size_t cap, size_t *len, const char *want)
{
    while (strstr(buf, want) == NULL) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 5000) <= 0 || *len + 1 >= cap) {
            return -1;
        }
        ssize_t n = recv(fd, buf + *len, cap - 1 - *len, 0);
        if (n <= 0) {
            return -1;
        }
        *len += (size_t)n;
        buf[*len] = '\0';
    }
    return 0;
}

static int64_t thread_cpu_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static void sleep_ms(long ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static int send_text(int fd, const char *text)
{
    size_t n = strlen(text);
    return send(fd, text, n, 0) == (ssize_t)n ? 0 : -1;
}

/* The scripted server; its exit status says which step failed (0: all as expected). */
static int serve(int listener)
{
    int fd = accept(listener, NULL, NULL);
    char buf[4096] = "";
    size_t len = 0;
    if (fd < 0 || send_text(fd, "< hi >") != 0) {
        return 10;
    }
    if (read_until(fd, buf, sizeof buf, &len, "< open can0 >") != 0 || send_text(fd, "< ok >")) {
        return 11;
    }
    if (read_until(fd, buf, sizeof buf, &len, "< rawmode >") != 0 || send_text(fd, "< ok >")) {
        return 12;
    }
    if (read_until(fd, buf, sizeof buf, &len, "< echo >") != 0 || send_text(fd, "< echo >")) {
        return 13; /* the client did not end the rawmode hold */
    }
    /* the client now sends two frames and waits 100 ms before it receives: nothing may come
     * before that receive */
    struct pollfd p = {fd, POLLIN, 0};
    if (poll(&p, 1, 50) != 0) {
        return 14;
    }
    len = 0;
    buf[0] = '\0';
    /* both frames in one read: they were written together */
    if (poll(&p, 1, 5000) != 1) {
        return 15;
    }
    ssize_t n = recv(fd, buf, sizeof buf - 1, 0);
    if (n <= 0) {
        return 15;
    }
    buf[n] = '\0';
    if (strcmp(buf, "< send 123 2 DE AD >< send 18FEF100 1 01 >") != 0) {
        fprintf(stderr, "server read '%s'\n", buf);
        return 16;
    }
    if (send_text(fd, "< echo >< frame 321 1.000000 BEEF >") != 0) {
        return 17;
    }
    /* a burst 1 ms later: the busy-polling receive takes it */
    sleep_ms(1);
    if (send_text(fd, "< frame 322 1.001000 01 >") != 0) {
        return 17;
    }
    /* a poll writes what was sent before it, and so does close */
    len = 0;
    buf[0] = '\0';
    if (read_until(fd, buf, sizeof buf, &len, "< send 7FF 0 >< send 7FF 0 >") != 0) {
        return 18;
    }
    close(fd);
    return 0;
}

static void test_handshake_write_behind_and_busy_poll(void)
{
    int listener = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in addr;
    memset(&addr, 0, sizeof addr);
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t alen = sizeof addr;
    CHECK(listener >= 0);
    CHECK_INT(bind(listener, (struct sockaddr *)&addr, sizeof addr), 0);
    CHECK_INT(listen(listener, 1), 0);
    CHECK_INT(getsockname(listener, (struct sockaddr *)&addr, &alen), 0);
    fflush(NULL);
    pid_t child = fork();
    if (child == 0) {
        _exit(serve(listener));
    }
    close(listener);

    char spec[96];
    /* a generous busy-poll limit (200 ms): the 1 ms gap below must grow the window even when
     * a loaded machine stretches it to tens of ms (the window logic, not the host, is tested) */
    snprintf(spec, sizeof spec, "socketcand:127.0.0.1:%u/can0,busy_poll_us=200000",
             (unsigned)ntohs(addr.sin_port));
    static hal_can_t bus;
    CHECK_INT(hal_can_open(&bus, spec), 0);
    CHECK_INT(bus.busy_poll_limit_ns, 200000000);
    hal_can_frame_t a = {0x123, false, 2, {0xDE, 0xAD}};
    hal_can_frame_t b = {0x18FEF100, true, 1, {0x01}};
    CHECK_INT(hal_can_send(&bus, &a), 0);
    CHECK_INT(hal_can_send(&bus, &b), 0);
    sleep_ms(100);
    hal_can_frame_t got;
    CHECK_INT(hal_can_recv(&bus, &got, 2000000), HAL_CAN_FRAME);
    CHECK_INT(got.id, 0x321);
    CHECK_INT(got.len, 2);
    /* the next frame comes 1 ms after this one: a wait that short grows the busy-poll window
     * from nothing, so the receive after it spins instead of sleeping */
    CHECK_INT(hal_can_recv(&bus, &got, 2000000), HAL_CAN_FRAME);
    CHECK_INT(got.id, 0x322);
    CHECK(bus.busy_poll_window_ns > 0);
    hal_can_frame_t c = {0x7FF, false, 0, {0}};
    CHECK_INT(hal_can_send(&bus, &c), 0);
    /* a poll does not spin: judged on this thread's CPU time, which a loaded machine does not
     * stretch (a spin burns up to the busy-poll window; being descheduled burns nothing) */
    int64_t t0 = thread_cpu_ns();
    CHECK_INT(hal_can_recv(&bus, &got, 0), HAL_CAN_TIMEOUT);
    CHECK(thread_cpu_ns() - t0 < 2000000);
    CHECK_INT(hal_can_send(&bus, &c), 0);
    hal_can_close(&bus);
    int status = -1;
    CHECK_INT(waitpid(child, &status, 0), child);
    CHECK(WIFEXITED(status));
    CHECK_INT(WEXITSTATUS(status), 0);
}

TEST_MAIN("socketcand_io", test_handshake_write_behind_and_busy_poll)
