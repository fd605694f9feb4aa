/* agrihil-sowing-depth-isobus-fw: the sowing-depth controller of [D] as an ISOBUS implement
 * (iso_depth.h): the seeding depth from the Task Controller (DDI 56), the default depth its DDOP
 * declares (DDI 58) when the TC is lost. The command line is agrihil-depth-fw's (app.h: --bus,
 * --sync, --period-ms, --param KEY=VALUE) with the ISOBUS mode's parameters as the Python
 * controller names them: address, identity_number, default_depth_mm, min_depth_mm,
 * max_depth_mm, latency_ms, fixed_depth_mm (numbers), actual=sensed|setpoint,
 * fallback=default|hold. Ground speed from the GNSS receiver on the serial port the environment
 * names in AGRIHIL_GNSS_PORT (NMEA RMC/VTG), as agrihil-depth-fw. The loop is iso_app_run (a
 * step may send a whole CTS window of TP data frames). */
#include <stdio.h>
#include <stdlib.h>

#include "app.h"
#include "hal_serial.h"
#include "iso_app.h"
#include "iso_depth.h"
#include "nmea.h"

#define GNSS_BAUD 115200

typedef struct {
    iso_depth_t controller;
    hal_serial_t gnss;
    bool gnss_open;
    nmea_reader_t nmea;
} depth_isobus_app_t;

static depth_isobus_app_t app;
static iso_depth_config_t cfg;
static const app_info_t INFO = {"agrihil-sowing-depth-isobus-fw", false, 10.0};

static int word_param(void *ctx, const char *key, const char *value)
{
    const char *why = NULL;
    int rc = iso_depth_word_param(ctx, key, value, &why);
    if (rc < 0) {
        app_error(&INFO, "parameter '%s': %s, got '%s'", key, why, value);
    }
    return rc;
}

static size_t on_frame(void *ctx, const hal_can_frame_t *frame)
{
    depth_isobus_app_t *d = ctx;
    return iso_depth_on_frame(&d->controller, frame);
}

static size_t step(void *ctx)
{
    depth_isobus_app_t *d = ctx;
    return iso_depth_step(&d->controller);
}

static const hal_can_frame_t *out(void *ctx)
{
    depth_isobus_app_t *d = ctx;
    return d->controller.out;
}

static void poll_gnss(void *ctx)
{
    depth_isobus_app_t *d = ctx;
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
                iso_depth_on_gnss(&d->controller, true, mps);
            } else if (r == NMEA_NO_FIX) {
                iso_depth_on_gnss(&d->controller, false, 0.0);
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
    iso_depth_config_defaults(&cfg);
    cfg.step_on_sync = opt.sync;
    param_ref_t refs[ISO_DEPTH_PARAM_COUNT];
    size_t n = iso_depth_param_refs(&cfg, refs);
    rc = app_apply_params(&INFO, &opt, refs, n, word_param, &cfg);
    if (rc == 0) {
        rc = app_reconcile_period(&INFO, &opt, &cfg.depth.core.period_s);
    }
    if (rc != 0) {
        return rc;
    }
    char err[128];
    if (iso_depth_check(&cfg, err, sizeof err) != 0) {
        app_error(&INFO, "%s", err);
        return APP_EXIT_USAGE;
    }
    if (iso_depth_init(&app.controller, &cfg) != 0) {
        app_error(&INFO, "the DDOP does not fit a TP transfer (%u bytes at most)",
                  (unsigned)ISO_DDOP_MAX_BYTES);
        return APP_EXIT_USAGE;
    }
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
    fprintf(stderr, "%s: NAME 0x%016llX, preferred address 0x%02X, DDOP %u bytes\n", INFO.name,
            (unsigned long long)app.controller.name, (unsigned)cfg.address,
            (unsigned)app.controller.pool.size);
    iso_app_hooks_t hooks = {&app, on_frame, step, out, poll_gnss, iso_depth_bootup()};
    rc = iso_app_run(&INFO, &opt, &hooks);
    if (app.gnss_open) {
        hal_serial_close(&app.gnss);
    }
    if (rc == APP_EXIT_OK) {
        fprintf(stderr, "%s: stopped after %u steps, TC client %s, %u connection(s)\n",
                INFO.name, (unsigned)iso_depth_steps(&app.controller),
                tcc_connected(&app.controller.tc) ? "connected" : "not connected",
                app.controller.tc.connections);
    }
    return rc;
}
