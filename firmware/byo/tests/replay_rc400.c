/* Replay the RC-400 frame vectors of the Python build (make_vectors.py) through the C adapter
 * (replay.h): every frame it sends must equal the Python build's, byte for byte, in order.
 *
 *   replay_rc400 FILE...     exit 0 when all equal; 1 naming the first difference of each file
 *                            (file:line, what was expected and what came), or a missing or
 *                            unreadable file; 2 on bad usage */
#include <stdio.h>
#include <string.h>

#include "fertilizer_rc400_adapter.h"
#include "replay.h"

_Static_assert(RC400_MAX_OUT <= REPLAY_MAX_OUT && RC400_BOOT_FRAMES <= REPLAY_MAX_OUT,
               "the replay holds every frame of a step");

static rc400_adapter_t adapter;
static rc400_config_t cfg;

static void reset(void)
{
    rc400_config_defaults(&cfg, PPID_LAW_PHYSICAL);
    rc400_init(&adapter, &cfg);
}

static int set_params(const char *path, long line, char *text)
{
    /* the law first: it decides the defaults and which names exist */
    ppid_law_t law = PPID_LAW_PHYSICAL;
    const char *mode = strstr(text, "mode=");
    int failed = 0;
    if (mode != NULL) {
        char name[32];
        if (sscanf(mode + 5, "%31s", name) != 1 || !ppid_law_parse(name, &law)) {
            fprintf(stderr, "%s:%ld: unknown law in '%s'\n", path, line, text);
            return 1;
        }
    }
    rc400_config_defaults(&cfg, law);
    param_ref_t refs[RC400_PARAM_COUNT];
    size_t n = rc400_param_refs(&cfg, refs);
    for (char *tok = strtok(text, " \n"); tok != NULL && !failed; tok = strtok(NULL, " \n")) {
        char *value = param_split(tok);
        if (value == NULL) {
            fprintf(stderr, "%s:%ld: '%s' is not KEY=VALUE\n", path, line, tok);
            failed = 1;
        } else if (strcmp(tok, "mode") != 0 && param_set(refs, n, tok, value) != PARAM_OK) {
            fprintf(stderr, "%s:%ld: bad parameter '%s=%s'\n", path, line, tok, value);
            failed = 1;
        }
    }
    rc400_init(&adapter, &cfg);
    return failed;
}

static size_t boot(hal_can_frame_t out[REPLAY_MAX_OUT])
{
    return rc400_boot_frames(out);
}

static size_t step(hal_can_frame_t out[REPLAY_MAX_OUT])
{
    return rc400_step(&adapter, out);
}

static size_t on_frame(const hal_can_frame_t *frame, hal_can_frame_t out[REPLAY_MAX_OUT])
{
    (void)out;
    rc400_on_frame(&adapter, frame);
    return 0;
}

int main(int argc, char **argv)
{
    static const replay_ops_t ops = {"replay_rc400", reset, set_params, boot, step, on_frame};
    return replay_main(argc, argv, &ops);
}
