/* The sowing-depth firmware's control at signal level: firmware/apps/depth_adapter.c and its
 * core, unchanged, fed with values instead of frames.
 *
 * Each control period (a time event every FIXED_SOLVER_STEP = 0.01 s, the rig's SYNC period)
 * the inputs become the frames the adapter would have heard since the last step, stamped with
 * the adapter clock (steps x period) as the firmware stamps frames in lockstep: the drive's
 * heartbeat when its NMT state changed (the adapter answers a state other than Operational
 * with an NMT start), the drive's TPDO1 (statusword, position) once heard, the terminal's
 * set-point once its counter has been heard, the tractor's speed once its distance has been
 * heard (a value holds until the next: a tractor that falls silent cannot be told from one
 * that keeps sending), and an inclinometer report only when its counter changed (the depth
 * filter takes one step per report). When the string parameter agrihil_gnss_port names a
 * serial port (the rig's AGRIHIL_GNSS_PORT) the GNSS receiver's NMEA is read each step, as
 * the firmware reads it. Then depth_step runs and its frames give the outputs: the drive's
 * controlword and target velocity (RPDO2) every step, its mode of operation (RPDO3) once
 * written, the NMT command of this step (0: none), and the status every tenth step (held in
 * between), as the firmware sends them. Parameters kp0, ki0, kd0 as the firmware's --param. */
#include <math.h>
#include <string.h>

#include "model.h"
#include "params.h"
#include "servo_cylinder_pdo.h"
#include "sowing_depth.h"

#define GNSS_BAUD 115200
#define J1939_NOT_AVAILABLE_MPS 64.255
#define J1939_NOT_AVAILABLE_RAW 0xFFFFu
#define NMT_ID 0x000u
#define INC_STATUS_OK 0

static const ValueReference FLOAT_PARAMS[] = {vr_kp0, vr_ki0, vr_kd0};
static const char *const FLOAT_PARAM_NAMES[] = {"kp0", "ki0", "kd0"};
#define N_FLOAT_PARAMS (sizeof FLOAT_PARAMS / sizeof FLOAT_PARAMS[0])

static bool is_real(ValueReference vr)
{
    return vr == vr_time || vr == vr_groundspeed || vr == vr_grounddistance ||
           vr == vr_inclinometer_x || vr == vr_setpoint_targetdepth || vr == vr_drive_position ||
           vr == vr_drive_targetvelocity || vr == vr_status_measureddepth ||
           vr == vr_status_rollerpositioncommand || (vr >= vr_kp0 && vr <= vr_kd0);
}

static bool is_integer(ValueReference vr)
{
    return vr == vr_inclinometer_xstatus || vr == vr_inclinometer_counter ||
           (vr >= vr_setpoint_enable && vr <= vr_drive_statusword) ||
           vr == vr_drive_nmtcommand || vr == vr_drive_controlword ||
           vr == vr_drive_modeofoperation || vr == vr_status_state || vr == vr_status_counter;
}

static bool is_boolean(ValueReference vr)
{
    return vr >= vr_status_sensorfault && vr <= vr_status_speedlost;
}

static bool is_input(ValueReference vr)
{
    return vr >= vr_groundspeed && vr <= vr_drive_position;
}

static bool is_parameter(ValueReference vr)
{
    return (vr >= vr_kp0 && vr <= vr_kd0) || vr == vr_gnss_port;
}

static void start(ModelInstance *comp)
{
    if (M(started)) {
        return;
    }
    M(started) = true;
    depth_config_t cfg;
    depth_config_defaults(&cfg);
    cfg.core.period_s = FIXED_SOLVER_STEP;
    param_ref_t refs[DEPTH_PARAM_COUNT];
    const size_t n = depth_param_refs(&cfg, refs);
    for (size_t p = 0; p < N_FLOAT_PARAMS; p++) {
        if (!M(given)[FLOAT_PARAMS[p]]) {
            continue;
        }
        for (size_t i = 0; i < n; i++) {
            if (param_name_equal(refs[i].name, FLOAT_PARAM_NAMES[p])) {
                *refs[i].value = M(real)[FLOAT_PARAMS[p]];
            }
        }
    }
    char err[128];
    if (depth_config_check(&cfg, err, sizeof err) != 0) {
        logError(comp, "%s", err);
        M(failed) = true;
        return;
    }
    depth_init(&M(adapter), &cfg);
    nmea_init(&M(nmea));
    if (M(gnss_port)[0] != '\0') {
        if (hal_serial_open(&M(gnss), M(gnss_port), GNSS_BAUD) != 0) {
            logError(comp, "GNSS (agrihil_gnss_port): %s", M(gnss).error);
            M(failed) = true;
            return;
        }
        M(gnss_open) = true;
    }
}

