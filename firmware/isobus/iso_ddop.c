#include "iso_ddop.h"

#include <math.h>
#include <string.h>

#define NULL_OBJECT 0xFFFFu
#define BOOM_OFFSET_X_MM (-1500) /* isobus_mode.BOOM_OFFSET_X_MM */
#define BROKEN_PRESENTATION 0x7FFFu

enum { DET_DEVICE = 1, DET_FUNCTION = 2, DET_SECTION = 4 };

typedef struct {
    uint8_t *buf;
    size_t cap;
    size_t len;
    bool overflow;
} writer_t;

static void put(writer_t *w, const void *bytes, size_t n)
{
    if (w->overflow || n > w->cap - w->len) {
        w->overflow = true;
        return;
    }
    memcpy(w->buf + w->len, bytes, n);
    w->len += n;
}

static void put_u8(writer_t *w, unsigned v)
{
    uint8_t b = (uint8_t)v;
    put(w, &b, 1);
}

static void put_u16(writer_t *w, unsigned v)
{
    uint8_t b[2] = {(uint8_t)(v & 0xFFu), (uint8_t)((v >> 8) & 0xFFu)};
    put(w, b, 2);
}

static void put_u32(writer_t *w, uint32_t v)
{
    uint8_t b[4];
    for (int i = 0; i < 4; i++) {
        b[i] = (uint8_t)(v >> (8 * i));
    }
    put(w, b, 4);
}

static void put_text(writer_t *w, const char *s)
{
    size_t n = strlen(s);
    put_u8(w, (unsigned)n);
    put(w, s, n);
}

static void head(writer_t *w, const char *table, unsigned id)
{
    put(w, table, 3);
    put_u16(w, id);
}

static void presentation(writer_t *w, unsigned id, const char *designator, float scale,
                         unsigned decimals)
{
    uint32_t bits;
    memcpy(&bits, &scale, sizeof bits);
    head(w, "DVP", id);
    put_u32(w, 0); /* offset */
    put_u32(w, bits);
    put_u8(w, decimals);
    put_text(w, designator);
}

static void element(writer_t *w, unsigned id, unsigned type, const char *designator,
                    unsigned number, unsigned parent, unsigned first_child, unsigned children)
{
    head(w, "DET", id);
    put_u8(w, type);
    put_text(w, designator);
    put_u16(w, number);
    put_u16(w, parent);
    put_u16(w, children);
    for (unsigned i = 0; i < children; i++) {
        put_u16(w, first_child + i);
    }
}

static void property(writer_t *w, unsigned id, unsigned ddi, int32_t value,
                     const char *designator, unsigned pres)
{
    head(w, "DPT", id);
    put_u16(w, ddi);
    put_u32(w, (uint32_t)value);
    put_text(w, designator);
    put_u16(w, pres);
}

static void process_data(writer_t *w, iso_ddop_info_t *info, unsigned id, unsigned element_no,
                         unsigned ddi, bool settable, unsigned triggers, const char *designator,
                         unsigned pres)
{
    unsigned props = ISO_DPD_DEFAULT_SET | (settable ? ISO_DPD_SETTABLE : 0u);
    head(w, "DPD", id);
    put_u16(w, ddi);
    put_u8(w, props);
    put_u8(w, triggers);
    put_text(w, designator);
    put_u16(w, pres);
    info->dpd[info->ndpd++] = (iso_dpd_t){(uint16_t)element_no, (uint16_t)ddi, (uint8_t)props,
                                          (uint8_t)triggers};
}

