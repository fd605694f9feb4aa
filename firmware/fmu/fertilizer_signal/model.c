/* The fertilizer firmware's control at signal level: firmware/apps/fertilizer_adapter.c and
 * its core, unchanged, fed with values instead of frames.
 *
 * Each control period (a time event every FIXED_SOLVER_STEP = 0.1 s, the rig's SYNC period)
 * the inputs become the adapter's state as its frame handlers would set it: the set-point as
 * it stands, a row's report only when its counter changed (the report's arrival, stamped with
 * the adapter clock steps x period, as the firmware stamps frames in lockstep), the Hall speed
 * once its counter has been heard, the ISO 11783-7 speeds once their distance has been heard
 * (a value above 64.255 m/s is "not available"), the ground-based speed heard every step once
 * heard (a value holds until the next), the operator's calibration test (MeterCalibration) once its values have
 * been heard. Then fert_step runs and its frames give the outputs: the motor command
 * every step, the status every tenth (held in between), as the firmware sends them.
 * Parameters: mode (the law) and ff_coeff, as the firmware's --param. */
#include <math.h>
#include <string.h>

#include "model.h"
#include "fertilizer.h"
#include "params.h"

#define J1939_NOT_AVAILABLE_MPS 64.255

static bool is_real(ValueReference vr)
{
    return vr == vr_time || vr == vr_setpoint_targetrate || vr == vr_setpoint_workingwidth ||
           vr == vr_setpoint_targetflow || (vr >= vr_row1_flow && vr <= vr_row4_flow) ||
           vr == vr_wheelspeed || (vr >= vr_wheelbasedspeed && vr <= vr_groundbaseddistance) ||
           (vr >= vr_motorcommand && vr <= vr_status_commandvoltage) || vr == vr_ff_coeff ||
           (vr >= vr_calibration_gramsperrev && vr <= vr_calibration_revolutions);
}

static bool is_integer(ValueReference vr)
{
    return (vr >= vr_setpoint_mode && vr <= vr_setpoint_counter && vr != vr_setpoint_enable) ||
           (vr >= vr_row1_counter && vr <= vr_row4_counter) || vr == vr_wheelcounter ||
           vr == vr_status_pidsegment || vr == vr_status_mode || vr == vr_status_counter;
}

static bool is_boolean(ValueReference vr)
{
    return vr == vr_setpoint_enable || (vr >= vr_row1_baselineready && vr <= vr_row4_adcoverrange) ||
           vr == vr_status_enabled || vr == vr_status_sensorfault;
}

static bool is_input(ValueReference vr)
{
    return (vr >= vr_setpoint_targetrate && vr <= vr_groundbaseddistance) ||
           (vr >= vr_calibration_gramsperrev && vr <= vr_calibration_revolutions);
}

static void start(ModelInstance *comp)
{
    if (M(started)) {
        return;
    }
    M(started) = true;
    ppid_law_t law = PPID_LAW_PHYSICAL;
    if (M(mode)[0] != '\0' && !ppid_law_parse(M(mode), &law)) {
        logError(comp, "parameter mode = '%s': not a law (physical, paper-literal, open-loop)",
                 M(mode));
        M(failed) = true;
        return;
    }
    fert_config_t cfg;
    fert_config_defaults(&cfg, law);
    cfg.period_s = FIXED_SOLVER_STEP;
    if (M(real)[vr_ff_coeff] > 0.0) {
        param_ref_t refs[FERT_PARAM_COUNT];
        size_t n = fert_param_refs(&cfg, refs);
        for (size_t i = 0; i < n; i++) {
            if (param_name_equal(refs[i].name, "ff_coeff")) {
                *refs[i].value = M(real)[vr_ff_coeff];
            }
        }
    }
    fert_init(&M(adapter), &cfg);
}

Status setStartValues(ModelInstance *comp)
{
    memset(&comp->modelData, 0, sizeof comp->modelData);
    M(integer)[vr_setpoint_activerows] = 4;
    M(integer)[vr_setpoint_counter] = -1;
    for (int r = 0; r < FERT_ROWS; r++) {
        M(integer)[vr_row1_counter + r] = -1;
        M(last_row_counter)[r] = -1;
    }
    M(integer)[vr_wheelcounter] = -1;
    M(last_wheel_counter) = -1;
    M(real)[vr_wheelbaseddistance] = -1.0;
    M(real)[vr_groundbaseddistance] = -1.0;
    M(real)[vr_calibration_gramsperrev] = -1.0;
    strcpy(M(mode), "physical");
    comp->nextEventTime = FIXED_SOLVER_STEP;
    comp->nextEventTimeDefined = true;
    return OK;
}

Status calculateValues(ModelInstance *comp)
{
    UNUSED(comp);
    return OK;
}