Status setStartValues(ModelInstance *comp)
{
    memset(&comp->modelData, 0, sizeof comp->modelData);
    M(real)[vr_grounddistance] = -1.0;
    M(real)[vr_setpoint_targetdepth] = 30.0;
    M(integer)[vr_inclinometer_counter] = -1;
    M(integer)[vr_setpoint_counter] = -1;
    M(integer)[vr_drive_nmtstate] = -1;
    M(integer)[vr_drive_statusword] = -1;
    M(last_inclinometer_counter) = -1;
    M(last_nmt_state) = -1;
    comp->nextEventTime = FIXED_SOLVER_STEP;
    comp->nextEventTimeDefined = true;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

static void poll_gnss(ModelInstance *comp, double now_s)
{
    if (!M(gnss_open)) {
        return;
    }
    char buf[256];
    for (;;) {
        long n = hal_serial_read(&M(gnss), buf, sizeof buf);
        if (n < 0) {
            logError(comp, "GNSS: %s; going on without it", M(gnss).error);
            hal_serial_close(&M(gnss));
            M(gnss_open) = false;
            return;
        }
        if (n == 0) {
            return;
        }
        for (long i = 0; i < n; i++) {
            double mps;
            nmea_result_t r = nmea_feed(&M(nmea), buf[i], &mps);
            if (r == NMEA_SPEED) {
                depth_on_gnss(&M(adapter), true, mps, now_s);
            } else if (r == NMEA_NO_FIX) {
                depth_on_gnss(&M(adapter), false, 0.0, now_s);
            }
        }
    }
}

static hal_can_frame_t frame_of(uint32_t id, bool extended, uint8_t len)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.extended = extended;
    f.len = len;
    return f;
}

static void take_outputs(ModelInstance *comp, const hal_can_frame_t *out, size_t n);

/* the frame to the adapter, its answers (an NMT start) to the outputs */
static void hear(ModelInstance *comp, const hal_can_frame_t *f, double now_s)
{
    hal_can_frame_t out[DEPTH_MAX_OUT];
    const size_t n = depth_on_frame(&M(adapter), f, now_s, out);
    take_outputs(comp, out, n);
}

static void take_inputs(ModelInstance *comp, double now_s)
{
    poll_gnss(comp, now_s);
    const int32_t nmt = M(integer)[vr_drive_nmtstate];
    if (nmt >= 0 && nmt != M(last_nmt_state)) {
        M(last_nmt_state) = nmt;
        hal_can_frame_t f = frame_of(0x700u + DEPTH_DRIVE_NODE, false, 1);
        f.data[0] = (uint8_t)nmt;
        hear(comp, &f, now_s);
    }
    if (M(integer)[vr_drive_statusword] >= 0) {
        struct servo_cylinder_pdo_tpdo1_t m;
        m.statusword = (uint16_t)M(integer)[vr_drive_statusword];
        m.position_actual_value = (int32_t)rint(M(real)[vr_drive_position] * 100.0);
        hal_can_frame_t f = frame_of(0x180u + DEPTH_DRIVE_NODE, false,
                                     SERVO_CYLINDER_PDO_TPDO1_LENGTH);
        servo_cylinder_pdo_tpdo1_pack(f.data, &m, sizeof f.data);
        hear(comp, &f, now_s);
    }
    if (M(integer)[vr_setpoint_counter] >= 0) {
        struct sowing_depth_depth_setpoint_t m;
        memset(&m, 0, sizeof m);
        m.ds_target_depth = sowing_depth_depth_setpoint_ds_target_depth_encode(
            M(real)[vr_setpoint_targetdepth]);
        m.ds_enable = (uint8_t)M(integer)[vr_setpoint_enable];
        m.ds_mode = (uint8_t)M(integer)[vr_setpoint_mode];
        hal_can_frame_t f = frame_of(SOWING_DEPTH_DEPTH_SETPOINT_FRAME_ID, true,
                                     SOWING_DEPTH_DEPTH_SETPOINT_LENGTH);
        sowing_depth_depth_setpoint_pack(f.data, &m, sizeof f.data);
        hear(comp, &f, now_s);
    }
    if (M(real)[vr_grounddistance] >= 0.0) {
        struct sowing_depth_gbsd_t m;
        memset(&m, 0, sizeof m);
        const double v = M(real)[vr_groundspeed];
        m.gbsd_ground_speed = v <= J1939_NOT_AVAILABLE_MPS
                                  ? sowing_depth_gbsd_gbsd_ground_speed_encode(v)
                                  : (uint16_t)J1939_NOT_AVAILABLE_RAW;
        m.gbsd_ground_distance =
            sowing_depth_gbsd_gbsd_ground_distance_encode(M(real)[vr_grounddistance]);
        hal_can_frame_t f = frame_of(SOWING_DEPTH_GBSD_FRAME_ID, true, SOWING_DEPTH_GBSD_LENGTH);
        sowing_depth_gbsd_pack(f.data, &m, sizeof f.data);
        hear(comp, &f, now_s);
    }
    const int32_t counter = M(integer)[vr_inclinometer_counter];
    if (counter >= 0 && counter != M(last_inclinometer_counter)) {
        M(last_inclinometer_counter) = counter;
        struct sowing_depth_inclinometer_t m;
        memset(&m, 0, sizeof m);
        m.inc_x_voltage =
            sowing_depth_inclinometer_inc_x_voltage_encode(M(real)[vr_inclinometer_x]);
        m.inc_x_status = (uint8_t)M(integer)[vr_inclinometer_xstatus];
        hal_can_frame_t f = frame_of(SOWING_DEPTH_INCLINOMETER_FRAME_ID, true,
                                     SOWING_DEPTH_INCLINOMETER_LENGTH);
        sowing_depth_inclinometer_pack(f.data, &m, sizeof f.data);
        hear(comp, &f, now_s);
    }
}

