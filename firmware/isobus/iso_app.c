#include "iso_app.h"

#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "hal_time.h"

#define IDLE_WAIT_US 50000

static volatile sig_atomic_t stop_requested = 0;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static int send_all(const app_info_t *info, hal_can_t *bus, const hal_can_frame_t *out,
                    size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (hal_can_send(bus, &out[i]) != 0) {
            app_error(info, "bus failure: %s", bus->error);
            return -1;
        }
    }
    return 0;
}

int iso_app_run(const app_info_t *info, const app_options_t *opt, const iso_app_hooks_t *h)
{
    static hal_can_t bus; /* static: the receive buffer is too big for a small stack */
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    if (hal_can_open(&bus, opt->bus) != 0) {
        app_error(info, "%s", bus.error);
        return APP_EXIT_BUS;
    }
    if (send_all(info, &bus, &h->bootup, 1) != 0) {
        hal_can_close(&bus);
        return APP_EXIT_BUS;
    }
    fprintf(stderr, "%s: on %s, %s, period %g ms\n", info->name, opt->bus,
            opt->sync ? "lockstep (one step per SYNC)" : "free-running", opt->period_ms);
    const int64_t period_ns = (int64_t)(opt->period_ms * 1e6);
    int64_t deadline_ns = hal_time_now_ns() + period_ns;
    int status = APP_EXIT_OK;
    while (!stop_requested) {
        int64_t wait_us = IDLE_WAIT_US;
        if (!opt->sync) {
            int64_t now_ns = hal_time_now_ns();
            if (now_ns >= deadline_ns) {
                size_t n = h->step(h->ctx);
                if (send_all(info, &bus, h->out(h->ctx), n) != 0) {
                    status = APP_EXIT_BUS;
                    break;
                }
                deadline_ns += period_ns;
                if (now_ns - deadline_ns > period_ns) {
                    deadline_ns = now_ns + period_ns; /* fell far behind: skip, don't burst */
                }
                continue;
            }
            wait_us = (deadline_ns - now_ns + 999) / 1000;
            if (wait_us > IDLE_WAIT_US) {
                wait_us = IDLE_WAIT_US;
            }
        }
        hal_can_frame_t frame;
        int rc = hal_can_recv(&bus, &frame, wait_us);
        if (rc == HAL_CAN_ERROR) {
            if (stop_requested) {
                break;
            }
            app_error(info, "bus failure: %s", bus.error);
            status = APP_EXIT_BUS;
            break;
        }
        if (h->poll != NULL) {
            h->poll(h->ctx);
        }
        if (rc != HAL_CAN_FRAME) {
            continue;
        }
        size_t n = h->on_frame(h->ctx, &frame);
        if (send_all(info, &bus, h->out(h->ctx), n) != 0) {
            status = APP_EXIT_BUS;
            break;
        }
    }
    hal_can_close(&bus);
    return status;
}
