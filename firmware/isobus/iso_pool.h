/* The fertilizer meter's operator interface: its Virtual Terminal object pool (ISO 11783-6,
 * version 4), written in C.
 *
 * iso_vt_pool() writes the same bytes as the Python build's
 * reference_controllers.fertilizer.operator_pool.meter_vt_pool(rows).to_bytes() for the same
 * row count (the isobus_vt_pool ctest compares them on the pools of
 * firmware/isobus/data/vt-pool.txt, which the Python build writes): three masks, as a market
 * meter's terminal pages,
 *   - Run (the home mask): the rate set-point, each row's actual rate (kg/ha), the master
 *     switch's state; soft keys Master and Calib.;
 *   - Calibration: grams per revolution and the test's shaft speed (input numbers); Back;
 *   - Alarm (priority high, a beep): "Row N: flow lost"; Ack;
 * with the object ids of operator_pool.VtIds (the labels' ids handed out from 100 up in the
 * Python builder's call order).
 *
 * `bad_font` writes the pool of the must-fail implement vt_defect=bad-pool: the rate's output
 * number names a font (0x7777) the pool lacks, which a VT refuses (faulty object 5100).
 * Pure C, no allocation: the caller owns the buffer. */
#ifndef AGRIHIL_ISO_POOL_H
#define AGRIHIL_ISO_POOL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define ISO_POOL_MAX_ROWS 16
#define ISO_POOL_MAX_BYTES 2304 /* 16 rows: 2,074 bytes; 4 rows: 1,047 */
#define ISO_POOL_VERSION_LABEL "AGF-VT1" /* stored on the VT under this label (7 bytes) */
#define ISO_POOL_ALARM_TEXT_LENGTH 24
#define ISO_POOL_BAD_FONT 0x7777u

/* object ids (operator_pool.VtIds) */
#define ISO_POOL_WORKING_SET 0u
#define ISO_POOL_RUN 1000u
#define ISO_POOL_CALIBRATION 1001u
#define ISO_POOL_ALARM 1002u
#define ISO_POOL_RUN_KEYS 2000u
#define ISO_POOL_CALIBRATION_KEYS 2001u
#define ISO_POOL_ALARM_KEYS 2002u
#define ISO_POOL_KEY_MASTER 3000u
#define ISO_POOL_KEY_CALIBRATION 3001u
#define ISO_POOL_KEY_BACK 3002u
#define ISO_POOL_KEY_ACK 3003u
#define ISO_POOL_RATE_VAR 5000u
#define ISO_POOL_ROW_VAR_1 5001u /* row r's number variable: 5001 + r - 1 (kg/ha x 10) */
#define ISO_POOL_RATE_OUT 5100u
#define ISO_POOL_ROW_OUT_1 5101u
#define ISO_POOL_MASTER_VAR 5200u
#define ISO_POOL_MASTER_OUT 5201u
#define ISO_POOL_CAL_GRAMS_IN 5300u
#define ISO_POOL_CAL_GRAMS_VAR 5301u
#define ISO_POOL_CAL_RPM_IN 5302u
#define ISO_POOL_CAL_RPM_VAR 5303u
#define ISO_POOL_ALARM_VAR 5400u
#define ISO_POOL_ALARM_OUT 5401u
#define ISO_POOL_FONT_LARGE 8000u
#define ISO_POOL_FONT_SMALL 8001u

/* Write the pool for `rows` rows (1 .. ISO_POOL_MAX_ROWS) into buf. Returns 0 and sets *size,
 * -1 for a bad row count or a buffer too small. */
int iso_vt_pool(unsigned rows, bool bad_font, uint8_t *buf, size_t cap, size_t *size);

#endif
