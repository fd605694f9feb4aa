/* The fertilizer firmware (firmware/apps/fertilizer_adapter.c and its core, unchanged) as an
 * FMI-LS-BUS CAN node (common/lsbus_fmu.h): its frames cross Rx_Data / Tx_Data instead of a
 * socket.
 *
 * The loop is agrihil-fertilizer-fw's in lockstep (firmware/apps/app.c): the boot-up frame at
 * start, one control step per received SYNC (0x080) with the adapter clock at steps x period,
 * every other frame handed to the adapter stamped with that clock. Parameters: mode (the law:
 * physical, paper-literal, open-loop) and ff_coeff, as the firmware's --param. */
#include <stdio.h>

#include "lsbus_fmu.h"

#define SYNC_ID 0x080u

const lsbus_param_t lsbus_model_params[] = {
    LSBUS_PARAM(vr_ff_coeff, LSBUS_PARAM_FLOAT64, "ff_coeff", ff_coeff),
    LSBUS_PARAM(vr_mode, LSBUS_PARAM_STRING, "mode", mode),
};
const size_t lsbus_model_param_count = sizeof lsbus_model_params / sizeof lsbus_model_params[0];

void lsbus_model_defaults(ModelInstance *comp)
{
    UNUSED(comp); /* mode "": the physical law */
}

bool lsbus_model_start(ModelInstance *comp)
{
    ppid_law_t law = PPID_LAW_PHYSICAL;
    if (M(mode)[0] != '\0' && !ppid_law_parse(M(mode), &law)) {
        logError(comp, "parameter mode = '%s': not a law (physical, paper-literal, open-loop)",
                 M(mode));
        return false;
    }
    fert_config_t cfg;
    fert_config_defaults(&cfg, law);
    param_ref_t refs[FERT_PARAM_COUNT];
    size_t n = fert_param_refs(&cfg, refs);
    char owner[64];
    snprintf(owner, sizeof owner, "the %s law", ppid_law_name(law));
    if (!lsbus_fmu_apply_float64(comp, refs, n, owner)) {
        return false;
    }
    fert_init(&M(adapter), &cfg);
    hal_can_frame_t boot = fert_bootup();
    lsbus_fmu_send(comp, &boot, 1);
    return true;
}

void lsbus_model_on_frame(ModelInstance *comp, const hal_can_frame_t *f)
{
    const double now_s = (double)M(steps) * M(adapter).cfg.period_s;
    if (!f->extended && f->id == SYNC_ID) {
        hal_can_frame_t out[FERT_MAX_OUT];
        size_t n = fert_step(&M(adapter), now_s, out);
        M(steps)++;
        lsbus_fmu_send(comp, out, n);
    } else {
        fert_on_frame(&M(adapter), f, now_s);
    }
}
