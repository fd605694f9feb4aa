/* A proportional flow controller: command (mV) = feed-forward + kp x (target - flow). */
#include "model.h"

Status setStartValues(ModelInstance *comp)
{
    M(target) = M(flow) = M(command) = 0.0;
    M(kp) = 40.0;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    double mv = 85.0 * M(target) + M(kp) * (M(target) - M(flow));
    M(command) = mv < 0.0 ? 0.0 : (mv > 10000.0 ? 10000.0 : mv);
    return OK;
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    calculateValues(comp);
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
