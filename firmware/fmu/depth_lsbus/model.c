/* The sowing-depth firmware (firmware/apps/depth_adapter.c and its core, unchanged) as an
 * FMI-LS-BUS CAN node (common/lsbus_fmu.h), looped as agrihil-depth-fw is in lockstep
 * (firmware/apps/app.c and depth_main.c): the boot-up frame at start, one control step per
 * SYNC with the adapter clock at steps x period, the adapter's answers to a frame sent at once,
 * and, when the string parameter agrihil_gnss_port names a serial port (the rig's
 * AGRIHIL_GNSS_PORT), the GNSS receiver's NMEA read before each frame is handled. Parameters
 * kp0, ki0, kd0 as --param. */
#include <string.h>

#include "lsbus_fmu.h"

#define SYNC_ID 0x080u
#define GNSS_BAUD 115200

const lsbus_param_t lsbus_model_params[] = {
    LSBUS_PARAM(vr_kp0, LSBUS_PARAM_FLOAT64, "kp0", kp0),
    LSBUS_PARAM(vr_ki0, LSBUS_PARAM_FLOAT64, "ki0", ki0),
    LSBUS_PARAM(vr_kd0, LSBUS_PARAM_FLOAT64, "kd0", kd0),
    LSBUS_PARAM(vr_gnss_port, LSBUS_PARAM_STRING, "agrihil_gnss_port", gnss_port),
};
const size_t lsbus_model_param_count = sizeof lsbus_model_params / sizeof lsbus_model_params[0];

void lsbus_model_defaults(ModelInstance *comp)
{
    UNUSED(comp);
}

bool lsbus_model_start(ModelInstance *comp)
{
    depth_config_t cfg;
    depth_config_defaults(&cfg);
    param_ref_t refs[DEPTH_PARAM_COUNT];
    size_t n = depth_param_refs(&cfg, refs);
    if (!lsbus_fmu_apply_float64(comp, refs, n, "the depth controller")) {
        return false;
    }
    char err[128];
    if (depth_config_check(&cfg, err, sizeof err) != 0) {
        logError(comp, "%s", err);
        return false;
    }
    depth_init(&M(adapter), &cfg);
    nmea_init(&M(nmea));
    if (M(gnss_port)[0] != '\0') {
        if (hal_serial_open(&M(gnss), M(gnss_port), GNSS_BAUD) != 0) {
            logError(comp, "GNSS (agrihil_gnss_port): %s", M(gnss).error);
            return false;
        }
        M(gnss_open) = true;
    }
    hal_can_frame_t boot = depth_bootup();
    lsbus_fmu_send(comp, &boot, 1);
    return true;
}

static double now_s(ModelInstance *comp)
{
    return (double)M(steps) * M(adapter).cfg.core.period_s;
}

static void poll_gnss(ModelInstance *comp)
{
    if (!M(gnss_open)) {
        return;
    }
    char buf[256];
    for (;;) {
        long n = hal_serial_read(&M(gnss), buf, sizeof buf);
        if (n < 0) {
            logError(comp, "GNSS: %s; going on without it", M(gnss).error);
            hal_serial_close(&M(gnss));
            M(gnss_open) = false;
            return;
        }
        if (n == 0) {
            return;
        }
        for (long i = 0; i < n; i++) {
            double mps;
            nmea_result_t r = nmea_feed(&M(nmea), buf[i], &mps);
            if (r == NMEA_SPEED) {
                depth_on_gnss(&M(adapter), true, mps, now_s(comp));
            } else if (r == NMEA_NO_FIX) {
                depth_on_gnss(&M(adapter), false, 0.0, now_s(comp));
            }
        }
    }
}

void lsbus_model_on_frame(ModelInstance *comp, const hal_can_frame_t *f)
{
    poll_gnss(comp);
    hal_can_frame_t out[DEPTH_MAX_OUT];
    size_t n;
    if (!f->extended && f->id == SYNC_ID) {
        n = depth_step(&M(adapter), now_s(comp), out);
        M(steps)++;
    } else {
        n = depth_on_frame(&M(adapter), f, now_s(comp), out);
    }
    lsbus_fmu_send(comp, out, n);
}
