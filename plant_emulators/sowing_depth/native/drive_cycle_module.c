/* CPython glue of the C twin of the depth drive's profile-velocity loop (drive_cycle_core.h):
 * the function plant_emulators.sowing_depth._drive_cycle_native.run. The Python side
 * (Cia402Drive.run_native) hands over the drive's and the cylinder's state, and takes back
 * what the steps changed; everything else stays in Python. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "drive_cycle_core.h"

#define N_LOOP 6       /* n, dt, dx, t, x, next_cell */
#define N_DRIVE 16
#define N_CYLINDER 17
#define N_ARGS (N_LOOP + N_DRIVE + N_CYLINDER)

static PyObject *run(PyObject *Py_UNUSED(module), PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != N_ARGS) {
        PyErr_Format(PyExc_TypeError, "run() takes %d arguments (%zd given)", N_ARGS, nargs);
        return NULL;
    }
    long long n = PyLong_AsLongLong(args[0]);
    if (n == -1 && PyErr_Occurred()) {
        return NULL;
    }
    if (n < 0) {
        PyErr_Format(PyExc_ValueError, "n must be >= 0, got %lld", n);
        return NULL;
    }
    double v[N_ARGS];
    for (Py_ssize_t i = 1; i < N_ARGS; ++i) {
        v[i] = PyFloat_AsDouble(args[i]);
        if (v[i] == -1.0 && PyErr_Occurred()) {
            return NULL;
        }
    }
    double dt = v[1], dx = v[2], t = v[3], x = v[4], next_cell = v[5];
    const double *dv = v + N_LOOP;
    DcDrive d = {
        .target = dv[0], .lim_min = dv[1], .lim_max = dv[2], .accel = dv[3], .decel = dv[4],
        .vmax = dv[5], .vel_window = dv[6], .vel_window_s = dv[7], .vel_threshold = dv[8],
        .vel_threshold_s = dv[9], .overload_limit_s = dv[10], .prof_velocity = dv[11],
        .prof_position = dv[12], .window_time_s = dv[13], .threshold_time_s = dv[14],
        .overload_s = dv[15],
    };
    const double *cv = dv + N_DRIVE;
    DcCylinder c = {
        .position_mm = cv[0], .velocity_mm_s = cv[1], .load_contact_mm = cv[2],
        .load_stiffness_n_per_mm = cv[3], .load_damping_n_s_per_mm = cv[4],
        .load_preload_n = cv[5], .m_eff_kg = cv[6], .k_force_n_per_n_m = cv[7], .k_vel = cv[8],
        .torque_limit_n_m = cv[9], .kt_n_m_per_a = cv[10], .dc_bus_voltage_v = cv[11],
        .ke_v_s_per_rad = cv[12], .rad_per_mm = cv[13], .ra_ohm = cv[14],
        .rod_speed_max_mm_per_s = cv[15], .stroke_mm = cv[16],
    };
    int why = 0;
    long long done = dc_run(&d, &c, n, dt, dx, &t, &x, next_cell, &why);
    return Py_BuildValue("(LidddddddNNNdddddN)", done, why, t, x, d.prof_velocity,
                         d.prof_position, d.window_time_s, d.threshold_time_s, d.overload_s,
                         PyBool_FromLong(d.internal_limit), PyBool_FromLong(d.target_reached),
                         PyBool_FromLong(d.speed_zero), c.position_mm, c.velocity_mm_s,
                         c.torque_n_m, c.current_a, c.force_n,
                         PyBool_FromLong(c.at_force_limit));
}

static PyMethodDef methods[] = {
    {"run", (PyCFunction)(void (*)(void))run, METH_FASTCALL,
     "run(n, dt, dx, t, x, next_cell, *drive(16), *cylinder(17)) -> (steps, why, t, x, "
     "prof_velocity, prof_position, window_time_s, threshold_time_s, overload_s, "
     "internal_limit, target_reached, speed_zero, position_mm, velocity_mm_s, torque_n_m, "
     "current_a, force_n, at_force_limit); see drive_cycle_core.h"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef drive_cycle_module = {
    PyModuleDef_HEAD_INIT, "_drive_cycle_native",
    "C twin of the sowing-depth drive's profile-velocity loop (see plant_emulators.engine)", -1,
    methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__drive_cycle_native(void)
{
    PyObject *m = PyModule_Create(&drive_cycle_module);
    if (m == NULL) {
        return NULL;
    }
    if (PyModule_AddIntConstant(m, "CELL", DC_CELL) < 0
        || PyModule_AddIntConstant(m, "OVERLOAD", DC_OVERLOAD) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
