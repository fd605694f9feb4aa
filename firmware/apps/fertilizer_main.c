/* agrihil-fertilizer-fw: the fertilizer flow controller of [F] (piecewise PID) as a host
 * program. See app.h for the command line; --law picks the control law (default physical). */
#include <stdio.h>
#include <string.h>

#include "app.h"
#include "fertilizer_adapter.h"

static fert_adapter_t adapter;

static size_t on_frame(void *ctx, const hal_can_frame_t *frame, double now_s,
                       hal_can_frame_t *out)
{
    (void)out;
    fert_on_frame(ctx, frame, now_s);
    return 0;
}

static size_t step(void *ctx, double now_s, hal_can_frame_t *out)
{
    return fert_step(ctx, now_s, out);
}

static const app_info_t INFO = {"agrihil-fertilizer-fw", true, 100.0};

static bool is_law_key(const char *key)
{
    return param_name_equal(key, "law") || param_name_equal(key, "mode");
}

/* law= / mode= were read before the defaults were set; here they are only skipped */
static int law_param(void *ctx, const char *key, const char *value)
{
    (void)ctx;
    (void)value;
    return is_law_key(key) ? 1 : 0;
}

int main(int argc, char **argv)
{
    app_options_t opt;
    int rc = app_parse_args(&INFO, argc, argv, &opt);
    if (rc >= 0) {
        return rc;
    }
    /* the law decides the default gains and thresholds: find it first, from --law or a
     * law= / mode= parameter (the Python build's name); the two must not disagree */
    const char *param_law = NULL;
    for (size_t i = 0; i < opt.nparams; i++) {
        const char *eq = strchr(opt.params[i], '=');
        char key[16];
        size_t len = (size_t)(eq - opt.params[i]);
        if (len < sizeof key) {
            memcpy(key, opt.params[i], len);
            key[len] = '\0';
            if (is_law_key(key)) {
                param_law = eq + 1;
            }
        }
    }
    if (opt.law != NULL && param_law != NULL && strcmp(opt.law, param_law) != 0) {
        app_error(&INFO, "parameter 'mode' = '%s' contradicts --law %s", param_law, opt.law);
        return APP_EXIT_USAGE;
    }
    const char *law_text = opt.law != NULL ? opt.law : param_law != NULL ? param_law : "physical";
    ppid_law_t law;
    if (!ppid_law_parse(law_text, &law)) {
        app_error(&INFO, "unknown law '%s' (physical, paper-literal or open-loop)", law_text);
        return APP_EXIT_USAGE;
    }
    static fert_config_t cfg;
    fert_config_defaults(&cfg, law);
    param_ref_t refs[FERT_PARAM_COUNT];
    size_t n = fert_param_refs(&cfg, refs);
    rc = app_apply_params(&INFO, &opt, refs, n, law_param, NULL);
    if (rc == 0) {
        rc = app_reconcile_period(&INFO, &opt, &cfg.period_s);
    }
    if (rc != 0) {
        return rc;
    }
    if (cfg.use_calibration != 0.0 && cfg.use_calibration != 1.0) {
        app_error(&INFO, "use_calibration must be 0 or 1, got %g", cfg.use_calibration);
        return APP_EXIT_USAGE;
    }
    fert_init(&adapter, &cfg);
    fprintf(stderr, "%s: law %s\n", INFO.name, ppid_law_name(law));
    app_hooks_t hooks = {&adapter, on_frame, step, NULL, fert_bootup()};
    return app_run(&INFO, &opt, &hooks);
}
