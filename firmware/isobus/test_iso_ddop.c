/* test_iso_ddop FILE: the C DDOP writer against the Python's pools (reference_controllers/
 * vectors/isobus-ddop.txt, written by python -m reference_controllers.vectors.isobus): every
 * line's parameters must give the same bytes, in version 4 and 3. Also checks the process
 * data table the TC client answers from. Exit 0 when all match, 1 naming the first difference. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_ddop.h"

#define BUF 4096
#define LINE_LEN (2 * BUF + 256)

static uint64_t name_of(unsigned long identity)
{
    /* isobus_mode.implement_name: group 2, class 5, function 128, self-configurable */
    return (uint64_t)identity | ((uint64_t)128 << 40) | ((uint64_t)5 << 49) |
           ((uint64_t)2 << 60) | ((uint64_t)1 << 63);
}

static int hexbyte(const char *s)
{
    unsigned v;
    return sscanf(s, "%2x", &v) == 1 ? (int)v : -1;
}

static int check_table(const iso_ddop_info_t *info, unsigned rows, long lineno)
{
    static const uint16_t ddis[ISO_DDOP_MAX_DPD] = {6, 7, 141, 289, 161, 290};
    static const uint8_t settable[ISO_DDOP_MAX_DPD] = {1, 0, 0, 1, 0, 1};
    if (info->ndpd != ISO_DDOP_MAX_DPD || info->boom != 1 || info->elements != 2 + rows ||
        info->sections != rows) {
        fprintf(stderr, "line %ld: table has %zu DPDs, boom %u, %u elements\n", lineno,
                info->ndpd, info->boom, info->elements);
        return 1;
    }
    for (size_t i = 0; i < info->ndpd; i++) {
        const iso_dpd_t *d = &info->dpd[i];
        bool s = (d->properties & ISO_DPD_SETTABLE) != 0;
        if (d->ddi != ddis[i] || d->element != 1 || s != (settable[i] != 0) ||
            iso_ddop_dpd(info, 1, ddis[i]) != d) {
            fprintf(stderr, "line %ld: DPD %zu is DDI %u on element %u\n", lineno, i, d->ddi,
                    d->element);
            return 1;
        }
    }
    if (iso_ddop_dpd(info, 2, 6) != NULL || iso_ddop_dpd(info, 1, 142) != NULL) {
        fprintf(stderr, "line %ld: a DPD where the pool has none\n", lineno);
        return 1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_iso_ddop FILE\n");
        return 2;
    }
    FILE *fp = fopen(argv[1], "r");
    if (fp == NULL) {
        fprintf(stderr, "%s: missing\n", argv[1]);
        return 2;
    }
    static char line[LINE_LEN];
    static uint8_t want[BUF], got[BUF];
    long lineno = 0;
    int cases = 0, rc = 0;
    while (rc == 0 && fgets(line, sizeof line, fp) != NULL) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n') {
            continue;
        }
        unsigned long identity;
        double width;
        unsigned rows, broken, version;
        long latency;
        int at = 0;
        if (sscanf(line, "%lu %lf %u %ld %u %u %n", &identity, &width, &rows, &latency, &broken,
                   &version, &at) != 6) {
            fprintf(stderr, "%s:%ld: not 'identity width rows latency broken version hex'\n",
                    argv[1], lineno);
            rc = 2;
            break;
        }
        size_t n = 0;
        for (const char *h = line + at; h[0] && h[0] != '\n' && n < BUF; h += 2) {
            int b = hexbyte(h);
            if (b < 0) {
                fprintf(stderr, "%s:%ld: bad hex\n", argv[1], lineno);
                return 2;
            }
            want[n++] = (uint8_t)b;
        }
        iso_ddop_params_t p = {name_of(identity), width, rows, (int32_t)latency, broken != 0,
                               version};
        iso_ddop_info_t info;
        if (iso_meter_pool(&p, got, sizeof got, &info) != 0) {
            fprintf(stderr, "%s:%ld: the C writer refused the parameters\n", argv[1], lineno);
            rc = 1;
            break;
        }
        if (info.size != n || memcmp(got, want, n) != 0) {
            size_t i = 0;
            while (i < n && i < info.size && got[i] == want[i]) {
                i++;
            }
            fprintf(stderr, "%s:%ld: C pool of %zu bytes, Python's %zu; first difference at "
                    "byte %zu\n", argv[1], lineno, info.size, n, i);
            rc = 1;
            break;
        }
        rc = check_table(&info, rows, lineno);
        cases++;
    }
    fclose(fp);
    if (rc == 0 && cases == 0) {
        fprintf(stderr, "%s: no pools\n", argv[1]);
        rc = 2;
    }
    if (rc == 0) {
        /* out of range: refused, as the Python raises */
        uint8_t small[16];
        iso_ddop_info_t info;
        iso_ddop_params_t rows0 = {name_of(1), 3.0, 0, 430, false, 4};
        iso_ddop_params_t rows17 = {name_of(1), 3.0, 17, 430, false, 4};
        iso_ddop_params_t fits = {name_of(1), 3.0, 4, 430, false, 4};
        if (iso_meter_pool(&rows0, got, sizeof got, &info) == 0 ||
            iso_meter_pool(&rows17, got, sizeof got, &info) == 0 ||
            iso_meter_pool(&fits, small, sizeof small, &info) == 0) {
            fprintf(stderr, "rows 0, rows 17 or a too small buffer was not refused\n");
            rc = 1;
        }
    }
    if (rc == 0) {
        printf("%s: %d pools identical\n", argv[1], cases);
    }
    return rc;
}
