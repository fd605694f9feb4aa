/* agrihil-fertilizer-isobus-fw: the fertilizer flow controller of [F] as an ISOBUS implement
 * (iso_fert.h). The command line is agrihil-fertilizer-fw's (app.h: --bus, --sync,
 * --period-ms, --law, --param KEY=VALUE), with the ISOBUS mode's parameters as the Python
 * controller names them: address, identity_number, width_m (numbers), speed=ground|wheel,
 * ddop=valid|broken; vt=yes (the operator interface on a VT, isobus_vt.py) and vt_defect=NAME.
 *
 * The loop is iso_app_run (iso_app.h), not app_run(): a CTS from the Task Controller is
 * answered with up to 255 TP data frames at once, more than app_run's APP_MAX_OUT (8). As
 * there, the command frame 0x220 ends each step (so no step-end frame is needed in lockstep),
 * the boot-up frame goes first, SIGTERM/SIGINT stop it with status 0, a bus failure gives 1,
 * bad arguments 2. */
#include <stdio.h>
#include <string.h>

#include "app.h"
#include "iso_app.h"
#include "iso_fert.h"

static const app_info_t INFO = {"agrihil-fertilizer-isobus-fw", true, 100.0};
static iso_fert_t controller;
static iso_fert_config_t cfg;

static bool is_law_key(const char *key)
{
    return param_name_equal(key, "law") || param_name_equal(key, "mode");
}

/* the word-valued parameters; law= / mode= were read before the defaults were set */
static int word_param(void *ctx, const char *key, const char *value)
{
    iso_fert_config_t *c = ctx;
    if (is_law_key(key)) {
        return 1;
    }
    if (param_name_equal(key, "speed")) {
        if (strcmp(value, "ground") != 0 && strcmp(value, "wheel") != 0) {
            app_error(&INFO, "parameter 'speed' must be ground or wheel, got '%s'", value);
            return -1;
        }
        c->speed_wheel = strcmp(value, "wheel") == 0;
        return 1;
    }
    if (param_name_equal(key, "ddop")) {
        if (strcmp(value, "valid") != 0 && strcmp(value, "broken") != 0) {
            app_error(&INFO, "parameter 'ddop' must be valid or broken, got '%s'", value);
            return -1;
        }
        c->ddop_broken = strcmp(value, "broken") == 0;
        return 1;
    }
    const char *why = NULL;
    int vt = iso_fert_vt_param(c, key, value, &why);
    if (vt < 0) {
        app_error(&INFO, "%s, got '%s'", why, value);
    }
    return vt;
}

static size_t on_frame(void *ctx, const hal_can_frame_t *frame)
{
    return iso_fert_on_frame(ctx, frame);
}

static size_t step(void *ctx)
{
    return iso_fert_step(ctx);
}

static const hal_can_frame_t *out(void *ctx)
{
    return ((iso_fert_t *)ctx)->out;
}

static int run(const app_options_t *opt)
{
    iso_app_hooks_t hooks = {&controller, on_frame, step, out, NULL, iso_fert_bootup()};
    int status = iso_app_run(&INFO, opt, &hooks);
    if (status == APP_EXIT_OK) {
        fprintf(stderr, "%s: stopped after %u steps, TC client %s, %u connection(s)\n",
                INFO.name, (unsigned)controller.steps,
                tcc_connected(&controller.tc) ? "connected" : "not connected",
                controller.tc.connections);
        if (cfg.vt) {
            fprintf(stderr, "%s: VT client %s, %u connection(s), %u upload(s)%s\n", INFO.name,
                    vtc_connected(&controller.vt) ? "connected" : "not connected",
                    controller.vt.connections, controller.vt.uploads,
                    controller.vt.refused ? ", pool refused" : "");
        }
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
    const char *param_law = NULL;
    for (size_t i = 0; i < opt.nparams; i++) {
        const char *eq = strchr(opt.params[i], '=');
        char key[16];
        size_t len = eq != NULL ? (size_t)(eq - opt.params[i]) : 0;
        if (eq != NULL && len < sizeof key) {
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
    if (!ppid_law_parse(law_text, &law) || law == PPID_LAW_OPEN_LOOP) {
        app_error(&INFO, "unknown law '%s' (the ISOBUS mode runs physical or paper-literal)",
                  law_text);
        return APP_EXIT_USAGE;
    }
    iso_fert_config_defaults(&cfg, law);
    cfg.step_on_sync = opt.sync;
    param_ref_t refs[ISO_FERT_PARAM_COUNT];
    size_t n = iso_fert_param_refs(&cfg, refs);
    rc = app_apply_params(&INFO, &opt, refs, n, word_param, &cfg);
    if (rc == 0) {
        rc = app_reconcile_period(&INFO, &opt, &cfg.fert.period_s);
    }
    if (rc != 0) {
        return rc;
    }
    const char *why = iso_fert_check(&cfg);
    if (why != NULL) {
        app_error(&INFO, "%s", why);
        return APP_EXIT_USAGE;
    }
    if (iso_fert_init(&controller, &cfg) != 0) {
        app_error(&INFO, "the DDOP does not fit a TP transfer (%u bytes at most)",
                  (unsigned)ISO_DDOP_MAX_BYTES);
        return APP_EXIT_USAGE;
    }
    fprintf(stderr, "%s: law %s, NAME 0x%016llX, preferred address 0x%02X, DDOP %u bytes\n",
            INFO.name, ppid_law_name(law), (unsigned long long)controller.name,
            (unsigned)cfg.address, (unsigned)controller.pool.size);
    return run(&opt);
}
