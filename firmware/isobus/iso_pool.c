#include "iso_pool.h"

#include <stdio.h>
#include <string.h>

/* object types (ISO 11783-6 Annex B) */
enum { T_WORKING_SET = 0, T_DATA_MASK = 1, T_ALARM_MASK = 2, T_SOFT_KEY_MASK = 4, T_KEY = 5,
       T_INPUT_NUMBER = 9, T_OUTPUT_STRING = 11, T_OUTPUT_NUMBER = 12, T_NUMBER_VARIABLE = 21,
       T_STRING_VARIABLE = 22, T_FONT_ATTRIBUTES = 23 };
/* colours of the VT palette (operator_pool.py) */
enum { BLACK = 0, WHITE = 1, SILVER = 7, RED = 12 };
#define NO_OBJECT 0xFFFFu
#define SCALE_TENTH 0.1f
#define FIRST_AUTO_ID 100u
#define MAX_CHILDREN (4 + 2 * ISO_POOL_MAX_ROWS)

typedef struct {
    uint8_t *buf;
    size_t cap, n;
    bool overflow;
    uint16_t next_id; /* the Python builder's ids for objects made without one */
} writer_t;

typedef struct {
    uint16_t id;
    int16_t x, y;
} child_t;

static void u8(writer_t *w, unsigned v)
{
    if (w->n >= w->cap) {
        w->overflow = true;
        return;
    }
    w->buf[w->n++] = (uint8_t)(v & 0xFFu);
}

static void u16(writer_t *w, unsigned v)
{
    u8(w, v);
    u8(w, v >> 8);
}

static void u32(writer_t *w, uint32_t v)
{
    u16(w, (unsigned)(v & 0xFFFFu));
    u16(w, (unsigned)(v >> 16));
}

static void f32(writer_t *w, float f)
{
    uint32_t bits;
    memcpy(&bits, &f, sizeof bits);
    u32(w, bits);
}

static void bytes(writer_t *w, const char *text, size_t len)
{
    for (size_t i = 0; i < len; i++) {
        u8(w, (uint8_t)text[i]);
    }
}

static void header(writer_t *w, unsigned id, unsigned type)
{
    u16(w, id);
    u8(w, type);
}

static uint16_t auto_id(writer_t *w)
{
    return w->next_id++;
}

static void children(writer_t *w, const child_t *c, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        u16(w, c[i].id);
        u16(w, (uint16_t)c[i].x);
        u16(w, (uint16_t)c[i].y);
    }
}

/* --- the builder's conveniences, with the attributes meter_vt_pool gives ------------------ */

static void font(writer_t *w, unsigned id, unsigned size)
{
    header(w, id, T_FONT_ATTRIBUTES);
    u8(w, BLACK); /* colour */
    u8(w, size);
    u8(w, 0); /* type */
    u8(w, 0); /* style */
    u8(w, 0); /* macros */
}

static void output_string(writer_t *w, unsigned id, const char *text, unsigned font_id,
                          unsigned width, unsigned height, unsigned background,
                          unsigned options, unsigned variable)
{
    size_t len = strlen(text);
    header(w, id, T_OUTPUT_STRING);
    u16(w, width);
    u16(w, height);
    u8(w, background);
    u16(w, font_id);
    u8(w, options);
    u16(w, variable);
    u8(w, 0); /* justification */
    u16(w, (unsigned)len);
    bytes(w, text, len);
    u8(w, 0); /* macros */
}

/* label(): an output string with its own text, white, transparent (options 0x01) */
static uint16_t label(writer_t *w, const char *text, unsigned width, unsigned font_id)
{
    uint16_t id = auto_id(w);
    output_string(w, id, text, font_id, width, 20, WHITE, 0x01, NO_OBJECT);
    return id;
}

/* key(): a soft key drawing a silver label at (0, 0) */
static void key(writer_t *w, const char *text, unsigned id, unsigned code)
{
    uint16_t text_id = auto_id(w);
    output_string(w, text_id, text, ISO_POOL_FONT_SMALL, 76, 20, SILVER, 0x01, NO_OBJECT);
    header(w, id, T_KEY);
    u8(w, SILVER); /* background */
    u8(w, code);
    u8(w, 1); /* children */
    u8(w, 0); /* macros */
    child_t c = {text_id, 0, 0};
    children(w, &c, 1);
}

