/* CPython side of normal_block.h: a NormalBlock refilled by a Python callable.
 *
 * `draw` is called as draw() and must return an object with the buffer protocol holding
 * exactly `size` C doubles (numpy's rng.standard_normal(size) does). Header-only, for the
 * extension modules' glue.
 */
#ifndef AGRIHIL_PY_NORMAL_BLOCK_H
#define AGRIHIL_PY_NORMAL_BLOCK_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

#include "normal_block.h"

/* ctx is the callable (a borrowed reference held by the owning object). */
static int pynb_refill(void *ctx, double *block, size_t n)
{
    PyObject *values = PyObject_CallNoArgs((PyObject *)ctx);
    if (values == NULL) {
        return -1;
    }
    Py_buffer view;
    if (PyObject_GetBuffer(values, &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) != 0) {
        Py_DECREF(values);
        return -1;
    }
    int ok = view.itemsize == (Py_ssize_t)sizeof(double) && view.format != NULL
             && strcmp(view.format, "d") == 0 && view.len == (Py_ssize_t)(n * sizeof(double));
    if (ok) {
        memcpy(block, view.buf, n * sizeof(double));
    } else {
        PyErr_Format(PyExc_ValueError,
                     "the normal-variate source must return %zu C doubles, got %zd bytes "
                     "of format %s", n, view.len, view.format ? view.format : "?");
    }
    PyBuffer_Release(&view);
    Py_DECREF(values);
    return ok ? 0 : -1;
}

/* -1 with a RuntimeError when an earlier refill failed (the model stopped mid-step and
 * cannot go on), else 0. Call it before stepping. */
static inline int pynb_check_usable(const NormalBlock *b)
{
    if (b->failed) {
        PyErr_SetString(PyExc_RuntimeError,
                        "an earlier draw of noise failed in the middle of a step (see the "
                        "error raised then); this model's state is inconsistent: build a new "
                        "one");
        return -1;
    }
    return 0;
}

/* Point `b` at `storage` (size doubles), empty, refilled by `draw`. */
static inline void pynb_init(NormalBlock *b, double *storage, size_t size, PyObject *draw)
{
    b->values = storage;
    b->size = size;
    b->pos = size;
    b->refill = pynb_refill;
    b->ctx = draw;
    b->failed = 0;
}

#endif
