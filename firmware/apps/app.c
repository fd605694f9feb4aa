#include "app.h"

#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_time.h"
#include "params.h"

#define SYNC_ID 0x080u
#define IDLE_WAIT_US 50000 /* longest blocking wait: how soon a signal is noticed at worst */

static volatile sig_atomic_t stop_requested = 0;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

void app_error(const app_info_t *info, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "%s: ", info->name);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

static void usage(const app_info_t *info, FILE *to)
{
    fprintf(to,
            "usage: %s [--bus SPEC] [--sync | --period-ms N] [--param KEY=VALUE]...%s\n"
            "  --bus SPEC         socketcan:IFACE or socketcand:HOST:PORT[/CHANNEL]\n"
            "                     (default: $AGRIHIL_BUS)\n"
            "  --sync             lockstep: one control step per SYNC (0x080)\n"
            "  --period-ms N      free-running control period (default %g ms)\n"
            "  --param KEY=VALUE  set a parameter (repeatable)\n"
            "%s"
            "  --help, --version\n",
            info->name, info->has_law ? " [--law LAW]" : "", info->default_period_ms,
            info->has_law ? "  --law LAW          physical | paper-literal | open-loop\n" : "");
}

int app_parse_args(const app_info_t *info, int argc, char **argv, app_options_t *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->period_ms = info->default_period_ms;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        const char *value = NULL;
        /* --opt=value as well as --opt value */
        char name[32];
        const char *eq = strchr(arg, '=');
        if (strncmp(arg, "--", 2) == 0 && eq != NULL && (size_t)(eq - arg) < sizeof name) {
            memcpy(name, arg, (size_t)(eq - arg));
            name[eq - arg] = '\0';
            value = eq + 1;
        } else {
            snprintf(name, sizeof name, "%s", arg);
        }
        bool takes_value = strcmp(name, "--bus") == 0 || strcmp(name, "--period-ms") == 0 ||
                           strcmp(name, "--param") == 0 ||
                           (info->has_law && strcmp(name, "--law") == 0);
        if (takes_value && value == NULL) {
            if (i + 1 >= argc) {
                app_error(info, "%s needs a value", name);
                return APP_EXIT_USAGE;
            }
            value = argv[++i];
        } else if (!takes_value && value != NULL) {
            app_error(info, "%s takes no value", name);
            return APP_EXIT_USAGE;
        }
        if (strcmp(name, "--help") == 0 || strcmp(name, "-h") == 0) {
            usage(info, stdout);
            return APP_EXIT_OK;
        } else if (strcmp(name, "--version") == 0) {
            printf("%s %s\n", info->name, AGRIHIL_FW_VERSION);
            return APP_EXIT_OK;
        } else if (strcmp(name, "--sync") == 0) {
            opt->sync = true;
        } else if (strcmp(name, "--bus") == 0) {
            opt->bus = value;
        } else if (strcmp(name, "--law") == 0) {
            opt->law = value;
        } else if (strcmp(name, "--period-ms") == 0) {
            double ms;
            if (!param_parse_double(value, &ms) || !(ms > 0.0) || ms > 60000.0) {
                app_error(info, "--period-ms: '%s' is not a period in ms (0 < N <= 60000)",
                          value);
                return APP_EXIT_USAGE;
            }
            opt->period_ms = ms;
            opt->period_given = true;
        } else if (strcmp(name, "--param") == 0) {
            if (strchr(value, '=') == NULL || value[0] == '=') {
                app_error(info, "--param: '%s' is not KEY=VALUE", value);
                return APP_EXIT_USAGE;
            }
            if (opt->nparams == APP_MAX_PARAMS) {
                app_error(info, "--param: more than %d parameters", APP_MAX_PARAMS);
                return APP_EXIT_USAGE;
            }
            opt->params[opt->nparams++] = (char *)value; /* argv strings are writable */
        } else {
            app_error(info, "unknown argument '%s' (see --help)", arg);
            return APP_EXIT_USAGE;
        }
    }
    if (opt->bus == NULL) {
        const char *env = getenv("AGRIHIL_BUS");
        if (env == NULL || *env == '\0') {
            app_error(info, "no bus: give --bus SPEC or set AGRIHIL_BUS "
                            "(e.g. socketcand:127.0.0.1:29536/can0)");
            return APP_EXIT_USAGE;
        }
        opt->bus = env;
    }
    bus_spec_t spec;
    char err[HAL_CAN_ERRLEN];
    if (bus_spec_parse(opt->bus, &spec, err, sizeof err) != 0) {
        app_error(info, "%s", err);
        return APP_EXIT_USAGE;
    }
    return -1;
}