/* Python's floor division */
static int32_t floordiv(int32_t a, int32_t b)
{
    int32_t q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

/* The device object: designator, software version "1.0.0", NAME, serial "1", labels */
static void device_object(writer_t *w, const char *designator, uint64_t name_value,
                          const iso_ddop_info_t *info, unsigned version)
{
    head(w, "DVC", 0);
    put_text(w, designator);
    put_text(w, "1.0.0");
    uint8_t name[8];
    for (int i = 0; i < 8; i++) {
        name[i] = (uint8_t)(name_value >> (8 * i));
    }
    put(w, name, 8);
    put_text(w, "1");
    put(w, info->structure_label, 7);
    put(w, info->localization_label, 7);
    if (version >= 4) {
        put_text(w, ""); /* extended structure label: none */
    }
}

int iso_meter_pool(const iso_ddop_params_t *p, uint8_t *buf, size_t cap, iso_ddop_info_t *info)
{
    memset(info, 0, sizeof *info);
    if (p->rows < 1 || p->rows > ISO_DDOP_MAX_ROWS || !(p->width_m > 0.0 && p->width_m <= 30.0)) {
        return -1;
    }
    writer_t w = {buf, cap, 0, false};
    /* ids in the builder's call order */
    enum { DVC = 0, MM = 1, MS = 2, KG_HA = 3, DEVICE = 4, BOOM = 5, FIRST_BOOM_CHILD = 6,
           BOOM_CHILDREN = 12 };
    const unsigned dense = ISO_TRIGGER_ON_CHANGE | ISO_TRIGGER_TIME;

    memcpy(info->structure_label, p->broken ? "AGF-BRK" : "AGF-ISO", 7);
    memcpy(info->localization_label, "en\0\0\0\0\xff", 7);
    device_object(&w, "agrihil fertilizer meter", p->name, info, p->version);
    presentation(&w, MM, "mm", 1.0f, 0);
    presentation(&w, MS, "ms", 1.0f, 0);
    presentation(&w, KG_HA, "kg/ha", 0.01f, 1);
    element(&w, DEVICE, DET_DEVICE, "Fertilizer meter", 0, DVC, 0, 0);
    element(&w, BOOM, DET_FUNCTION, "Boom", 1, DEVICE, FIRST_BOOM_CHILD, BOOM_CHILDREN);
    int32_t width_mm = (int32_t)rint(p->width_m * 1000.0);
    unsigned id = FIRST_BOOM_CHILD;
    property(&w, id++, ISO_DDI_ACTUAL_WORKING_WIDTH, width_mm, "Working width", MM);
    property(&w, id++, ISO_DDI_OFFSET_X, BOOM_OFFSET_X_MM, "Offset X", MM);
    property(&w, id++, ISO_DDI_OFFSET_Y, 0, "Offset Y", MM);
    property(&w, id++, ISO_DDI_TURN_ON_TIME, p->latency_ms, "Turn on time", MS);
    property(&w, id++, ISO_DDI_TURN_OFF_TIME, p->latency_ms, "Turn off time", MS);
    property(&w, id++, ISO_DDI_SETPOINT_LATENCY, p->latency_ms, "Setpoint latency", MS);
    process_data(&w, info, id++, 1, ISO_DDI_SETPOINT_MASS_PER_AREA_RATE, true,
                 ISO_TRIGGER_ON_CHANGE, "Target rate", KG_HA);
    process_data(&w, info, id++, 1, ISO_DDI_ACTUAL_MASS_PER_AREA_RATE, false, dense,
                 "Actual rate", p->broken ? BROKEN_PRESENTATION : KG_HA);
    process_data(&w, info, id++, 1, ISO_DDI_ACTUAL_WORK_STATE, false, dense,
                 "Actual work state", NULL_OBJECT);
    process_data(&w, info, id++, 1, ISO_DDI_SETPOINT_WORK_STATE, true, ISO_TRIGGER_ON_CHANGE,
                 "Setpoint work state", NULL_OBJECT);
    process_data(&w, info, id++, 1, ISO_DDI_ACTUAL_CONDENSED_1_16, false, dense,
                 "Actual work state 1-16", NULL_OBJECT);
    process_data(&w, info, id++, 1, ISO_DDI_SETPOINT_CONDENSED_1_16, true,
                 ISO_TRIGGER_ON_CHANGE, "Setpoint work state 1-16", NULL_OBJECT);
    int32_t rows = (int32_t)p->rows;
    int32_t row_mm = floordiv(width_mm, rows);
    for (int32_t i = 0; i < rows; i++) {
        char designator[8] = "Row ";
        int n = i + 1;
        size_t at = 4;
        if (n >= 10) {
            designator[at++] = (char)('0' + n / 10);
        }
        designator[at++] = (char)('0' + n % 10);
        designator[at] = '\0';
        unsigned section = id++;
        element(&w, section, DET_SECTION, designator, 2u + (unsigned)i, BOOM, id, 3);
        /* offsets are from the device's reference point (ISO 11783-10): the boom's */
        property(&w, id++, ISO_DDI_OFFSET_X, BOOM_OFFSET_X_MM, "Offset X", MM);
        property(&w, id++, ISO_DDI_OFFSET_Y,
                 floordiv(-width_mm, 2) + i * row_mm + floordiv(row_mm, 2), "Offset Y", MM);
        property(&w, id++, ISO_DDI_ACTUAL_WORKING_WIDTH, row_mm, "Width", MM);
    }
    if (w.overflow) {
        return -1;
    }
    info->size = w.len;
    info->boom = 1;
    info->elements = (uint16_t)(2u + p->rows);
    info->sections = p->rows;
    return 0;
}

int iso_depth_pool(const iso_depth_ddop_params_t *p, uint8_t *buf, size_t cap,
                   iso_ddop_info_t *info)
{
    memset(info, 0, sizeof *info);
    if (!(p->width_m > 0.0 && p->width_m <= 30.0)) {
        return -1;
    }
    writer_t w = {buf, cap, 0, false};
    /* ids in depth_pool()'s call order */
    enum { MM = 1, MS = 2, DEVICE = 3, LINE = 4, FIRST_LINE_CHILD = 5, LINE_CHILDREN = 9 };
    memcpy(info->structure_label, "AGD-ISO", 7);
    memcpy(info->localization_label, "en\0\0\0\0\xff", 7);
    device_object(&w, "agrihil depth seeder", p->name, info, p->version);
    presentation(&w, MM, "mm", 1.0f, 0);
    presentation(&w, MS, "ms", 1.0f, 0);
    element(&w, DEVICE, DET_DEVICE, "Depth seeder", 0, 0, 0, 0);
    element(&w, LINE, DET_FUNCTION, "Seed line", 1, DEVICE, FIRST_LINE_CHILD, LINE_CHILDREN);
    unsigned id = FIRST_LINE_CHILD;
    property(&w, id++, ISO_DDI_ACTUAL_WORKING_WIDTH, (int32_t)rint(p->width_m * 1000.0),
             "Working width", MM);
    property(&w, id++, ISO_DDI_OFFSET_X, p->offset_x_mm, "Offset X", MM);
    property(&w, id++, ISO_DDI_OFFSET_Y, 0, "Offset Y", MM);
    property(&w, id++, ISO_DDI_SETPOINT_LATENCY, (int32_t)rint(p->latency_ms),
             "Setpoint latency", MS);
    property(&w, id++, ISO_DDI_DEFAULT_SEEDING_DEPTH, (int32_t)rint(p->default_mm),
             "Default depth", MM);
    property(&w, id++, ISO_DDI_MINIMUM_SEEDING_DEPTH, (int32_t)rint(p->min_mm),
             "Minimum depth", MM);
    property(&w, id++, ISO_DDI_MAXIMUM_SEEDING_DEPTH, (int32_t)rint(p->max_mm),
             "Maximum depth", MM);
    process_data(&w, info, id++, 1, ISO_DDI_SETPOINT_SEEDING_DEPTH, true,
                 ISO_TRIGGER_ON_CHANGE, "Target depth", MM);
    process_data(&w, info, id++, 1, ISO_DDI_ACTUAL_SEEDING_DEPTH, false,
                 ISO_TRIGGER_ON_CHANGE | ISO_TRIGGER_TIME, "Actual depth", MM);
    if (w.overflow) {
        return -1;
    }
    info->size = w.len;
    info->boom = 1;
    info->elements = 2;
    info->sections = 0;
    return 0;
}

const iso_dpd_t *iso_ddop_dpd(const iso_ddop_info_t *info, uint16_t element_no, uint16_t ddi)
{
    for (size_t i = 0; i < info->ndpd; i++) {
        if (info->dpd[i].element == element_no && info->dpd[i].ddi == ddi) {
            return &info->dpd[i];
        }
    }
    return NULL;
}
