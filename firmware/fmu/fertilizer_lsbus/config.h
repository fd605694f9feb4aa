/* agrihil-fertilizer-lsbus: the fertilizer firmware as an FMI 3.0 LS-BUS CAN node. */
#ifndef config_h
#define config_h

#include "fertilizer_adapter.h"
#include "lsbus_fmu_config.h"

#define MODEL_IDENTIFIER agrihil_fertilizer_lsbus
#define INSTANTIATION_TOKEN "{6f0c2f7e-agri-hil0-fert-lsbus0000001}"

#define SET_FLOAT64
#define SET_STRING

typedef enum {
    LSBUS_FMU_VALUE_REFERENCES,
    vr_ff_coeff = 10,
    vr_mode = 11
} ValueReference;

#define MODE_TEXT 32

typedef struct {
    LSBUS_FMU_DATA
    fert_adapter_t adapter;
    uint64_t steps;
    char mode[MODE_TEXT];
    double ff_coeff;
} ModelData;

#endif
