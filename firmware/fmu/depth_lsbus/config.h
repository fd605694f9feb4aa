/* agrihil-depth-lsbus: the sowing-depth firmware as an FMI 3.0 LS-BUS CAN node. */
#ifndef config_h
#define config_h

#include "depth_adapter.h"
#include "hal_serial.h"
#include "lsbus_fmu_config.h"
#include "nmea.h"

#define MODEL_IDENTIFIER agrihil_depth_lsbus
#define INSTANTIATION_TOKEN "{6f0c2f7e-agri-hil0-dept-lsbus0000001}"

#define SET_FLOAT64
#define SET_STRING

typedef enum {
    LSBUS_FMU_VALUE_REFERENCES,
    vr_kp0 = 10,
    vr_ki0 = 11,
    vr_kd0 = 12,
    vr_gnss_port = 20
} ValueReference;

#define PORT_TEXT 256

typedef struct {
    LSBUS_FMU_DATA
    depth_adapter_t adapter;
    uint64_t steps;
    double kp0;
    double ki0;
    double kd0;
    char gnss_port[PORT_TEXT];
    hal_serial_t gnss;
    bool gnss_open;
    nmea_reader_t nmea;
} ModelData;

#endif
