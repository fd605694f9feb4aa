/* replay_isobus_depth's controller: the depth controller's ISOBUS mode (iso_depth). Besides
 * frames, its vectors carry the GNSS receiver's reports: 'G SPEED' (m/s, a valid fix) and
 * 'G nofix', applied at the next step as the serial port's are. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_depth.h"
#include "replay_ctl.h"

_Static_assert(ISO_DEPTH_MAX_OUT <= REPLAY_MAX_OUT, "a step's frames fit the replay");

static iso_depth_t ctl;

/* key=value ... (the Python's names; actual= and fallback= are words) */
int replay_configure(const char *path, char *params)
{
    iso_depth_config_t cfg;
    iso_depth_config_defaults(&cfg);
    param_ref_t refs[ISO_DEPTH_PARAM_COUNT];
    size_t n = iso_depth_param_refs(&cfg, refs);
    char *save = NULL;
    for (char *tok = strtok_r(params, " \t\n", &save); tok; tok = strtok_r(NULL, " \t\n", &save)) {
        char *value = param_split(tok);
        if (value == NULL) {
            fprintf(stderr, "%s: '%s' is not key=value\n", path, tok);
            return 2;
        }
        const char *why = NULL;
        int word = iso_depth_word_param(&cfg, tok, value, &why);
        if (word < 0) {
            fprintf(stderr, "%s: %s, got %s\n", path, why, value);
            return 2;
        }
        if (word == 0 && param_set(refs, n, tok, value) != PARAM_OK) {
            fprintf(stderr, "%s: bad parameter %s=%s\n", path, tok, value);
            return 2;
        }
    }
    char err[128];
    if (iso_depth_check(&cfg, err, sizeof err) != 0) {
        fprintf(stderr, "%s: %s\n", path, err);
        return 2;
    }
    if (iso_depth_init(&ctl, &cfg) != 0) {
        fprintf(stderr, "%s: the pool cannot be written\n", path);
        return 2;
    }
    return 0;
}

hal_can_frame_t replay_bootup(void)
{
    return iso_depth_bootup();
}

size_t replay_on_frame(const hal_can_frame_t *frame)
{
    return iso_depth_on_frame(&ctl, frame);
}

const hal_can_frame_t *replay_out(void)
{
    return ctl.out;
}

int replay_other(const char *line)
{
    if (strncmp(line, "G ", 2) != 0) {
        return -1;
    }
    if (strncmp(line + 2, "nofix", 5) == 0) {
        iso_depth_on_gnss(&ctl, false, 0.0);
        return 0;
    }
    char *end = NULL;
    double mps = strtod(line + 2, &end);
    if (end == line + 2) {
        return -1;
    }
    iso_depth_on_gnss(&ctl, true, mps);
    return 0;
}

unsigned replay_steps(void)
{
    return (unsigned)iso_depth_steps(&ctl);
}