static void take_inputs(ModelInstance *comp, double now_s)
{
    fert_adapter_t *a = &M(adapter);
    if (M(integer)[vr_setpoint_counter] >= 0) {
        fert_setpoint_t *s = &a->setpoint;
        s->seen = true;
        s->mode = (uint8_t)M(integer)[vr_setpoint_mode];
        s->enable = M(boolean)[vr_setpoint_enable];
        s->target_rate = M(real)[vr_setpoint_targetrate];
        s->working_width = M(real)[vr_setpoint_workingwidth];
        s->target_flow = M(real)[vr_setpoint_targetflow];
        s->speed_source = (uint8_t)M(integer)[vr_setpoint_speedsource];
        s->active_rows = (uint8_t)M(integer)[vr_setpoint_activerows];
    }
    for (int i = 0; i < FERT_ROWS; i++) {
        const int32_t counter = M(integer)[vr_row1_counter + i];
        if (counter < 0 || counter == M(last_row_counter)[i]) {
            continue;
        }
        M(last_row_counter)[i] = counter;
        fert_row_t *r = &a->rows[i];
        r->seen = true;
        r->flow_gps = M(real)[vr_row1_flow + i];
        r->baseline_ready = M(boolean)[vr_row1_baselineready + i];
        r->overrange = M(boolean)[vr_row1_adcoverrange + i];
        r->at_s = now_s;
        r->reported = true;
    }
    if (M(integer)[vr_wheelcounter] >= 0) {
        a->speed[0] = (fert_speed_t){true, M(real)[vr_wheelspeed]};
    }
    if (M(real)[vr_wheelbaseddistance] >= 0.0) {
        const double v = M(real)[vr_wheelbasedspeed];
        const bool valid = v <= J1939_NOT_AVAILABLE_MPS;
        a->speed[1] = (fert_speed_t){valid, valid ? v : 0.0};
    }
    /* a value holds until the next: once heard, the tractor's ground-based speed is taken as
     * heard every step (standing still, neither speed nor distance changes while its frames
     * keep coming; a tractor that falls silent cannot be told from one standing still) */
    const double d = M(real)[vr_groundbaseddistance];
    const double v = M(real)[vr_groundbasedspeed];
    if (d >= 0.0) {
        const bool valid = v <= J1939_NOT_AVAILABLE_MPS;
        a->speed[2] = (fert_speed_t){valid, valid ? v : 0.0};
        a->ground_at_s = now_s;
    }
    if (M(real)[vr_calibration_gramsperrev] >= 0.0) {
        /* the terminal's calibration test, through the adapter's own handler: it sets the
         * meter map from the values alone, so taking it each step is taking it once */
        struct fertilizer_meter_calibration_t m;
        m.grams_per_rev =
            fertilizer_meter_calibration_grams_per_rev_encode(M(real)[vr_calibration_gramsperrev]);
        m.test_shaft_speed =
            fertilizer_meter_calibration_test_shaft_speed_encode(M(real)[vr_calibration_shaftspeed]);
        m.revolutions =
            fertilizer_meter_calibration_revolutions_encode(M(real)[vr_calibration_revolutions]);
        hal_can_frame_t f;
        memset(&f, 0, sizeof f);
        f.id = FERTILIZER_METER_CALIBRATION_FRAME_ID;
        f.len = 8;
        fertilizer_meter_calibration_pack(f.data, &m, sizeof f.data);
        fert_on_frame(a, &f, now_s);
    }
}

static void take_outputs(ModelInstance *comp, const hal_can_frame_t *out, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        const hal_can_frame_t *f = &out[i];
        if (f->id == FERTILIZER_ANALOG_OUTPUT_COMMAND_FRAME_ID) {
            struct fertilizer_analog_output_command_t m;
            if (fertilizer_analog_output_command_unpack(&m, f->data, f->len) >= 0) {
                M(real)[vr_motorcommand] =
                    fertilizer_analog_output_command_ch1_output_decode(m.ch1_output);
            }
        } else if (f->id == FERTILIZER_CONTROLLER_STATUS_FRAME_ID) {
            struct fertilizer_controller_status_t m;
            if (fertilizer_controller_status_unpack(&m, f->data, f->len) >= 0) {
                M(real)[vr_status_targetflow] =
                    fertilizer_controller_status_target_flow_decode(m.target_flow);
                M(real)[vr_status_measuredflow] =
                    fertilizer_controller_status_measured_flow_decode(m.measured_flow);
                M(real)[vr_status_commandvoltage] =
                    fertilizer_controller_status_command_voltage_decode(m.command_voltage);
                M(integer)[vr_status_pidsegment] = m.pid_segment;
                M(integer)[vr_status_mode] = m.active_mode;
                M(boolean)[vr_status_enabled] = m.enabled != 0;
                M(boolean)[vr_status_sensorfault] = m.sensor_fault != 0;
                M(integer)[vr_status_counter] = m.counter;
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
        const double now_s = (double)M(steps) * M(adapter).cfg.period_s;
        take_inputs(comp, now_s);
        hal_can_frame_t out[FERT_MAX_OUT];
        const size_t n = fert_step(&M(adapter), now_s, out);
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
    if (!is_real(vr) || !(is_input(vr) || (vr == vr_ff_coeff && !M(started)))) {
        logError(comp, "Set Real is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    M(real)[vr] = values[(*index)++];
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

Status setBoolean(ModelInstance *comp, ValueReference vr, const bool values[], size_t nValues,
                  size_t *index)
{
    ASSERT_NVALUES(1);
    if (!is_boolean(vr) || !is_input(vr)) {
        logError(comp, "Set Boolean is not allowed for value reference %u.", (unsigned)vr);
        return Error;
    }
    M(boolean)[vr] = values[(*index)++];
    return OK;
}

Status setString(ModelInstance *comp, ValueReference vr, const char *const values[],
                 size_t nValues, size_t *index)
{
    ASSERT_NVALUES(1);
    const char *text = values[(*index)++];
    if (vr != vr_mode || M(started) || text == NULL || strlen(text) >= MODE_TEXT) {
        logError(comp, "Set String is not allowed for value reference %u now.", (unsigned)vr);
        return Error;
    }
    strcpy(M(mode), text);
    return OK;
}
