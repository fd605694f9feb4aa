/* CPython glue of the C twin of FertilizerPlant's step loop (plant_core.h): the extension
 * type plant_emulators.fertilizer._plant_native.PlantCore. The Python class keeps every
 * computation that runs once per call or less (inputs, constants, outputs' units) and hands
 * the per-step loop to this type. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "../../native/py_glue.h"
#include "plant_core.h"

typedef struct {
    PyObject_HEAD
    PlantCore pc;
    NormalBlock z;
    double z_storage[NORMAL_BLOCK];
    PyObject *draw;       /* the normal-variate source: draw() -> NORMAL_BLOCK doubles */
    int ready;
} PlantCoreObject;

static PyObject *tuple_of(const double *values, int n, double scale)
{
    PyObject *t = PyTuple_New(n);
    if (t == NULL) {
        return NULL;
    }
    for (int i = 0; i < n; ++i) {
        PyObject *v = PyFloat_FromDouble(scale == 1.0 ? values[i] : values[i] * scale);
        if (v == NULL) {
            Py_DECREF(t);
            return NULL;
        }
        PyTuple_SET_ITEM(t, i, v);
    }
    return t;
}

static int core_init(PlantCoreObject *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"rows", "charge_sd", "dens_base", "gain", "offsets", "cos_off",
                             "sin_off", "hopper_g", "density_wander", "draw", NULL};
    int rows;
    double charge_sd, dens_base, hopper_g, wander;
    PyObject *gain, *offsets, *cos_off, *sin_off, *draw;
    if (self->ready) {
        PyErr_SetString(PyExc_RuntimeError, "PlantCore is initialised once");
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "iddOOOOddO", kwlist, &rows, &charge_sd,
                                     &dens_base, &gain, &offsets, &cos_off, &sin_off,
                                     &hopper_g, &wander, &draw)) {
        return -1;
    }
    if (rows < 1) {
        PyErr_Format(PyExc_ValueError, "rows must be >= 1, got %d", rows);
        return -1;
    }
    if (!PyCallable_Check(draw)) {
        PyErr_SetString(PyExc_TypeError, "draw must be callable");
        return -1;
    }
    double *buf = PyMem_Calloc((size_t)rows * 4, sizeof(double));
    if (buf == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    int rc = -1;
    if (pyglue_doubles(gain, "gain", rows, buf) == 0
        && pyglue_doubles(offsets, "offsets", rows, buf + rows) == 0
        && pyglue_doubles(cos_off, "cos_off", rows, buf + 2 * rows) == 0
        && pyglue_doubles(sin_off, "sin_off", rows, buf + 3 * rows) == 0) {
        Py_INCREF(draw);
        Py_XSETREF(self->draw, draw);
        pynb_init(&self->z, self->z_storage, NORMAL_BLOCK, draw);
        if (pc_init(&self->pc, rows, charge_sd, dens_base, buf, buf + rows, buf + 2 * rows,
                    buf + 3 * rows, hopper_g, wander, &self->z) == 0) {
            self->ready = 1;
            rc = 0;
        } else if (!PyErr_Occurred()) {
            PyErr_NoMemory();
        }
    }
    PyMem_Free(buf);
    return rc;
}

