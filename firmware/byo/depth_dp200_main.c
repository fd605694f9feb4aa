/* agrihil-depth-dp200-fw: [D]'s sowing-depth controller (fuzzy self-tuning PID) in the DepthPro
 * DP-200's CAN layout, as a host program. The command line is agrihil-depth-fw's (app.h: --bus,
 * --sync, --period-ms, --param KEY=VALUE, --help, --version); the parameters are the Python
 * build's, plus sdo_timeout_s. Ground speed from GBSD and, when the environment names one in
 * AGRIHIL_GNSS_PORT, from the GNSS receiver's NMEA RMC/VTG on that serial port (read at the
 * start of each step, as the Python build reads it).
 *
 * The loop is its own, not app_run(): the DP-200 answers the drive's boot-up with the 30 SDO
 * writes of its configuration at once, more than app_run's APP_MAX_OUT (8), and it stops when
 * the drive refuses that configuration. As there, the drive command ends each step (no
 * step-end frame is needed in lockstep), the boot-up frame goes first, and
 *   exit 0  after SIGTERM/SIGINT
 *        1  on a bus failure
 *        2  on bad arguments
 *        3  when the drive refused its configuration (an SDO abort: the object, the abort code
 *           and its CiA 301 meaning on stderr), answered out of turn, or did not answer within
 *           sdo_timeout_s (the first unconfirmed object on stderr); the drive is left stopped. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app.h"
#include "depth_dp200_adapter.h"
#include "hal_serial.h"
#include "hal_time.h"
#include "nmea.h"

#define IDLE_WAIT_US 50000
#define GNSS_BAUD 115200
#define SYNC_ID 0x080u
#define EXIT_DRIVE_CONFIG 3

static const app_info_t INFO = {"agrihil-depth-dp200-fw", false, 10.0};
static dp200_adapter_t adapter;
static dp200_config_t cfg;
static hal_can_frame_t out[DP200_MAX_OUT];
static hal_serial_t gnss;
static bool gnss_open;
static nmea_reader_t nmea;
static volatile sig_atomic_t stop_requested = 0;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static int send_all(hal_can_t *bus, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (hal_can_send(bus, &out[i]) != 0) {
            app_error(&INFO, "bus failure: %s", bus->error);
            return -1;
        }
    }
    return 0;
}

/* The GNSS sentences received since the last step, as speeds of this step. */
static void poll_gnss(void)
{
    char buf[256];
    while (gnss_open) {
        long n = hal_serial_read(&gnss, buf, sizeof buf);
        if (n < 0) {
            app_error(&INFO, "GNSS: %s; going on without it", gnss.error);
            hal_serial_close(&gnss);
            gnss_open = false;
            return;
        }
        if (n == 0) {
            return;
        }
        for (long i = 0; i < n; i++) {
            double mps;
            nmea_result_t r = nmea_feed(&nmea, buf[i], &mps);
            if (r == NMEA_SPEED) {
                dp200_on_gnss(&adapter, true, mps);
            } else if (r == NMEA_NO_FIX) {
                dp200_on_gnss(&adapter, false, 0.0);
            }
        }
    }
}

static size_t step(void)
{
    poll_gnss();
    return dp200_step(&adapter, out);
}

static int run(const app_options_t *opt)
{
    static hal_can_t bus;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    if (hal_can_open(&bus, opt->bus) != 0) {
        app_error(&INFO, "%s", bus.error);
        return APP_EXIT_BUS;
    }
    out[0] = dp200_bootup();
    if (send_all(&bus, 1) != 0) {
        hal_can_close(&bus);
        return APP_EXIT_BUS;
    }
    fprintf(stderr, "%s: on %s, %s, period %g ms\n", INFO.name, opt->bus,
            opt->sync ? "lockstep (one step per SYNC)" : "free-running", opt->period_ms);
    const int64_t period_ns = (int64_t)(opt->period_ms * 1e6);
    int64_t deadline_ns = hal_time_now_ns() + period_ns;
    int status = APP_EXIT_OK;
    while (!stop_requested && dp200_error(&adapter) == NULL) {
        size_t n = 0;
        if (!opt->sync && hal_time_now_ns() >= deadline_ns) {
            int64_t now_ns = hal_time_now_ns();
            n = step();
            deadline_ns += period_ns;
            if (now_ns - deadline_ns > period_ns) {
                deadline_ns = now_ns + period_ns; /* fell far behind: skip, don't burst */
            }
        } else {
            int64_t wait_us = IDLE_WAIT_US;
            if (!opt->sync) {
                wait_us = (deadline_ns - hal_time_now_ns() + 999) / 1000;
                wait_us = wait_us > IDLE_WAIT_US ? IDLE_WAIT_US : wait_us < 0 ? 0 : wait_us;
            }
            hal_can_frame_t frame;
            int rc = hal_can_recv(&bus, &frame, wait_us);
            if (rc == HAL_CAN_ERROR) {
                if (!stop_requested) {
                    app_error(&INFO, "bus failure: %s", bus.error);
                    status = APP_EXIT_BUS;
                }
                break;
            }
            if (rc != HAL_CAN_FRAME) {
                continue;
            }
            if (opt->sync && !frame.extended && frame.id == SYNC_ID) {
                n = step();
            } else {
                n = dp200_on_frame(&adapter, &frame, out);
            }
        }
        if (send_all(&bus, n) != 0) {
            status = APP_EXIT_BUS;
            break;
        }
    }
    const char *why = dp200_error(&adapter);
    if (status == APP_EXIT_OK && why != NULL) {
        app_error(&INFO, "the servo drive (node %u) did not take its configuration: %s; the "
                         "drive is left stopped",
                  (unsigned)adapter.drive_node, why);
        status = EXIT_DRIVE_CONFIG;
    }
    hal_can_close(&bus); /* writes what is still queued */
    if (status == APP_EXIT_OK) {
        fprintf(stderr, "%s: stopped after %u steps, drive %s\n", INFO.name,
                (unsigned)adapter.law.steps, adapter.configured ? "configured" : "not configured");
    }
    return status;
}

int main(int argc, char **argv)
{
    app_options_t opt;
    int rc = app_parse_args(&INFO, argc, argv, &opt);
    if (rc >= 0) {
        return rc;
    }
    dp200_config_defaults(&cfg);
    param_ref_t refs[DP200_PARAM_COUNT];
    size_t n = dp200_param_refs(&cfg, refs);
    rc = app_apply_params(&INFO, &opt, refs, n, NULL, NULL);
    if (rc == 0) {
        rc = app_reconcile_period(&INFO, &opt, &cfg.core.period_s);
    }
    if (rc != 0) {
        return rc;
    }
    char err[128];
    if (dp200_config_check(&cfg, err, sizeof err) != 0) {
        app_error(&INFO, "%s", err);
        return APP_EXIT_USAGE;
    }
    dp200_init(&adapter, &cfg);
    nmea_init(&nmea);
    const char *port = getenv("AGRIHIL_GNSS_PORT");
    if (port != NULL && *port != '\0') {
        if (hal_serial_open(&gnss, port, GNSS_BAUD) != 0) {
            app_error(&INFO, "GNSS (AGRIHIL_GNSS_PORT): %s", gnss.error);
            return APP_EXIT_BUS;
        }
        gnss_open = true;
        fprintf(stderr, "%s: GNSS on %s\n", INFO.name, port);
    }
    rc = run(&opt);
    if (gnss_open) {
        hal_serial_close(&gnss);
    }
    return rc;
}