static void take_outputs(ModelInstance *comp, const hal_can_frame_t *out, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        const hal_can_frame_t *f = &out[i];
        if (!f->extended && f->id == NMT_ID && f->len >= 1) {
            M(integer)[vr_drive_nmtcommand] = f->data[0];
        } else if (!f->extended && f->id == SERVO_CYLINDER_PDO_RPDO3_FRAME_ID) {
            struct servo_cylinder_pdo_rpdo3_t m;
            if (servo_cylinder_pdo_rpdo3_unpack(&m, f->data, f->len) >= 0) {
                M(integer)[vr_drive_modeofoperation] = m.modes_of_operation;
            }
        } else if (!f->extended && f->id == SERVO_CYLINDER_PDO_RPDO2_FRAME_ID) {
            struct servo_cylinder_pdo_rpdo2_t m;
            if (servo_cylinder_pdo_rpdo2_unpack(&m, f->data, f->len) >= 0) {
                M(integer)[vr_drive_controlword] = m.controlword;
                M(real)[vr_drive_targetvelocity] = (double)m.target_velocity / 100.0;
            }
        } else if (f->extended && f->id == SOWING_DEPTH_DEPTH_CONTROLLER_STATUS_FRAME_ID) {
            struct sowing_depth_depth_controller_status_t m;
            if (sowing_depth_depth_controller_status_unpack(&m, f->data, f->len) >= 0) {
                M(real)[vr_status_measureddepth] =
                    sowing_depth_depth_controller_status_dc_measured_depth_decode(
                        m.dc_measured_depth);
                M(real)[vr_status_rollerpositioncommand] =
                    sowing_depth_depth_controller_status_dc_roller_position_command_decode(
                        m.dc_roller_position_command);
                M(integer)[vr_status_state] = m.dc_state;
                M(boolean)[vr_status_sensorfault] = m.dc_sensor_fault != 0;
                M(boolean)[vr_status_drivefault] = m.dc_drive_fault != 0;
                M(boolean)[vr_status_speedlost] = m.dc_speed_lost != 0;
                M(integer)[vr_status_counter] = m.dc_counter;
            }
        }
    }
}

Status eventUpdate(ModelInstance *comp)
{
    start(comp);
    if (M(failed)) {
        return Error;
    }
    if (comp->nextEventTimeDefined && comp->time + 1e-9 >= comp->nextEventTime) {
        const double now_s = (double)M(steps) * M(adapter).cfg.core.period_s;
        M(integer)[vr_drive_nmtcommand] = 0;
        take_inputs(comp, now_s);
        hal_can_frame_t out[DEPTH_MAX_OUT];
        const size_t n = depth_step(&M(adapter), now_s, out);
        M(steps)++;
        take_outputs(comp, out, n);
        /* the skeleton's clock is nSteps x FIXED_SOLVER_STEP: the same product, no drift */
        comp->nextEventTime = (double)(M(steps) + 1u) * FIXED_SOLVER_STEP;
    }
    comp->newDiscreteStatesNeeded = false;
    comp->terminateSimulation = false;
    comp->nextEventTimeDefined = true;
    return OK;
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (!is_real(vr)) {
        logError(comp, "Get Real is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    values[(*index)++] = vr == vr_time ? comp->time : M(real)[vr];
    return OK;
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (!is_real(vr) || !(is_input(vr) || (is_parameter(vr) && !M(started)))) {
        logError(comp, "Set Real is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    M(real)[vr] = values[(*index)++];
    M(given)[vr] = true;
    return OK;
}

Status getInt32(ModelInstance *comp, ValueReference vr, int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    if (!is_integer(vr)) {
        logError(comp, "Get Integer is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    values[(*index)++] = M(integer)[vr];
    return OK;
}

Status setInt32(ModelInstance *comp, ValueReference vr, const int32_t values[], size_t nValues,
                size_t *index)
{
    ASSERT_NVALUES(1);
    if (!is_integer(vr) || !is_input(vr)) {
        logError(comp, "Set Integer is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    M(integer)[vr] = values[(*index)++];
    return OK;
}

Status getBoolean(ModelInstance *comp, ValueReference vr, bool values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (!is_boolean(vr)) {
        logError(comp, "Get Boolean is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    values[(*index)++] = M(boolean)[vr];
    return OK;
}

Status setString(ModelInstance *comp, ValueReference vr, const char *const values[],
                 size_t nValues, size_t *index)
{
    ASSERT_NVALUES(1);
    const char *text = values[(*index)++];
    if (vr != vr_gnss_port || M(started) || text == NULL || strlen(text) >= PORT_TEXT) {
        logError(comp, "Set String is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    strcpy(M(gnss_port), text);
    return OK;
}
