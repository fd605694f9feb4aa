/* agrihil-depth-fw: the sowing-depth controller of [D] (fuzzy self-tuning PID) as a host
 * program. See app.h for the command line. Ground speed from GBSD and, when the environment
 * names one in AGRIHIL_GNSS_PORT, from the GNSS receiver's NMEA RMC/VTG on that serial port. */
#include <stdio.h>
#include <stdlib.h>

#include "app.h"
#include "depth_adapter.h"
#include "hal_serial.h"
#include "nmea.h"

#define GNSS_BAUD 115200

typedef struct {
    depth_adapter_t adapter;
    hal_serial_t gnss;
    bool gnss_open;
    nmea_reader_t nmea;
} depth_app_t;

static depth_app_t app;
static const app_info_t INFO = {"agrihil-depth-fw", false, 10.0};

static size_t on_frame(void *ctx, const hal_can_frame_t *frame, double now_s,
                       hal_can_frame_t *out)
{
    depth_app_t *d = ctx;
    return depth_on_frame(&d->adapter, frame, now_s, out);
}

static size_t step(void *ctx, double now_s, hal_can_frame_t *out)
{
    depth_app_t *d = ctx;
    return depth_step(&d->adapter, now_s, out);
}

static void poll_gnss(void *ctx, double now_s)
{
    depth_app_t *d = ctx;
    if (!d->gnss_open) {
        return;
    }
    char buf[256];
    for (;;) {
        long n = hal_serial_read(&d->gnss, buf, sizeof buf);
        if (n < 0) {
            app_error(&INFO, "GNSS: %s; going on without it", d->gnss.error);
            hal_serial_close(&d->gnss);
            d->gnss_open = false;
            return;
        }
        if (n == 0) {
            return;
        }
        for (long i = 0; i < n; i++) {
            double mps;
            nmea_result_t r = nmea_feed(&d->nmea, buf[i], &mps);
            if (r == NMEA_SPEED) {
                depth_on_gnss(&d->adapter, true, mps, now_s);
            } else if (r == NMEA_NO_FIX) {
                depth_on_gnss(&d->adapter, false, 0.0, now_s);
            }
        }
    }
}

int main(int argc, char **argv)
{
    app_options_t opt;
    int rc = app_parse_args(&INFO, argc, argv, &opt);
    if (rc >= 0) {
        return rc;
    }
    static depth_config_t cfg;
    depth_config_defaults(&cfg);
    param_ref_t refs[DEPTH_PARAM_COUNT];
    size_t n = depth_param_refs(&cfg, refs);
    rc = app_apply_params(&INFO, &opt, refs, n, NULL, NULL);
    if (rc == 0) {
        rc = app_reconcile_period(&INFO, &opt, &cfg.core.period_s);
    }
    if (rc != 0) {
        return rc;
    }
    char err[128];
    if (depth_config_check(&cfg, err, sizeof err) != 0) {
        app_error(&INFO, "%s", err);
        return APP_EXIT_USAGE;
    }
    depth_init(&app.adapter, &cfg);
    nmea_init(&app.nmea);
    const char *port = getenv("AGRIHIL_GNSS_PORT");
    if (port != NULL && *port != '\0') {
        if (hal_serial_open(&app.gnss, port, GNSS_BAUD) != 0) {
            app_error(&INFO, "GNSS (AGRIHIL_GNSS_PORT): %s", app.gnss.error);
            return APP_EXIT_BUS;
        }
        app.gnss_open = true;
        fprintf(stderr, "%s: GNSS on %s\n", INFO.name, port);
    }
    app_hooks_t hooks = {&app, on_frame, step, poll_gnss, depth_bootup()};
    rc = app_run(&INFO, &opt, &hooks);
    if (app.gnss_open) {
        hal_serial_close(&app.gnss);
    }
    return rc;
}
