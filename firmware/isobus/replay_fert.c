/* replay_isobus's controller: the fertilizer's ISOBUS mode (iso_fert). */
#include <stdio.h>
#include <string.h>

#include "iso_fert.h"
#include "replay_ctl.h"

_Static_assert(ISO_FERT_MAX_OUT <= REPLAY_MAX_OUT, "a step's frames fit the replay");

static iso_fert_t ctl;

/* law=... speed=... ddop=... key=value ... */
int replay_configure(const char *path, char *params)
{
    iso_fert_config_t cfg;
    ppid_law_t law = PPID_LAW_PHYSICAL;
    char copy[512];
    snprintf(copy, sizeof copy, "%s", params);
    char *save = NULL;
    for (char *tok = strtok_r(copy, " \t\n", &save); tok; tok = strtok_r(NULL, " \t\n", &save)) {
        if (strncmp(tok, "law=", 4) == 0 && !ppid_law_parse(tok + 4, &law)) {
            fprintf(stderr, "%s: unknown law '%s'\n", path, tok + 4);
            return 2;
        }
    }
    iso_fert_config_defaults(&cfg, law);
    param_ref_t refs[ISO_FERT_PARAM_COUNT];
    size_t n = iso_fert_param_refs(&cfg, refs);
    for (char *tok = strtok_r(params, " \t\n", &save); tok; tok = strtok_r(NULL, " \t\n", &save)) {
        char *value = param_split(tok);
        if (value == NULL) {
            fprintf(stderr, "%s: '%s' is not key=value\n", path, tok);
            return 2;
        }
        if (param_name_equal(tok, "law") || param_name_equal(tok, "mode")) {
            continue;
        }
        if (param_name_equal(tok, "speed")) {
            cfg.speed_wheel = strcmp(value, "wheel") == 0;
            continue;
        }
        if (param_name_equal(tok, "ddop")) {
            cfg.ddop_broken = strcmp(value, "broken") == 0;
            continue;
        }
        const char *vt_why = NULL;
        int vt = iso_fert_vt_param(&cfg, tok, value, &vt_why);
        if (vt < 0) {
            fprintf(stderr, "%s: %s\n", path, vt_why);
            return 2;
        }
        if (vt > 0) {
            continue; /* vt=yes, vt_defect=... (the VT vectors, data/vt-*.frames) */
        }
        if (param_set(refs, n, tok, value) != PARAM_OK) {
            fprintf(stderr, "%s: bad parameter %s=%s\n", path, tok, value);
            return 2;
        }
    }
    const char *why = iso_fert_check(&cfg);
    if (why != NULL) {
        fprintf(stderr, "%s: %s\n", path, why);
        return 2;
    }
    if (iso_fert_init(&ctl, &cfg) != 0) {
        fprintf(stderr, "%s: the pool cannot be written\n", path);
        return 2;
    }
    return 0;
}

hal_can_frame_t replay_bootup(void)
{
    return iso_fert_bootup();
}

size_t replay_on_frame(const hal_can_frame_t *frame)
{
    return iso_fert_on_frame(&ctl, frame);
}

const hal_can_frame_t *replay_out(void)
{
    return ctl.out;
}

int replay_other(const char *line)
{
    (void)line;
    return -1;
}

unsigned replay_steps(void)
{
    return (unsigned)ctl.steps;
}
