/* Named numeric parameters of a control core, set from "key=value" text.
 *
 * A core publishes a table of {name, pointer} pairs; the apps (--param key=value), the vector
 * replay (#params line) and a port to an MCU (a parameter block in flash) all set parameters
 * through it. Names match case-insensitively ("Kp1" and "kp1" are the same key). Pure: no I/O,
 * no allocation. */
#ifndef AGRIHIL_PARAMS_H
#define AGRIHIL_PARAMS_H

#include <stdbool.h>
#include <stddef.h>

typedef struct {
    const char *name;
    double *value;
} param_ref_t;

typedef enum {
    PARAM_OK = 0,
    PARAM_UNKNOWN,   /* no such key in the table */
    PARAM_BAD_VALUE  /* the text is not a finite number */
} param_status_t;

/* Case-insensitive ASCII comparison of two NUL-terminated strings. */
bool param_name_equal(const char *a, const char *b);

/* Parse a whole string as a finite double ("1e-3", "0x10" is rejected); true on success. */
bool param_parse_double(const char *text, double *out);

/* Look `name` up in `table` (n entries) and set it from `text`. */
param_status_t param_set(const param_ref_t *table, size_t n, const char *name, const char *text);

/* Split "key=value" in place: writes a NUL over '=' and returns the value, or NULL if there is
 * no '=' or the key is empty. */
char *param_split(char *key_value);

#endif
