/* CPython glue of the C twin of GroundSpeedModel's step loop (ground_speed_core.h): the
 * extension type plant_emulators.fertilizer._ground_speed_native.GroundSpeedCore. The Python
 * class keeps every computation that runs once per run or per call (the per-run draws, the
 * constants, the target) and hands the per-step loop, the outputs and the Hall report to this
 * type: advance() returns the outputs of _update_outputs in one tuple, so that a rig period
 * costs one call. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "../../native/py_glue.h"
#include "ground_speed_core.h"


typedef struct {
    PyObject_HEAD
    GroundSpeedCore gs;
    NormalBlock z;
    double z_storage[NORMAL_BLOCK];
    PyObject *draw;          /* the normal-variate source: draw() -> NORMAL_BLOCK doubles */
    PyObject *report_type;   /* called with the four fields of a Hall report (HallReport) */
    int ready;
} GroundSpeedCoreObject;

/* 0 for GS_OK; otherwise -1 with the Python error the code stands for. */
static int check_rc(int rc)
{
    if (rc == GS_OK) {
        return 0;
    }
    if (rc == GS_ZERO_DIVISION) {
        PyErr_SetString(PyExc_ZeroDivisionError, "float division by zero");
    } else if (!PyErr_Occurred()) {
        PyErr_SetString(PyExc_RuntimeError, "the normal-variate source failed");
    }
    return -1;
}

static int core_init(GroundSpeedCoreObject *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"errors", "variation", "wheel_slip", "tractor_slip",
                             "radar_noise", "ar1", "ar2", "ar_gain", "radar_gain",
                             "vib_rms_per_mps", "hall_timeout_s", "hall_average_window_s",
                             "reported_metres_per_pulse", "report_type", "draw", NULL};
    PyObject *errors, *report_type, *draw;
    double variation, wslip, tslip, rnoise, ar1, ar2, ar_gain, radar_gain, vib_rms;
    double timeout, window, mpp;
    if (self->ready) {
        PyErr_SetString(PyExc_RuntimeError, "GroundSpeedCore is initialised once");
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OddddddddddddOO", kwlist, &errors,
                                     &variation, &wslip, &tslip, &rnoise, &ar1, &ar2, &ar_gain,
                                     &radar_gain, &vib_rms, &timeout, &window, &mpp,
                                     &report_type, &draw)) {
        return -1;
    }
    if (!PyCallable_Check(draw) || !PyCallable_Check(report_type)) {
        PyErr_SetString(PyExc_TypeError, "draw and report_type must be callable");
        return -1;
    }
    Py_ssize_t n_mag = PyObject_Length(errors);
    if (n_mag < 0) {
        return -1;
    }
    if (n_mag < 1 || n_mag > 1000000) {
        PyErr_Format(PyExc_ValueError, "errors: expected 1 to 1000000 values, got %zd", n_mag);
        return -1;
    }
    double *buf = PyMem_Malloc((size_t)n_mag * sizeof(double));
    if (buf == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    int rc = -1;
    if (pyglue_doubles(errors, "errors", n_mag, buf) == 0) {
        pynb_init(&self->z, self->z_storage, NORMAL_BLOCK, draw);
        if (gs_init(&self->gs, (int)n_mag, buf, variation, wslip, tslip, rnoise, ar1, ar2,
                    ar_gain, radar_gain, vib_rms, timeout, window, mpp, &self->z) == 0) {
            Py_INCREF(draw);
            self->draw = draw;
            Py_INCREF(report_type);
            self->report_type = report_type;
            self->ready = 1;
            rc = 0;
        } else {
            PyErr_NoMemory();
        }
    }
    PyMem_Free(buf);
    return rc;
}

static void core_dealloc(GroundSpeedCoreObject *self)
{
    if (self->ready) {
        gs_free(&self->gs);
    }
    Py_XDECREF(self->draw);
    Py_XDECREF(self->report_type);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int check_ready(GroundSpeedCoreObject *self, int need_bound)
{
    return pyglue_check_ready(self->ready, self->gs.bound, need_bound, "GroundSpeedCore");
}

static PyObject *core_bind(GroundSpeedCoreObject *self, PyObject *args)
{
    double dt;
    PyObject *constants;
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    if (!PyArg_ParseTuple(args, "dO", &dt, &constants)) {
        return NULL;
    }
    if (self->gs.bound) {
        PyErr_SetString(PyExc_RuntimeError, "GroundSpeedCore's step size is bound once");
        return NULL;
    }
    double c[15];
    if (pyglue_doubles(constants, "step constants", 15, c) != 0) {
        return NULL;
    }
    GsStep k = {(long)c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10],
                c[11], c[12], c[13], c[14]};
    if ((double)k.slow != c[0] || k.slow < 1) {
        PyErr_Format(PyExc_ValueError, "slow must be a whole number >= 1, got %g", c[0]);
        return NULL;
    }
    gs_bind(&self->gs, dt, &k);
    Py_RETURN_NONE;
}

