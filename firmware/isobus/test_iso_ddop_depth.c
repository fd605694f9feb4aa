/* test_iso_ddop_depth FILE: the C depth DDOP writer against the Python's depth_pool()
 * (firmware/isobus/data/depth-ddop.txt, written by python -m
 * reference_controllers.vectors.isobus_depth): every line's parameters must give the same
 * bytes. Also checks the process data table the TC client answers from. Exit 0 when all match,
 * 1 naming the first difference, 2 on a file that cannot be read. */
#include <stdio.h>
#include <string.h>

#include "iso_ddop.h"

#define BUF 2048
#define LINE_LEN (2 * BUF + 256)

static uint64_t name_of(unsigned long identity)
{
    /* isobus_mode.implement_name: group 2, class 4 (planters/seeders), function 128,
     * self-configurable */
    return (uint64_t)identity | ((uint64_t)128 << 40) | ((uint64_t)4 << 49) |
           ((uint64_t)2 << 60) | ((uint64_t)1 << 63);
}

static int check_table(const iso_ddop_info_t *info, long lineno)
{
    if (info->ndpd != 2 || info->boom != 1 || info->elements != 2 || info->sections != 0 ||
        info->dpd[0].ddi != ISO_DDI_SETPOINT_SEEDING_DEPTH ||
        (info->dpd[0].properties & ISO_DPD_SETTABLE) == 0 ||
        info->dpd[1].ddi != ISO_DDI_ACTUAL_SEEDING_DEPTH ||
        (info->dpd[1].properties & ISO_DPD_SETTABLE) != 0 ||
        info->dpd[1].triggers != (ISO_TRIGGER_ON_CHANGE | ISO_TRIGGER_TIME) ||
        iso_ddop_dpd(info, 1, ISO_DDI_DEFAULT_SEEDING_DEPTH) != NULL) {
        fprintf(stderr, "line %ld: table has %zu DPDs, seed line %u, %u elements\n", lineno,
                info->ndpd, info->boom, info->elements);
        return 1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_iso_ddop_depth FILE\n");
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
        double width, latency, def, lo, hi;
        long offset;
        unsigned version;
        int at = 0;
        if (sscanf(line, "%lu %lf %ld %lf %lf %lf %lf %u %n", &identity, &width, &offset,
                   &latency, &def, &lo, &hi, &version, &at) != 8) {
            fprintf(stderr, "%s:%ld: not 'identity width offset latency default min max "
                    "version hex'\n", argv[1], lineno);
            rc = 2;
            break;
        }
        size_t n = 0;
        for (const char *h = line + at; h[0] && h[0] != '\n' && n < BUF; h += 2) {
            unsigned v;
            if (sscanf(h, "%2x", &v) != 1) {
                fprintf(stderr, "%s:%ld: bad hex\n", argv[1], lineno);
                fclose(fp);
                return 2;
            }
            want[n++] = (uint8_t)v;
        }
        iso_depth_ddop_params_t p = {name_of(identity), width, (int32_t)offset, latency, def,
                                     lo, hi, version};
        iso_ddop_info_t info;
        if (iso_depth_pool(&p, got, sizeof got, &info) != 0) {
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
        rc = check_table(&info, lineno);
        cases++;
    }
    fclose(fp);
    if (rc == 0 && cases == 0) {
        fprintf(stderr, "%s: no pools\n", argv[1]);
        rc = 2;
    }
    if (rc == 0) {
        /* out of range or too small a buffer: refused */
        uint8_t small[16];
        iso_ddop_info_t info;
        iso_depth_ddop_params_t wide = {name_of(1), 30.5, -1900, 1000, 30, 10, 60, 4};
        iso_depth_ddop_params_t fits = {name_of(1), 2.4, -1900, 1000, 30, 10, 60, 4};
        if (iso_depth_pool(&wide, got, sizeof got, &info) == 0 ||
            iso_depth_pool(&fits, small, sizeof small, &info) == 0) {
            fprintf(stderr, "a 30.5 m width or a too small buffer was not refused\n");
            rc = 1;
        }
    }
    if (rc == 0) {
        printf("%s: %d pools identical\n", argv[1], cases);
    }
    return rc;
}