static void soft_key_mask(writer_t *w, unsigned id, const uint16_t *keys, size_t n)
{
    header(w, id, T_SOFT_KEY_MASK);
    u8(w, 0); /* background */
    u8(w, (unsigned)n);
    u8(w, 0); /* macros */
    for (size_t i = 0; i < n; i++) {
        u16(w, keys[i]);
    }
}

static void number_variable(writer_t *w, unsigned id, uint32_t value)
{
    header(w, id, T_NUMBER_VARIABLE);
    u32(w, value);
}

static void string_variable(writer_t *w, unsigned id, const char *text)
{
    size_t len = strlen(text);
    header(w, id, T_STRING_VARIABLE);
    u16(w, (unsigned)len);
    bytes(w, text, len);
}

/* output_number(): scale 0.1, 1 decimal, white, right-justified (0x02) */
static void output_number(writer_t *w, unsigned id, unsigned variable, unsigned font_id,
                          unsigned width, unsigned height)
{
    header(w, id, T_OUTPUT_NUMBER);
    u16(w, width);
    u16(w, height);
    u8(w, WHITE);
    u16(w, font_id);
    u8(w, 0); /* options */
    u16(w, variable);
    u32(w, 0); /* value */
    u32(w, 0); /* offset */
    f32(w, SCALE_TENTH);
    u8(w, 1); /* decimals */
    u8(w, 0); /* format */
    u8(w, 0x02);
    u8(w, 0); /* macros */
}

/* input_number(): scale 0.1, 1 decimal, white, enabled (options2 0x01) */
static void input_number(writer_t *w, unsigned id, unsigned variable, uint32_t min_value,
                         uint32_t max_value)
{
    header(w, id, T_INPUT_NUMBER);
    u16(w, 160);
    u16(w, 24);
    u8(w, WHITE);
    u16(w, ISO_POOL_FONT_LARGE);
    u8(w, 0); /* options */
    u16(w, variable);
    u32(w, 0); /* value */
    u32(w, min_value);
    u32(w, max_value);
    u32(w, 0); /* offset */
    f32(w, SCALE_TENTH);
    u8(w, 1); /* decimals */
    u8(w, 0); /* format */
    u8(w, 0); /* justification */
    u8(w, 0x01);
    u8(w, 0); /* macros */
}

static void mask(writer_t *w, unsigned id, unsigned type, unsigned soft_keys,
                 const child_t *c, size_t n)
{
    header(w, id, type);
    u8(w, WHITE);
    u16(w, soft_keys);
    if (type == T_ALARM_MASK) {
        u8(w, 0); /* priority: high */
        u8(w, 0); /* acoustic signal: highest */
    }
    u8(w, (unsigned)n);
    u8(w, 0); /* macros */
    children(w, c, n);
}

/* --- the pool ---------------------------------------------------------------------------- */

