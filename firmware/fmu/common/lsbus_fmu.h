/* The common LS-BUS CAN node FMU (common/lsbus_fmu.c): what a model supplies and what it may
 * call. Every agrihil bus-level FMU (the fertilizer and depth firmware, the diagnostic probes)
 * is the Reference-FMUs skeleton, this common part and a model of a few hooks:
 *
 *   lsbus_model_defaults   start values other than zero (after the common part zeroes all)
 *   lsbus_model_start      at the first event (or the first read of Tx_Data / Tx_Clock), the
 *                          parameters fixed: set up and queue the first frames; false when it
 *                          cannot start (logged): every later event is then an error
 *   lsbus_model_on_frame   each CAN frame the bus simulation delivered, in order
 *   lsbus_model_on_tick    (LSBUS_FMU_TIMED_TX_CLOCK) each tick of a time-based Tx_Clock
 *
 * and a table of its parameters (lsbus_model_params, lsbus_model_param_count): each a value in
 * ModelData that the importer may set before the start (and get), by value reference. The
 * common part answers for the terminal (Rx_Data, Tx_Data, Rx_Clock, Tx_Clock), the time,
 * Can_BusNotifications and those parameters, and refuses anything else naming the value
 * reference. No allocation. */
#ifndef AGRIHIL_LSBUS_FMU_H
#define AGRIHIL_LSBUS_FMU_H

#include <stdbool.h>
#include <stddef.h>

#include "hal_can.h"
#include "model.h"

typedef enum { LSBUS_PARAM_FLOAT64, LSBUS_PARAM_INT32, LSBUS_PARAM_STRING } lsbus_param_kind_t;

typedef struct {
    ValueReference vr;
    lsbus_param_kind_t kind;
    const char *name; /* the firmware's --param name (LSBUS_PARAM_FLOAT64) */
    size_t offset;    /* of the value in ModelData */
    size_t size;      /* of the value (a string's buffer, its terminating NUL included) */
} lsbus_param_t;

/* one row of the parameter table: LSBUS_PARAM(vr_kp0, LSBUS_PARAM_FLOAT64, "kp0", kp0) */
#define LSBUS_PARAM(vr, kind, name, field)                                                      \
    {(vr), (kind), (name), offsetof(ModelData, field), sizeof(((ModelData *)0)->field)}

/* --- the model's --- */
extern const lsbus_param_t lsbus_model_params[];
extern const size_t lsbus_model_param_count;

void lsbus_model_defaults(ModelInstance *comp);
bool lsbus_model_start(ModelInstance *comp);
void lsbus_model_on_frame(ModelInstance *comp, const hal_can_frame_t *f);
#ifdef LSBUS_FMU_TIMED_TX_CLOCK
void lsbus_model_on_tick(ModelInstance *comp);
#endif

/* --- the common part's, for the model --- */

/* The importer set the parameter of value reference vr (before the start). */
bool lsbus_fmu_given(const ModelInstance *comp, ValueReference vr);

/* Queue frames on Tx_Data (the Tx_Clock ticks); a frame that does not fit is logged. */
void lsbus_fmu_send(ModelInstance *comp, const hal_can_frame_t *frames, size_t n);

#ifndef AGRIHIL_FMU_STANDALONE
#include "params.h"

/* Each FLOAT64 parameter of the table that the importer set, written into the firmware's
 * named parameter of the same name (refs, n: the firmware's table); false when the firmware
 * has none (logged, naming the parameter and `owner`). */
bool lsbus_fmu_apply_float64(ModelInstance *comp, const param_ref_t *refs, size_t n,
                             const char *owner);
#endif

#endif
