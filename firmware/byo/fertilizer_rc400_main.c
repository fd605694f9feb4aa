/* agrihil-fertilizer-rc400-fw: [F]'s flow controller (piecewise PID) in the RateMaster RC-400's
 * CAN layout, as a host program. The command line is agrihil-fertilizer-fw's (app.h): --bus,
 * --sync, --period-ms, --param KEY=VALUE, --law (or a mode= / law= parameter, as the Python
 * build names it), --help, --version.
 *
 * The RC-400 sends two frames at start (its boot-up, then the SDO that configures the drive
 * module's consumer heartbeat); the app loop (apps/app.c) sends one boot-up frame, so the SDO
 * goes out just before the answer to the first frame or step, before any control output. */
#include <stdio.h>
#include <string.h>

#include "app.h"
#include "fertilizer_rc400_adapter.h"

typedef struct {
    rc400_adapter_t adapter;
    hal_can_frame_t boot[RC400_BOOT_FRAMES];
    size_t boot_sent; /* boot frames already on the bus */
} rc400_app_t;

static rc400_app_t app;

/* The boot frames the app loop has not sent yet, at the start of out[]. */
static size_t pending_boot(rc400_app_t *p, hal_can_frame_t *out)
{
    size_t n = 0;
    while (p->boot_sent < RC400_BOOT_FRAMES) {
        out[n++] = p->boot[p->boot_sent++];
    }
    return n;
}

static size_t on_frame(void *ctx, const hal_can_frame_t *frame, double now_s,
                       hal_can_frame_t *out)
{
    (void)now_s; /* ages are counted in control steps */
    rc400_app_t *p = ctx;
    rc400_on_frame(&p->adapter, frame);
    return pending_boot(p, out);
}

static size_t step(void *ctx, double now_s, hal_can_frame_t *out)
{
    (void)now_s;
    rc400_app_t *p = ctx;
    size_t n = pending_boot(p, out);
    return n + rc400_step(&p->adapter, out + n);
}

static const app_info_t INFO = {"agrihil-fertilizer-rc400-fw", true, 100.0};

static bool law_key(const char *key)
{
    return param_name_equal(key, "law") || param_name_equal(key, "mode");
}

/* law= / mode= were read before the defaults were set; app_apply_params skips them */
static int skip_law(void *ctx, const char *key, const char *value)
{
    (void)ctx;
    (void)value;
    return law_key(key) ? 1 : 0;
}

/* The law from --law or a law= / mode= parameter (the two must agree); physical by default.
 * Returns -1 when found, or APP_EXIT_USAGE (message printed). */
static int choose_law(const app_options_t *opt, ppid_law_t *law)
{
    const char *from_param = NULL;
    for (size_t i = 0; i < opt->nparams; i++) {
        char key[16];
        size_t len = strcspn(opt->params[i], "=");
        if (len < sizeof key) {
            memcpy(key, opt->params[i], len);
            key[len] = '\0';
            from_param = law_key(key) ? opt->params[i] + len + 1 : from_param;
        }
    }
    if (opt->law != NULL && from_param != NULL && strcmp(opt->law, from_param) != 0) {
        app_error(&INFO, "parameter 'mode' = '%s' contradicts --law %s", from_param, opt->law);
        return APP_EXIT_USAGE;
    }
    const char *text = opt->law != NULL ? opt->law : from_param != NULL ? from_param : "physical";
    if (!ppid_law_parse(text, law)) {
        app_error(&INFO, "unknown law '%s' (physical, paper-literal or open-loop)", text);
        return APP_EXIT_USAGE;
    }
    return -1;
}

int main(int argc, char **argv)
{
    app_options_t opt;
    int rc = app_parse_args(&INFO, argc, argv, &opt);
    if (rc >= 0) {
        return rc;
    }
    ppid_law_t law;
    rc = choose_law(&opt, &law);
    if (rc >= 0) {
        return rc;
    }
    static rc400_config_t cfg;
    rc400_config_defaults(&cfg, law);
    param_ref_t refs[RC400_PARAM_COUNT];
    size_t n = rc400_param_refs(&cfg, refs);
    rc = app_apply_params(&INFO, &opt, refs, n, skip_law, NULL);
    if (rc == 0) {
        rc = app_reconcile_period(&INFO, &opt, &cfg.period_s);
    }
    if (rc != 0) {
        return rc;
    }
    rc400_init(&app.adapter, &cfg);
    rc400_boot_frames(app.boot);
    app.boot_sent = 1; /* the boot-up goes out through the loop's own boot frame */
    fprintf(stderr, "%s: law %s\n", INFO.name, ppid_law_name(law));
    app_hooks_t hooks = {&app, on_frame, step, NULL, app.boot[0]};
    return app_run(&INFO, &opt, &hooks);
}
