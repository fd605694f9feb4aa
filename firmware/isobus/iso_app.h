/* The control loop of the ISOBUS programs (agrihil-fertilizer-isobus-fw, isobus_main.c, and
 * agrihil-sowing-depth-isobus-fw, depth_isobus_main.c): app_run()'s contract (app.h: the boot-up frame first,
 * lockstep on SYNC or free-running on an absolute-deadline timer, SIGTERM/SIGINT -> 0, a bus
 * failure -> 1), but a step may send as many frames as the controller's outbox holds: a CTS from
 * the Task Controller is answered with up to 255 TP data frames at once, more than app_run's
 * APP_MAX_OUT (8). The controller keeps its own step clock (steps x period), so the loop hands it
 * frames and steps, never a time. */
#ifndef AGRIHIL_ISO_APP_H
#define AGRIHIL_ISO_APP_H

#include <stddef.h>

#include "app.h"
#include "hal_can.h"

typedef struct {
    void *ctx;
    /* take a frame (a SYNC steps in lockstep); returns the count of frames in *out */
    size_t (*on_frame)(void *ctx, const hal_can_frame_t *frame);
    /* one free-running step; returns the count of frames in *out */
    size_t (*step)(void *ctx);
    const hal_can_frame_t *(*out)(void *ctx);
    /* optional: after every wake-up (the GNSS serial port) */
    void (*poll)(void *ctx);
    hal_can_frame_t bootup;
} iso_app_hooks_t;

/* Open the bus, send the boot-up frame, run until SIGTERM/SIGINT. Returns the exit status. */
int iso_app_run(const app_info_t *info, const app_options_t *opt, const iso_app_hooks_t *h);

#endif
