/* CPython glue shared by the physics twins' extension modules: argument conversion, the
 * "initialised and bound" check, and the module set-up (one extension type plus the block
 * size of the normal variates). Header-only: each module includes it once. */
#ifndef AGRIHIL_PY_GLUE_H
#define AGRIHIL_PY_GLUE_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "py_normal_block.h"

/* Variates per block the twins ask their Python source for: NormalStream's block size. */
#define NORMAL_BLOCK 1024

/* `seq` as exactly n doubles into out; -1 with a Python error naming `name` otherwise. */
static inline int pyglue_doubles(PyObject *seq, const char *name, Py_ssize_t n,
                                 double *out)
{
    PyObject *fast = PySequence_Fast(seq, name);
    if (fast == NULL) {
        return -1;
    }
    if (PySequence_Fast_GET_SIZE(fast) != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", name, n,
                     PySequence_Fast_GET_SIZE(fast));
        Py_DECREF(fast);
        return -1;
    }
    for (Py_ssize_t i = 0; i < n; ++i) {
        out[i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(fast, i));
        if (out[i] == -1.0 && PyErr_Occurred()) {
            Py_DECREF(fast);
            return -1;
        }
    }
    Py_DECREF(fast);
    return 0;
}

/* -1 with a RuntimeError when a twin of type `type_name` is not initialised, or (need_bound)
 * has no step size yet; else 0. */
static inline int pyglue_check_ready(int ready, int bound, int need_bound,
                                     const char *type_name)
{
    if (!ready) {
        PyErr_Format(PyExc_RuntimeError, "%s is not initialised", type_name);
        return -1;
    }
    if (need_bound && !bound) {
        PyErr_Format(PyExc_RuntimeError, "%s has no step size yet (bind first)", type_name);
        return -1;
    }
    return 0;
}

/* The step count of an advance(n, ...) call into *n_out: -1 with a Python error when `arg` is
 * not an int, is negative, would carry the twin's count `done` past LLONG_MAX, or when the
 * twin is unusable (an earlier noise draw failed); else 0. */
static inline int pyglue_steps(PyObject *arg, long long done, const NormalBlock *z,
                               long long *n_out)
{
    long long n = PyLong_AsLongLong(arg);
    if (n == -1 && PyErr_Occurred()) {
        return -1;
    }
    if (n < 0) {
        PyErr_Format(PyExc_ValueError, "n must be >= 0, got %lld", n);
        return -1;
    }
    if (n > LLONG_MAX - done) {
        PyErr_Format(PyExc_OverflowError, "n = %lld steps past step %lld", n, done);
        return -1;
    }
    if (pynb_check_usable(z) != 0) {
        return -1;
    }
    *n_out = n;
    return 0;
}

/* The module of `def`, holding `type` as `type_name` and the constant NORMAL_BLOCK; NULL with
 * a Python error on failure. */
static inline PyObject *pyglue_module(struct PyModuleDef *def, PyTypeObject *type,
                               const char *type_name)
{
    if (PyType_Ready(type) < 0) {
        return NULL;
    }
    PyObject *m = PyModule_Create(def);
    if (m == NULL) {
        return NULL;
    }
    Py_INCREF(type);
    if (PyModule_AddObject(m, type_name, (PyObject *)type) < 0) {
        Py_DECREF(type);
        Py_DECREF(m);
        return NULL;
    }
    if (PyModule_AddIntConstant(m, "NORMAL_BLOCK", NORMAL_BLOCK) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}

#endif
