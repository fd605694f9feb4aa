/* The fertilizer meter's device descriptor object pool (ISO 11783-10 DDOP), written in C.
 *
 * iso_meter_pool() writes the same bytes as the Python build's
 * reference_controllers.fertilizer.isobus_mode.meter_pool() for the same parameters (the
 * isobus_ddop ctest compares them on the pools of reference_controllers/vectors/
 * isobus-ddop.txt): the device, one boom (function element) with its width, offsets,
 * look-ahead times, set-point latency and six process data (DDI 6, 7, 141, 289, 161, 290),
 * and one section per meter row. Object ids and element numbers are given in the Python
 * builder's call order.
 *
 * It also fills the pool's process data table (element number, DDI, properties, trigger
 * methods, in pool order), which the TC client needs to answer the TC. Pure C, no allocation:
 * the caller owns the buffer. */
#ifndef AGRIHIL_ISO_DDOP_H
#define AGRIHIL_ISO_DDOP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define ISO_DDOP_MAX_ROWS 16
#define ISO_DDOP_MAX_BYTES 1784 /* the pool transfer (command byte + pool) fits TP's 1785 */
#define ISO_DDOP_MAX_DPD 6

/* DDIs (ISO 11783-11) */
#define ISO_DDI_SETPOINT_MASS_PER_AREA_RATE 6
#define ISO_DDI_ACTUAL_MASS_PER_AREA_RATE 7
#define ISO_DDI_ACTUAL_WORKING_WIDTH 67
#define ISO_DDI_OFFSET_X 134
#define ISO_DDI_OFFSET_Y 135
#define ISO_DDI_ACTUAL_WORK_STATE 141
#define ISO_DDI_SETPOINT_LATENCY 142
#define ISO_DDI_ACTUAL_CONDENSED_1_16 161
#define ISO_DDI_TURN_ON_TIME 205
#define ISO_DDI_TURN_OFF_TIME 206
#define ISO_DDI_SETPOINT_WORK_STATE 289
#define ISO_DDI_SETPOINT_CONDENSED_1_16 290
#define ISO_DDI_REQUEST_DEFAULT 0xDFFF

/* DPD properties and trigger methods (ISO 11783-10) */
#define ISO_DPD_DEFAULT_SET 0x01
#define ISO_DPD_SETTABLE 0x02
#define ISO_TRIGGER_TIME 0x01
#define ISO_TRIGGER_DISTANCE 0x02
#define ISO_TRIGGER_THRESHOLD 0x04
#define ISO_TRIGGER_ON_CHANGE 0x08

typedef struct {
    uint64_t name;     /* the client's NAME, carried by the device object */
    double width_m;    /* boom width; rows sections of width_m / rows */
    unsigned rows;     /* 1 .. 16 */
    int32_t latency_ms; /* set-point latency and look-ahead times */
    bool broken;       /* DDI 7 names a value presentation that is not there (must-fail) */
    unsigned version;  /* ISO 11783-10 version of the bytes: 4, or 1-3 (no extended label) */
} iso_ddop_params_t;

typedef struct {
    uint16_t element; /* element number */
    uint16_t ddi;
    uint8_t properties;
    uint8_t triggers;
} iso_dpd_t;

typedef struct {
    size_t size;                  /* bytes written */
    uint16_t boom;                /* element number of the boom (depth pool: seed line) */
    uint16_t elements;            /* element numbers are 0 .. elements - 1 */
    unsigned sections;
    iso_dpd_t dpd[ISO_DDOP_MAX_DPD]; /* in pool order (the default set's order) */
    size_t ndpd;
    uint8_t structure_label[7];
    uint8_t localization_label[7];
} iso_ddop_info_t;

/* Write the pool into buf (capacity cap). Returns 0, or -1 when the parameters are out of range
 * (rows, width) or the pool does not fit cap. */
int iso_meter_pool(const iso_ddop_params_t *p, uint8_t *buf, size_t cap, iso_ddop_info_t *info);

/* The depth seeder's pool (issue 42): the bytes of the Python build's
 * reference_controllers.sowing_depth.isobus_mode.depth_pool() for the same parameters (the
 * isobus_depth_ddop ctest compares them on firmware/isobus/data/depth-ddop.txt): the device and
 * one function element, the seed line, with its working width (DDI 67), offsets (134, 135),
 * set-point latency (142), default, minimum and maximum seeding depth (58, 59, 60) and two
 * process data, the set-point seeding depth (56, settable) and the actual one (57, on change
 * and time interval). The values are rounded as the Python's round() does (half to even). */
#define ISO_DDI_SETPOINT_SEEDING_DEPTH 56
#define ISO_DDI_ACTUAL_SEEDING_DEPTH 57
#define ISO_DDI_DEFAULT_SEEDING_DEPTH 58
#define ISO_DDI_MINIMUM_SEEDING_DEPTH 59
#define ISO_DDI_MAXIMUM_SEEDING_DEPTH 60

typedef struct {
    uint64_t name;        /* the client's NAME, carried by the device object */
    double width_m;       /* the seed line's working width, (0, 30] m */
    int32_t offset_x_mm;  /* the seed line behind the device reference point (negative) */
    double latency_ms;    /* DDI 142 */
    double default_mm, min_mm, max_mm; /* DDI 58, 59, 60 */
    unsigned version;     /* 4, or 1-3 (no extended structure label) */
} iso_depth_ddop_params_t;

/* Write the depth pool into buf; info->boom is the seed line's element number, no sections.
 * Returns 0, or -1 when the width is out of range or the pool does not fit cap. */
int iso_depth_pool(const iso_depth_ddop_params_t *p, uint8_t *buf, size_t cap,
                   iso_ddop_info_t *info);

/* The DPD of (element, ddi), NULL when the pool has none. */
const iso_dpd_t *iso_ddop_dpd(const iso_ddop_info_t *info, uint16_t element, uint16_t ddi);

#endif
