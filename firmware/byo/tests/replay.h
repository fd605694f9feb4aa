/* Replay frame vectors written by a Python build (make_vectors*.py) through a C adapter: every
 * frame the adapter sends must equal the Python build's, byte for byte, in the same order.
 *
 * A file has lines "params K=V ...", "boot", "step", "in ID s|x HEX" (an event) and
 * "out ID s|x HEX" (a frame the Python build sent in answer to the event above). The replay
 * feeds the events to the adapter through replay_ops_t and compares what it answers.
 *
 * replay_main(): exit 0 when all files are equal; 1 naming the first difference of each file
 * (file:line, what was expected and what came), or a missing or unreadable file; 2 on bad
 * usage. */
#ifndef AGRIHIL_BYO_REPLAY_H
#define AGRIHIL_BYO_REPLAY_H

#include <stddef.h>

#include "hal_can.h"

#define REPLAY_MAX_OUT 32 /* frames one event may produce */

typedef struct {
    const char *program;
    /* start again with the default parameters */
    void (*reset)(void);
    /* the text after "params ": set the parameters and start again; 0, or 1 after printing
     * why (path:line) */
    int (*params)(const char *path, long line, char *text);
    size_t (*boot)(hal_can_frame_t out[REPLAY_MAX_OUT]);
    size_t (*step)(hal_can_frame_t out[REPLAY_MAX_OUT]);
    size_t (*on_frame)(const hal_can_frame_t *frame, hal_can_frame_t out[REPLAY_MAX_OUT]);
} replay_ops_t;

int replay_main(int argc, char **argv, const replay_ops_t *ops);

#endif