int app_apply_params(const app_info_t *info, app_options_t *opt, const param_ref_t *table,
                     size_t n, int (*special)(void *ctx, const char *key, const char *value),
                     void *ctx)
{
    for (size_t i = 0; i < opt->nparams; i++) {
        char *key = opt->params[i];
        char *value = param_split(key);
        if (value == NULL) {
            app_error(info, "--param: '%s' is not KEY=VALUE", key);
            return APP_EXIT_USAGE;
        }
        if (special != NULL) {
            int taken = special(ctx, key, value);
            if (taken < 0) {
                return APP_EXIT_USAGE;
            }
            if (taken > 0) {
                continue;
            }
        }
        param_status_t st = param_set(table, n, key, value);
        if (st == PARAM_UNKNOWN) {
            char known[512] = "";
            size_t used = 0;
            for (size_t k = 0; k < n && used < sizeof known; k++) {
                int w = snprintf(known + used, sizeof known - used, "%s%s", k ? ", " : "",
                                 table[k].name);
                used += w > 0 ? (size_t)w : 0;
            }
            app_error(info, "unknown parameter '%s' (known: %s)", key, known);
            return APP_EXIT_USAGE;
        }
        if (st == PARAM_BAD_VALUE) {
            app_error(info, "parameter '%s': '%s' is not a number", key, value);
            return APP_EXIT_USAGE;
        }
    }
    return 0;
}

bool app_param_given(const app_options_t *opt, const char *key)
{
    size_t klen = strlen(key);
    for (size_t i = 0; i < opt->nparams; i++) {
        const char *p = opt->params[i];
        size_t len = strcspn(p, "=");
        if (len == klen) {
            char name[64];
            if (len >= sizeof name) {
                continue;
            }
            memcpy(name, p, len);
            name[len] = '\0';
            if (param_name_equal(name, key)) {
                return true;
            }
        }
    }
    return false;
}

int app_reconcile_period(const app_info_t *info, app_options_t *opt, double *period_s)
{
    if (!app_param_given(opt, "period_s")) {
        *period_s = opt->period_ms / 1000.0;
        return 0;
    }
    if (!(*period_s > 0.0) || *period_s > 60.0) {
        app_error(info, "parameter 'period_s': %g is not a period in s (0 < T <= 60)",
                  *period_s);
        return APP_EXIT_USAGE;
    }
    if (opt->period_given && fabs(*period_s * 1000.0 - opt->period_ms) > 1e-9) {
        app_error(info, "parameter 'period_s' = %g s contradicts --period-ms %g", *period_s,
                  opt->period_ms);
        return APP_EXIT_USAGE;
    }
    opt->period_ms = *period_s * 1000.0;
    return 0;
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

int app_run(const app_info_t *info, const app_options_t *opt, const app_hooks_t *hooks)
{
    static hal_can_t bus; /* static: the receive buffer is too big for a small stack */
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0; /* no SA_RESTART: a blocking wait returns at once */
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    if (hal_can_open(&bus, opt->bus) != 0) {
        app_error(info, "%s", bus.error);
        return APP_EXIT_BUS;
    }
    hal_can_frame_t out[APP_MAX_OUT];
    if (send_all(info, &bus, &hooks->bootup, 1) != 0) {
        hal_can_close(&bus);
        return APP_EXIT_BUS;
    }
    fprintf(stderr, "%s: on %s, %s, period %g ms\n", info->name, opt->bus,
            opt->sync ? "lockstep (one step per SYNC)" : "free-running", opt->period_ms);

    const double period_s = opt->period_ms / 1000.0;
    const int64_t period_ns = (int64_t)(opt->period_ms * 1e6);
    const int64_t start_ns = hal_time_now_ns();
    int64_t deadline_ns = start_ns + period_ns;
    uint64_t steps = 0;
    int status = APP_EXIT_OK;

    while (!stop_requested) {
        int64_t now_ns = hal_time_now_ns();
        double now_s = opt->sync ? (double)steps * period_s : (double)(now_ns - start_ns) / 1e9;
        int64_t wait_us = IDLE_WAIT_US;
        if (!opt->sync) {
            if (now_ns >= deadline_ns) {
                size_t n = hooks->step(hooks->ctx, now_s, out);
                steps++;
                if (send_all(info, &bus, out, n) != 0) {
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
        if (opt->sync) {
            now_s = (double)steps * period_s;
        } else {
            now_s = (double)(hal_time_now_ns() - start_ns) / 1e9;
        }
        if (hooks->poll != NULL) {
            hooks->poll(hooks->ctx, now_s);
        }
        if (rc != HAL_CAN_FRAME) {
            continue;
        }
        size_t n;
        if (opt->sync && !frame.extended && frame.id == SYNC_ID) {
            n = hooks->step(hooks->ctx, now_s, out);
            steps++;
        } else {
            n = hooks->on_frame(hooks->ctx, &frame, now_s, out);
        }
        if (send_all(info, &bus, out, n) != 0) {
            status = APP_EXIT_BUS;
            break;
        }
    }
    hal_can_close(&bus);
    if (status == APP_EXIT_OK) {
        fprintf(stderr, "%s: stopped after %llu steps\n", info->name, (unsigned long long)steps);
    }
    return status;
}