int iso_vt_pool(unsigned rows, bool bad_font, uint8_t *buf, size_t cap, size_t *size)
{
    if (rows < 1 || rows > ISO_POOL_MAX_ROWS) {
        return -1;
    }
    writer_t wr = {buf, cap, 0, false, FIRST_AUTO_ID};
    writer_t *w = &wr;
    font(w, ISO_POOL_FONT_LARGE, 4);
    font(w, ISO_POOL_FONT_SMALL, 3);
    key(w, "Master", ISO_POOL_KEY_MASTER, 1);
    key(w, "Calib.", ISO_POOL_KEY_CALIBRATION, 2);
    key(w, "Back", ISO_POOL_KEY_BACK, 3);
    key(w, "Ack", ISO_POOL_KEY_ACK, 4);
    static const uint16_t run_keys[] = {ISO_POOL_KEY_MASTER, ISO_POOL_KEY_CALIBRATION};
    static const uint16_t calibration_keys[] = {ISO_POOL_KEY_BACK};
    static const uint16_t alarm_keys[] = {ISO_POOL_KEY_ACK};
    soft_key_mask(w, ISO_POOL_RUN_KEYS, run_keys, 2);
    soft_key_mask(w, ISO_POOL_CALIBRATION_KEYS, calibration_keys, 1);
    soft_key_mask(w, ISO_POOL_ALARM_KEYS, alarm_keys, 1);

    number_variable(w, ISO_POOL_RATE_VAR, 0);
    output_number(w, ISO_POOL_RATE_OUT, ISO_POOL_RATE_VAR,
                  bad_font ? ISO_POOL_BAD_FONT : ISO_POOL_FONT_LARGE, 160, 24);
    string_variable(w, ISO_POOL_MASTER_VAR, "OFF");
    output_string(w, ISO_POOL_MASTER_OUT, "", ISO_POOL_FONT_LARGE, 60, 24, WHITE, 0,
                  ISO_POOL_MASTER_VAR);
    child_t run[MAX_CHILDREN];
    size_t n = 0;
    run[n++] = (child_t){label(w, "Rate set-point (kg/ha)", 280, ISO_POOL_FONT_SMALL), 10, 10};
    run[n++] = (child_t){ISO_POOL_RATE_OUT, 300, 8};
    run[n++] = (child_t){label(w, "Master", 100, ISO_POOL_FONT_SMALL), 10, 44};
    run[n++] = (child_t){ISO_POOL_MASTER_OUT, 300, 40};
    for (unsigned row = 1; row <= rows; row++) {
        unsigned var = ISO_POOL_ROW_VAR_1 + row - 1;
        unsigned out = ISO_POOL_ROW_OUT_1 + row - 1;
        number_variable(w, var, 0);
        output_number(w, out, var, ISO_POOL_FONT_SMALL, 120, 20);
        int16_t y = (int16_t)(80 + 24 * (row - 1));
        char text[32];
        snprintf(text, sizeof text, "Row %u actual (kg/ha)", row);
        run[n++] = (child_t){label(w, text, 280, ISO_POOL_FONT_SMALL), 10, y};
        run[n++] = (child_t){(uint16_t)out, 300, y};
    }
    mask(w, ISO_POOL_RUN, T_DATA_MASK, ISO_POOL_RUN_KEYS, run, n);

    number_variable(w, ISO_POOL_CAL_GRAMS_VAR, 0);
    input_number(w, ISO_POOL_CAL_GRAMS_IN, ISO_POOL_CAL_GRAMS_VAR, 1, 5000);
    number_variable(w, ISO_POOL_CAL_RPM_VAR, 210);
    input_number(w, ISO_POOL_CAL_RPM_IN, ISO_POOL_CAL_RPM_VAR, 10, 2000);
    child_t cal[5];
    cal[0] = (child_t){label(w, "Calibration test", 280, ISO_POOL_FONT_LARGE), 10, 10};
    cal[1] = (child_t){label(w, "Grams per revolution", 280, ISO_POOL_FONT_SMALL), 10, 50};
    cal[2] = (child_t){ISO_POOL_CAL_GRAMS_IN, 300, 48};
    cal[3] = (child_t){label(w, "Shaft speed (rpm)", 280, ISO_POOL_FONT_SMALL), 10, 84};
    cal[4] = (child_t){ISO_POOL_CAL_RPM_IN, 300, 82};
    mask(w, ISO_POOL_CALIBRATION, T_DATA_MASK, ISO_POOL_CALIBRATION_KEYS, cal, 5);

    char blank[ISO_POOL_ALARM_TEXT_LENGTH + 1];
    memset(blank, ' ', ISO_POOL_ALARM_TEXT_LENGTH);
    blank[ISO_POOL_ALARM_TEXT_LENGTH] = '\0';
    string_variable(w, ISO_POOL_ALARM_VAR, blank);
    output_string(w, ISO_POOL_ALARM_OUT, "", ISO_POOL_FONT_LARGE, 440, 30, RED, 0,
                  ISO_POOL_ALARM_VAR);
    child_t alarm[2];
    alarm[0] = (child_t){label(w, "ALARM", 200, ISO_POOL_FONT_LARGE), 10, 10};
    alarm[1] = (child_t){ISO_POOL_ALARM_OUT, 10, 60};
    mask(w, ISO_POOL_ALARM, T_ALARM_MASK, ISO_POOL_ALARM_KEYS, alarm, 2);

    child_t designator = {label(w, "Fertilizer meter", 200, ISO_POOL_FONT_SMALL), 0, 0};
    header(w, ISO_POOL_WORKING_SET, T_WORKING_SET);
    u8(w, WHITE);
    u8(w, 1); /* selectable */
    u16(w, ISO_POOL_RUN);
    u8(w, 1); /* children */
    u8(w, 0); /* macros */
    u8(w, 0); /* languages */
    children(w, &designator, 1);
    if (w->overflow) {
        return -1;
    }
    *size = w->n;
    return 0;
}
