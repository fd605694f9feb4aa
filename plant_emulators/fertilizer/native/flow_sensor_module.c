/* CPython glue of the C twin of FlowSensor's step loop (flow_sensor_core.h): the extension
 * type plant_emulators.fertilizer._flow_sensor_native.FlowSensorCore. The Python class keeps
 * every computation that runs once per window or less (reports, faults, the vibration noise
 * level) and hands the per-step loop and the scheduling of the window ends to this type. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "../../native/py_glue.h"
#include "flow_sensor_core.h"


typedef struct {
    PyObject_HEAD
    FlowSensorCore fs;
    NormalBlock z;
    double z_storage[NORMAL_BLOCK];
    PyObject *draw;       /* the normal-variate source: draw() -> NORMAL_BLOCK doubles */
    int ready;
} FlowSensorCoreObject;

static int fs_obj_init(FlowSensorCoreObject *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"conv_s", "jit_a", "jit_b", "drift_a", "drift_b", "transit_s",
                             "sensitivity", "range_pf", "lsb_pf", "baseline_samples",
                             "jitter", "drift_pf", "inv_tau", "draw", NULL};
    double conv_s, jit_a, jit_b, drift_a, drift_b, transit_s, sensitivity, range_pf, lsb_pf;
    double jitter, drift_pf, inv_tau;
    long long baseline_samples;
    PyObject *draw;
    if (self->ready) {
        PyErr_SetString(PyExc_RuntimeError, "FlowSensorCore is initialised once");
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "dddddddddLdddO", kwlist, &conv_s, &jit_a,
                                     &jit_b, &drift_a, &drift_b, &transit_s, &sensitivity,
                                     &range_pf, &lsb_pf, &baseline_samples, &jitter,
                                     &drift_pf, &inv_tau, &draw)) {
        return -1;
    }
    if (!PyCallable_Check(draw)) {
        PyErr_SetString(PyExc_TypeError, "draw must be callable");
        return -1;
    }
    Py_INCREF(draw);
    self->draw = draw;
    pynb_init(&self->z, self->z_storage, NORMAL_BLOCK, draw);
    fs_init(&self->fs, conv_s, jit_a, jit_b, drift_a, drift_b, transit_s, sensitivity,
            range_pf, lsb_pf, baseline_samples, jitter, drift_pf, inv_tau, &self->z);
    self->ready = 1;
    return 0;
}