static void core_dealloc(PlantCoreObject *self)
{
    if (self->ready) {
        pc_free(&self->pc);
    }
    Py_XDECREF(self->draw);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int check_ready(PlantCoreObject *self, int need_bound)
{
    return pyglue_check_ready(self->ready, self->pc.bound, need_bound, "PlantCore");
}

static PyObject *core_bind(PlantCoreObject *self, PyObject *args)
{
    double dt, alpha;
    PyObject *drive, *meter;
    long to_sensor, to_exit;
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    if (!PyArg_ParseTuple(args, "dOOdll", &dt, &drive, &meter, &alpha, &to_sensor, &to_exit)) {
        return NULL;
    }
    if (self->pc.bound) {
        PyErr_SetString(PyExc_RuntimeError, "PlantCore's step size is bound once");
        return NULL;
    }
    if (to_sensor < 1 || to_exit < 1) {
        PyErr_Format(PyExc_ValueError, "delays must be >= 1 step, got %ld and %ld", to_sensor,
                     to_exit);
        return NULL;
    }
    double dv[19], mv[18];
    if (pyglue_doubles(drive, "drive constants", 19, dv) != 0
        || pyglue_doubles(meter, "meter constants", 18, mv) != 0) {
        return NULL;
    }
    PcDrive d = {dv[0], dv[1], dv[2], dv[3], dv[4], dv[5], dv[6], dv[7], dv[8], dv[9],
                 dv[10], dv[11], dv[12], dv[13], dv[14], dv[15], dv[16], dv[17], dv[18]};
    PcMeter m = {mv[0], mv[1], mv[2], mv[3], mv[4], mv[5], mv[6], mv[7], mv[8], mv[9],
                 mv[10], mv[11], mv[12], mv[13], mv[14], (long)mv[15], mv[16], mv[17]};
    if ((double)m.slow_steps != mv[15] || m.slow_steps < 1) {
        PyErr_Format(PyExc_ValueError, "slow_steps must be a whole number >= 1, got %g", mv[15]);
        return NULL;
    }
    if (pc_bind(&self->pc, dt, &d, &m, alpha, to_sensor, to_exit) != 0) {
        return PyErr_Format(PyExc_MemoryError, "no room for delay lines of %ld + %ld steps x "
                            "%d rows", to_sensor, to_exit, self->pc.rows);
    }
    Py_RETURN_NONE;
}

static PyObject *core_advance(PlantCoreObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4) {
        PyErr_Format(PyExc_TypeError,
                     "advance(n, w_target, stalled, dens_base): 4 arguments, got %zd", nargs);
        return NULL;
    }
    if (check_ready(self, 1) != 0) {
        return NULL;
    }
    long long n;            /* the plant keeps no step count: nothing to overflow */
    if (pyglue_steps(args[0], 0, &self->z, &n) != 0) {
        return NULL;
    }
    double w_target = PyFloat_AsDouble(args[1]);
    if (w_target == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    int stalled = PyObject_IsTrue(args[2]);
    if (stalled < 0) {
        return NULL;
    }
    double dens_base = PyFloat_AsDouble(args[3]);
    if (dens_base == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    if (pc_advance(&self->pc, n, w_target, stalled, dens_base) != 0) {
        if (!PyErr_Occurred()) {
            PyErr_SetString(PyExc_RuntimeError, "the normal-variate source failed");
        }
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyObject *core_state(PlantCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    const PlantCore *pc = &self->pc;
    return Py_BuildValue("(dddddNddd)", pc->w, pc->w_ref, pc->xi, pc->cur, pc->i2t,
                         PyBool_FromLong(pc->derated), pc->rev, pc->hopper, pc->wander);
}

static PyObject *core_rows_out(PlantCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 1) != 0) {
        return NULL;
    }
    const PlantCore *pc = &self->pc;
    PyObject *out = PyTuple_New(4);
    if (out == NULL) {
        return NULL;
    }
    PyObject *parts[4] = {tuple_of(pc->passed, pc->rows, pc->dt),
                          tuple_of(pc->delivered, pc->rows, pc->dt),
                          tuple_of(pc->flow_at_meter, pc->rows, 1.0),
                          tuple_of(pc->flow_at_sensor, pc->rows, 1.0)};
    for (int i = 0; i < 4; ++i) {
        if (parts[i] == NULL) {
            for (int j = 0; j < 4; ++j) {
                Py_XDECREF(parts[j]);
            }
            Py_DECREF(out);
            return NULL;
        }
    }
    for (int i = 0; i < 4; ++i) {
        PyTuple_SET_ITEM(out, i, parts[i]);
    }
    return out;
}

static PyObject *core_metered(PlantCoreObject *self, PyObject *Py_UNUSED(ignored))
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    return tuple_of(self->pc.metered, self->pc.rows, self->pc.bound ? self->pc.dt : 0.0);
}

static PyObject *core_set_gains(PlantCoreObject *self, PyObject *gains)
{
    if (check_ready(self, 0) != 0) {
        return NULL;
    }
    double buf[64];
    if (self->pc.rows > 64) {
        PyErr_Format(PyExc_ValueError, "at most 64 rows, got %d", self->pc.rows);
        return NULL;
    }
    if (pyglue_doubles(gains, "gains", self->pc.rows, buf) != 0) {
        return NULL;
    }
    for (int r = 0; r < self->pc.rows; ++r) {
        self->pc.gain[r] = buf[r];
    }
    Py_RETURN_NONE;
}

static PyMethodDef core_methods[] = {
    {"set_gains", (PyCFunction)core_set_gains, METH_O,
     "set_gains(gains): every row's gain from now on (a row clutch: 0 disengaged)"},
    {"bind", (PyCFunction)core_bind, METH_VARARGS,
     "bind(dt, drive_constants, meter_constants, alpha, to_sensor, to_exit): the step size"},
    {"advance", (PyCFunction)(void (*)(void))core_advance, METH_FASTCALL,
     "advance(n, w_target, stalled, dens_base): n steps with the inputs held"},
    {"state", (PyCFunction)core_state, METH_NOARGS,
     "(w, w_ref, xi, current, i2t, derated, rev, hopper_g, density_wander)"},
    {"rows_out", (PyCFunction)core_rows_out, METH_NOARGS,
     "(sensor_passed_g, delivered_g, flow_at_meter_gps, flow_at_sensor_gps), per row"},
    {"metered", (PyCFunction)core_metered, METH_NOARGS, "grams that left each roller"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject PlantCoreType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "plant_emulators.fertilizer._plant_native.PlantCore",
    .tp_doc = "C twin of FertilizerPlant's step loop (drive, meter, transport)",
    .tp_basicsize = sizeof(PlantCoreObject),
    .tp_itemsize = 0,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)core_init,
    .tp_dealloc = (destructor)core_dealloc,
    .tp_methods = core_methods,
};

static struct PyModuleDef plant_module = {
    PyModuleDef_HEAD_INIT, "_plant_native",
    "C twin of the fertilizer plant's step loop (see plant_emulators.engine)", -1, NULL,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__plant_native(void)
{
    return pyglue_module(&plant_module, &PlantCoreType, "PlantCore");
}
