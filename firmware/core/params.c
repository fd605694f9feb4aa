#include "params.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

bool param_name_equal(const char *a, const char *b)
{
    for (;; a++, b++) {
        int ca = tolower((unsigned char)*a);
        int cb = tolower((unsigned char)*b);
        if (ca != cb) {
            return false;
        }
        if (ca == '\0') {
            return true;
        }
    }
}

bool param_parse_double(const char *text, double *out)
{
    if (text == NULL || *text == '\0' || isspace((unsigned char)*text)) {
        return false;
    }
    /* strtod would read hex floats and "inf"/"nan": parameters are plain decimal numbers */
    for (const char *p = text; *p != '\0'; p++) {
        if (!(isdigit((unsigned char)*p) || *p == '.' || *p == '-' || *p == '+' || *p == 'e' ||
              *p == 'E')) {
            return false;
        }
    }
    char *end = NULL;
    errno = 0;
    double v = strtod(text, &end);
    if (end == text || *end != '\0' || errno == ERANGE || !isfinite(v)) {
        return false;
    }
    *out = v;
    return true;
}

param_status_t param_set(const param_ref_t *table, size_t n, const char *name, const char *text)
{
    for (size_t i = 0; i < n; i++) {
        if (param_name_equal(table[i].name, name)) {
            double v;
            if (!param_parse_double(text, &v)) {
                return PARAM_BAD_VALUE;
            }
            *table[i].value = v;
            return PARAM_OK;
        }
    }
    return PARAM_UNKNOWN;
}

char *param_split(char *key_value)
{
    char *eq = strchr(key_value, '=');
    if (eq == NULL || eq == key_value) {
        return NULL;
    }
    *eq = '\0';
    return eq + 1;
}
