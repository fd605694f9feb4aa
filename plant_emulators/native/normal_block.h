/* Standard normal variates handed out from blocks drawn by the Python side.
 *
 * The Python models draw per-step noise from plant_emulators.fertilizer.noise.NormalStream:
 * blocks of `size` variates from their own numpy generator, one value at a time. A C twin gets
 * the same sequence by asking the same generator for the same blocks: `refill` is called
 * whenever a block is used up (the module glue calls `rng.standard_normal(size)`), so the
 * values never depend on how the steps are split into calls.
 *
 * Header-only: each extension module includes it once.
 */
#ifndef AGRIHIL_NORMAL_BLOCK_H
#define AGRIHIL_NORMAL_BLOCK_H

#include <stddef.h>

/* Fill `block` with `n` new variates; 0 on success, nonzero on failure. */
typedef int (*nb_refill_fn)(void *ctx, double *block, size_t n);

typedef struct {
    double *values;      /* the current block (owned by the glue) */
    size_t size;         /* variates per block */
    size_t pos;          /* next value to hand out; == size: the block is used up */
    nb_refill_fn refill;
    void *ctx;
    int failed;          /* set when a refill failed: the caller must stop and report */
} NormalBlock;

/* The next variate. On a failed refill it sets `failed` and returns 0.0; once failed, it
 * never asks the source again (the caller's step stopped half done: its state is not one the
 * Python model could be in, so the model is unusable from then on). */
static inline double nb_next(NormalBlock *b)
{
    if (b->failed) {
        return 0.0;
    }
    if (b->pos >= b->size) {
        if (b->refill(b->ctx, b->values, b->size) != 0) {
            b->failed = 1;
            return 0.0;
        }
        b->pos = 0;
    }
    return b->values[b->pos++];
}

#endif
