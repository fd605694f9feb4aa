/* Replay the DP-200 frame vectors of the Python build (make_vectors_dp200.py) through the C
 * adapter (replay.h): every frame it sends (the drive's configuration by SDO, the NMT start,
 * the mode write, status, heartbeat, drive commands) must equal the Python build's, byte for
 * byte, in order.
 *
 *   replay_dp200 FILE...     exit 0 when all equal; 1 naming the first difference of each file
 *                            (file:line, what was expected and what came), or a missing or
 *                            unreadable file; 2 on bad usage */
#include <stdio.h>
#include <string.h>

#include "depth_dp200_adapter.h"
#include "replay.h"

_Static_assert(DP200_MAX_OUT <= REPLAY_MAX_OUT, "the replay holds every frame of an event");

static dp200_adapter_t adapter;
static dp200_config_t cfg;

static void reset(void)
{
    dp200_config_defaults(&cfg);
    dp200_init(&adapter, &cfg);
}

static int set_params(const char *path, long line, char *text)
{
    dp200_config_defaults(&cfg);
    param_ref_t refs[DP200_PARAM_COUNT];
    size_t n = dp200_param_refs(&cfg, refs);
    int failed = 0;
    for (char *tok = strtok(text, " \n"); tok != NULL && !failed; tok = strtok(NULL, " \n")) {
        char *value = param_split(tok);
        if (value == NULL || param_set(refs, n, tok, value) != PARAM_OK) {
            fprintf(stderr, "%s:%ld: bad parameter '%s'\n", path, line, tok);
            failed = 1;
        }
    }
    char err[128];
    if (!failed && dp200_config_check(&cfg, err, sizeof err) != 0) {
        fprintf(stderr, "%s:%ld: %s\n", path, line, err);
        failed = 1;
    }
    dp200_init(&adapter, &cfg);
    return failed;
}

static size_t boot(hal_can_frame_t out[REPLAY_MAX_OUT])
{
    out[0] = dp200_bootup();
    return 1;
}

static size_t step(hal_can_frame_t out[REPLAY_MAX_OUT])
{
    return dp200_step(&adapter, out);
}

static size_t on_frame(const hal_can_frame_t *frame, hal_can_frame_t out[REPLAY_MAX_OUT])
{
    return dp200_on_frame(&adapter, frame, out);
}

int main(int argc, char **argv)
{
    static const replay_ops_t ops = {"replay_dp200", reset, set_params, boot, step, on_frame};
    return replay_main(argc, argv, &ops);
}