static void fs_obj_dealloc(FlowSensorCoreObject *self)
{
    Py_XDECREF(self->draw);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int check_ready(FlowSensorCoreObject *self, int need_bound)
{
    return pyglue_check_ready(self->ready, self->fs.bound, need_bound, "FlowSensorCore");
}

/* The clock of fs_crossing must advance toward a finite threshold (else it would not end; the
 * Python _crossing raises on non-finite values): -1 with a Python error otherwise. */
static int check_clock(double t0, double step, double due)
{
    if (!(step > 0.0) || !isfinite(step) || !isfinite(t0) || !isfinite(due)) {
        PyErr_Format(PyExc_ValueError, "a window clock needs a finite start and threshold and "
                     "a finite step > 0");
        return -1;
    }
    return 0;
}

/* FS_CLOCK_STUCK as a Python error (where Python's _crossing would never return). */
static PyObject *clock_stuck(double step)
{
    PyObject *value = PyFloat_FromDouble(step);
    if (value != NULL) {
        PyErr_Format(PyExc_ValueError, "the module clock does not advance by a step of %R s",
                     value);
        Py_DECREF(value);
    }
    return NULL;
}

static PyObject *fs_obj_bind(FlowSensorCoreObject *self, PyObject *args)
{
    double dt, step, conv_due, sub_s, sub_due;
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    if (!PyArg_ParseTuple(args, "ddddd", &dt, &step, &conv_due, &sub_s, &sub_due)) {
        return NULL;
    }
    if (self->fs.bound) {
        PyErr_SetString(PyExc_RuntimeError, "FlowSensorCore's step size is bound once");
        return NULL;
    }
    if (check_clock(0.0, step, sub_due) != 0 || check_clock(-sub_s, step, sub_due) != 0) {
        return NULL;
    }
    if (fs_bind(&self->fs, dt, step, conv_due, sub_s, sub_due) != FS_OK) {
        return clock_stuck(step);
    }
    Py_RETURN_NONE;
}

/* advance(n, flow_gps, noise_pf) -> None, or the steps still to do when the running window
 * ended (the next one is scheduled; the caller closes the one that ended and advances by
 * them). */
static PyObject *fs_obj_advance(FlowSensorCoreObject *self, PyObject *const *args,
                                Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_Format(PyExc_TypeError, "advance(n, flow_gps, noise_pf): 3 arguments, got %zd",
                     nargs);
        return NULL;
    }
    if (check_ready(self, 1) != 0) {
        return NULL;
    }
    long long n;
    if (pyglue_steps(args[0], self->fs.steps, &self->z, &n) != 0) {
        return NULL;
    }
    double flow_gps = PyFloat_AsDouble(args[1]);
    if (flow_gps == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    double noise_pf = PyFloat_AsDouble(args[2]);
    if (noise_pf == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    long long rest;
    switch (fs_advance(&self->fs, n, flow_gps, noise_pf, &rest)) {
    case FS_OK:
        break;
    case FS_ROUND_NAN:          /* what round(c / lsb) raises in Python */
        PyErr_SetString(PyExc_ValueError, "cannot convert float NaN to integer");
        return NULL;
    case FS_ROUND_INF:
        PyErr_SetString(PyExc_OverflowError, "cannot convert float infinity to integer");
        return NULL;
    case FS_CLOCK_STUCK:
        return clock_stuck(self->fs.step);
    default:
        if (!PyErr_Occurred()) {
            PyErr_SetString(PyExc_RuntimeError, "the normal-variate source failed");
        }
        return NULL;
    }
    if (rest < 0) {
        Py_RETURN_NONE;
    }
    return PyLong_FromLongLong(rest);
}

static PyObject *fs_obj_take_window(FlowSensorCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    double sum_pf;
    int overrange;
    fs_take_window(&self->fs, &sum_pf, &overrange);
    return Py_BuildValue("(dN)", sum_pf, PyBool_FromLong(overrange));
}

static PyObject *fs_obj_state(FlowSensorCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    const FlowSensorCore *fs = &self->fs;
    PyObject *baseline = fs->baseline_ready ? PyFloat_FromDouble(fs->baseline_pf)
                                            : Py_NewRef(Py_None);
    if (baseline == NULL) {
        return NULL;
    }
    return Py_BuildValue("{s:L,s:L,s:d,s:d,s:d,s:d,s:d,s:d,s:L,s:d,s:d,s:L,s:N,s:d,s:N}",
                         "steps", fs->steps, "sub_at", fs->sub_at, "sub_clock", fs->sub_clock,
                         "holdup_g", fs->holdup,
                         "inv_tau", fs->inv_tau, "jitter", fs->jitter, "drift_pf", fs->drift,
                         "h_acc", fs->h_acc, "conv_start", fs->conv_start,
                         "t_conv", fs->t_conv, "baseline_acc", fs->baseline_acc,
                         "baseline_n", fs->baseline_n, "baseline_pf", baseline,
                         "sub_sum_pf", fs->sub_sum_pf,
                         "sub_overrange", PyBool_FromLong(fs->sub_overrange));
}

static PyObject *fs_obj_get_steps(FlowSensorCoreObject *self, void *Py_UNUSED(closure))
{
    return PyLong_FromLongLong(self->fs.steps);
}

static PyObject *fs_obj_get_sub_at(FlowSensorCoreObject *self, void *Py_UNUSED(closure))
{
    return PyLong_FromLongLong(self->fs.sub_at);
}

static PyObject *fs_obj_get_holdup(FlowSensorCoreObject *self, void *Py_UNUSED(closure))
{
    return PyFloat_FromDouble(self->fs.holdup);
}

static PyObject *fs_obj_get_baseline(FlowSensorCoreObject *self, void *Py_UNUSED(closure))
{
    if (!self->fs.baseline_ready) {
        Py_RETURN_NONE;
    }
    return PyFloat_FromDouble(self->fs.baseline_pf);
}

static PyMethodDef fs_obj_methods[] = {
    {"bind", (PyCFunction)fs_obj_bind, METH_VARARGS,
     "bind(dt, step_rig, conv_due, sub_s, sub_due): the step size; schedules the first "
     "window end"},
    {"advance", (PyCFunction)(void (*)(void))fs_obj_advance, METH_FASTCALL,
     "advance(n, flow_gps, noise_pf) -> None, or the steps left when the window ended"},
    {"take_window", (PyCFunction)fs_obj_take_window, METH_NOARGS,
     "(sum of C - C_initial over the window, overrange): read and reset"},
    {"state", (PyCFunction)fs_obj_state, METH_NOARGS,
     "the whole state, named as FlowSensor's attributes (without the underscore)"},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef fs_obj_getset[] = {
    {"steps", (getter)fs_obj_get_steps, NULL, "steps advanced", NULL},
    {"sub_at", (getter)fs_obj_get_sub_at, NULL, "step count at which the running window ends",
     NULL},
    {"holdup_g", (getter)fs_obj_get_holdup, NULL, "grams between the electrodes", NULL},
    {"baseline_pf", (getter)fs_obj_get_baseline, NULL,
     "the empty-pipe capacitance (pF), None until acquired", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject FlowSensorCoreType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "plant_emulators.fertilizer._flow_sensor_native.FlowSensorCore",
    .tp_doc = "C twin of FlowSensor's step loop (holdup, conversions, baseline, window sums)",
    .tp_basicsize = sizeof(FlowSensorCoreObject),
    .tp_itemsize = 0,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)fs_obj_init,
    .tp_dealloc = (destructor)fs_obj_dealloc,
    .tp_methods = fs_obj_methods,
    .tp_getset = fs_obj_getset,
};

/* crossing(t0, step, due) -> (k, t): flow_sensor._crossing, in C (for the tests). */
static PyObject *module_crossing(PyObject *Py_UNUSED(module), PyObject *args)
{
    double t0, step, due, t;
    if (!PyArg_ParseTuple(args, "ddd", &t0, &step, &due)) {
        return NULL;
    }
    if (check_clock(t0, step, due) != 0) {
        return NULL;
    }
    long long k = fs_crossing(t0, step, due, &t);
    if (k < 0) {
        return clock_stuck(step);
    }
    return Py_BuildValue("(Ld)", k, t);
}

static PyMethodDef module_methods[] = {
    {"crossing", module_crossing, METH_VARARGS,
     "crossing(t0, step, due) -> (k, t): flow_sensor._crossing in C"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef flow_sensor_module = {
    PyModuleDef_HEAD_INIT, "_flow_sensor_native",
    "C twin of the flow detection module's step loop (see plant_emulators.engine)", -1,
    module_methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__flow_sensor_native(void)
{
    return pyglue_module(&flow_sensor_module, &FlowSensorCoreType, "FlowSensorCore");
}
