/* What replay_isobus.c needs of the controller it replays the vectors through: one
 * implementation per program (replay_fert.c: iso_fert, the fertilizer's vectors in
 * reference_controllers/vectors/isobus-*.frames; replay_depth.c: iso_depth, the depth
 * vectors in firmware/isobus/data/depth-isobus-*.frames). */
#ifndef AGRIHIL_REPLAY_CTL_H
#define AGRIHIL_REPLAY_CTL_H

#include <stdbool.h>
#include <stddef.h>

#include "hal_can.h"

/* Frames one input can produce at most. */
#define REPLAY_MAX_OUT 400

/* Set the controller up from a "#params key=value ..." line (the text after "#params").
 * Returns 0, or 2 with a message naming path and the bad parameter on stderr. */
int replay_configure(const char *path, char *params);

hal_can_frame_t replay_bootup(void);

/* Hand the controller a frame; returns the count of frames it sent (replay_out()). */
size_t replay_on_frame(const hal_can_frame_t *frame);
const hal_can_frame_t *replay_out(void);

/* A line that is not a frame ('G ...': a GNSS report): 0 taken, -1 not a line this
 * controller knows. */
int replay_other(const char *line);

unsigned replay_steps(void);

#endif
