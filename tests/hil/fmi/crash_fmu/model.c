/* command (mV) = 85 x target + kp x (target - flow), until the control period fail_at_step
 * (counted at each read of command, once per period): there it fails as fail_how says,
 * 1 a segmentation fault (a store through a null pointer), 2 abort(), 3 exit(3), 4 it hangs. */
#include <stdlib.h>
#include <unistd.h>

#include "model.h"

enum { FAIL_SEGV = 1, FAIL_ABORT = 2, FAIL_EXIT = 3, FAIL_HANG = 4 };

Status setStartValues(ModelInstance *comp)
{
    M(target) = M(flow) = M(command) = 0.0;
    M(kp) = 40.0;
    M(fail_at_step) = 0;
    M(fail_how) = FAIL_SEGV;
    M(steps) = 0;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    double mv = 85.0 * M(target) + M(kp) * (M(target) - M(flow));
    M(command) = mv < 0.0 ? 0.0 : (mv > 10000.0 ? 10000.0 : mv);
    return OK;
}

static void fail(int how)
{
    int *volatile nowhere = NULL;
    switch (how) {
    case FAIL_SEGV: *nowhere = 1; break;
    case FAIL_ABORT: abort();
    case FAIL_EXIT: exit(3);
    case FAIL_HANG: for (;;) { sleep(1); }
    default: break;
    }
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    calculateValues(comp);
    if (vr == vr_command && ++M(steps) == M(fail_at_step)) {
        fail(M(fail_how));
    }
    double v[] = {comp->time, M(target), M(flow), M(command), M(kp)};
    if (vr > vr_kp) {
        return Error;
    }
    values[(*index)++] = v[vr];
    return OK;
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    double *v[] = {NULL, &M(target), &M(flow), NULL, &M(kp)};
    if (vr > vr_kp || v[vr] == NULL) {
        return Error;
    }
    *v[vr] = values[(*index)++];
    return OK;
}

static int32_t *int_variable(ModelInstance *comp, ValueReference vr)
{
    return vr == vr_fail_at_step ? &M(fail_at_step) : (vr == vr_fail_how ? &M(fail_how) : NULL);
}

Status getInt32(ModelInstance *comp, ValueReference vr, int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    int32_t *p = int_variable(comp, vr);
    if (p == NULL) {
        return Error;
    }
    values[(*index)++] = *p;
    return OK;
}

Status setInt32(ModelInstance *comp, ValueReference vr, const int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    int32_t *p = int_variable(comp, vr);
    if (p == NULL) {
        return Error;
    }
    *p = values[(*index)++];
    return OK;
}
