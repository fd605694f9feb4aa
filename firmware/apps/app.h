/* What the two firmware apps share: the command line, signals, and the control loop.
 *
 * Command line (both apps):
 *   --bus SPEC          socketcan:IFACE or socketcand:HOST:PORT[/CHANNEL] (default: $AGRIHIL_BUS)
 *   --sync              lockstep: one control step per received SYNC (0x080)
 *   --period-ms N       free-running period on an absolute-deadline timer (and the step length
 *                       the adapter's clock advances per SYNC in lockstep)
 *   --param KEY=VALUE   set a parameter (repeatable); an unknown key is an error
 *   --help, --version
 * Exit status: 0 after SIGTERM/SIGINT, 1 on a bus failure, 2 on bad arguments. */
#ifndef AGRIHIL_APP_H
#define AGRIHIL_APP_H

#include <stdbool.h>
#include <stddef.h>

#include "hal_can.h"
#include "params.h"

#define APP_MAX_PARAMS 64
#define APP_MAX_OUT 8
#define AGRIHIL_FW_VERSION "1.0.0"

enum { APP_EXIT_OK = 0, APP_EXIT_BUS = 1, APP_EXIT_USAGE = 2 };

typedef struct {
    const char *bus;
    bool sync;
    double period_ms;
    bool period_given;
    char *params[APP_MAX_PARAMS]; /* "key=value" from --param, in order */
    size_t nparams;
    const char *law; /* fertilizer only: --law */
} app_options_t;

typedef struct {
    const char *name;  /* program name for messages */
    bool has_law;      /* accepts --law */
    double default_period_ms;
} app_info_t;

/* Parse argv. Returns -1 to continue, or an exit status (0 after --help/--version, 2 on a
 * usage error, message already printed). */
int app_parse_args(const app_info_t *info, int argc, char **argv, app_options_t *opt);

/* Apply the --param KEY=VALUE list to `table`. `special` (optional) sees each key first and
 * returns 1 if it took it, 0 if not, -1 if the value is bad (it printed why). An unknown key or
 * a bad number prints a message naming the key and returns APP_EXIT_USAGE; 0 when all applied. */
int app_apply_params(const app_info_t *info, app_options_t *opt, const param_ref_t *table,
                     size_t n, int (*special)(void *ctx, const char *key, const char *value),
                     void *ctx);

/* Whether --param named `key` (case-insensitive), before or after app_apply_params. */
bool app_param_given(const app_options_t *opt, const char *key);

/* Reconcile --period-ms with a period_s parameter (both name the control period): period_s
 * alone sets the period; both must agree (else a message and APP_EXIT_USAGE); otherwise
 * *period_s is set from --period-ms. Call after app_apply_params. Returns 0 or the status. */
int app_reconcile_period(const app_info_t *info, app_options_t *opt, double *period_s);

/* The app's side of the loop. Every callback may emit frames into out[] (capacity APP_MAX_OUT)
 * and returns their count. now_s is the adapter clock: in lockstep the time of the next step
 * (steps done x period), free-running the monotonic time since start. */
typedef struct {
    void *ctx;
    size_t (*on_frame)(void *ctx, const hal_can_frame_t *frame, double now_s,
                       hal_can_frame_t *out);
    size_t (*step)(void *ctx, double now_s, hal_can_frame_t *out);
    /* optional: called after every wake-up (e.g. to drain the GNSS serial port) */
    void (*poll)(void *ctx, double now_s);
    hal_can_frame_t bootup;
} app_hooks_t;

/* Open the bus, send the boot-up frame, run until SIGTERM/SIGINT. Returns the exit status. */
int app_run(const app_info_t *info, const app_options_t *opt, const app_hooks_t *hooks);

/* Print "NAME: message" to stderr. */
void app_error(const app_info_t *info, const char *fmt, ...);

#endif