/* The outputs of _update_outputs, in its order. */
static PyObject *outputs_tuple(const GroundSpeedCore *gs)
{
    double out[GS_N_OUTPUTS];
    long long pulses;
    if (check_rc(gs_outputs(gs, out, &pulses)) != 0) {
        return NULL;
    }
    PyObject *t = PyTuple_New(GS_N_OUTPUTS + 1);
    if (t == NULL) {
        return NULL;
    }
    Py_ssize_t j = 0;
    for (int i = 0; i < GS_N_OUTPUTS; ++i) {
        if (i == GS_WB_SPEED) {         /* hall_pulses sits before wheel_based_speed_mps */
            PyObject *p = PyLong_FromLongLong(pulses);
            if (p == NULL) {
                Py_DECREF(t);
                return NULL;
            }
            PyTuple_SET_ITEM(t, j++, p);
        }
        PyObject *x = PyFloat_FromDouble(out[i]);
        if (x == NULL) {
            Py_DECREF(t);
            return NULL;
        }
        PyTuple_SET_ITEM(t, j++, x);
    }
    return t;
}

static PyObject *core_advance(GroundSpeedCoreObject *self, PyObject *const *args,
                              Py_ssize_t nargs)
{
    if (nargs != 2) {
        PyErr_Format(PyExc_TypeError, "advance(n, target): 2 arguments, got %zd", nargs);
        return NULL;
    }
    if (check_ready(self, 1) != 0) {
        return NULL;
    }
    long long n;
    if (pyglue_steps(args[0], self->gs.steps, &self->z, &n) != 0) {
        return NULL;
    }
    double target = PyFloat_AsDouble(args[1]);
    if (target == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    if (check_rc(gs_advance(&self->gs, n, target)) != 0) {
        return NULL;
    }
    return outputs_tuple(&self->gs);
}

static PyObject *core_outputs(GroundSpeedCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    return outputs_tuple(&self->gs);
}

static PyObject *core_hall_report(GroundSpeedCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    GsHallReport r;
    if (check_rc(gs_hall_report(&self->gs, &r)) != 0) {
        return NULL;
    }
    PyObject *fields[4] = {PyFloat_FromDouble(r.wheel_speed_mps),
                           PyLong_FromLongLong(r.pulse_count),
                           PyFloat_FromDouble(r.last_period_s), PyBool_FromLong(r.moving)};
    PyObject *result = NULL;
    if (fields[0] != NULL && fields[1] != NULL && fields[2] != NULL && fields[3] != NULL) {
        result = PyObject_Vectorcall(self->report_type, fields, 4, NULL);
    }
    for (int i = 0; i < 4; ++i) {
        Py_XDECREF(fields[i]);
    }
    return result;
}

static PyObject *core_edges(GroundSpeedCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    const GroundSpeedCore *gs = &self->gs;
    PyObject *t = PyTuple_New(gs->edge_count);
    if (t == NULL) {
        return NULL;
    }
    for (int i = 0; i < gs->edge_count; ++i) {
        PyObject *x = PyFloat_FromDouble(gs->edges[(gs->edge_start + i) % GS_EDGE_HISTORY]);
        if (x == NULL) {
            Py_DECREF(t);
            return NULL;
        }
        PyTuple_SET_ITEM(t, i, x);
    }
    return t;
}

static PyObject *core_state(GroundSpeedCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    const GroundSpeedCore *gs = &self->gs;
    return Py_BuildValue("(dddddddddddddLLl)", gs->v, gs->dist, gs->wheel_dist, gs->wb_dist,
                         gs->gb_dist, gs->variation, gs->wslip, gs->tslip, gs->rnoise,
                         gs->vib0, gs->vib1, gs->pos, gs->next_edge, gs->pulses, gs->steps,
                         gs->countdown);
}

static PyMethodDef core_methods[] = {
    {"bind", (PyCFunction)core_bind, METH_VARARGS,
     "bind(dt, step_constants): the step size and _StepConstants (in declared order)"},
    {"advance", (PyCFunction)(void (*)(void))core_advance, METH_FASTCALL,
     "advance(n, target) -> outputs: n steps with the target speed held"},
    {"outputs", (PyCFunction)core_outputs, METH_NOARGS,
     "the attributes _update_outputs sets, in its order"},
    {"hall_report", (PyCFunction)core_hall_report, METH_NOARGS,
     "report_type(wheel_speed_mps, pulse_count, last_period_s, moving)"},
    {"edges", (PyCFunction)core_edges, METH_NOARGS, "the recorded Hall edge times, oldest first"},
    {"state", (PyCFunction)core_state, METH_NOARGS,
     "(v, dist, wheel_dist, wb_dist, gb_dist, variation, wheel_slip, tractor_slip, "
     "radar_noise, vib0, vib1, pulse_pos, next_edge, pulses, steps, countdown)"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject GroundSpeedCoreType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "plant_emulators.fertilizer._ground_speed_native.GroundSpeedCore",
    .tp_doc = "C twin of GroundSpeedModel's step loop (speeds, distances, Hall pulses)",
    .tp_basicsize = sizeof(GroundSpeedCoreObject),
    .tp_itemsize = 0,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)core_init,
    .tp_dealloc = (destructor)core_dealloc,
    .tp_methods = core_methods,
};

static struct PyModuleDef ground_speed_module = {
    PyModuleDef_HEAD_INIT, "_ground_speed_native",
    "C twin of the fertilizer rig's ground-speed step loop (see plant_emulators.engine)", -1,
    NULL, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__ground_speed_native(void)
{
    PyObject *m = pyglue_module(&ground_speed_module, &GroundSpeedCoreType, "GroundSpeedCore");
    if (m != NULL && PyModule_AddIntConstant(m, "EDGE_HISTORY", GS_EDGE_HISTORY) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
