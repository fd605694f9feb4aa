/* test_iso_pool FILE: the C VT pool writer against the Python's (firmware/isobus/data/
 * vt-pool.txt, written by python tests/firmware/isobus_vt_vectors.py from
 * reference_controllers.fertilizer.operator_pool.meter_vt_pool): every line's row count (and
 * the bad-pool variant) must give the same bytes. Exit 0 when all match, 1 naming the first
 * difference, 2 on a file that cannot be read. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_pool.h"

#define LINE_LEN (2 * ISO_POOL_MAX_BYTES + 64)

static int hexbyte(const char *s)
{
    unsigned v;
    return sscanf(s, "%2x", &v) == 1 ? (int)v : -1;
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_iso_pool FILE\n");
        return 2;
    }
    FILE *fp = fopen(argv[1], "r");
    if (fp == NULL) {
        fprintf(stderr, "%s: missing\n", argv[1]);
        return 2;
    }
    static char line[LINE_LEN];
    static uint8_t want[ISO_POOL_MAX_BYTES], got[ISO_POOL_MAX_BYTES];
    long lineno = 0;
    int pools = 0;
    int rc = 0;
    while (rc == 0 && fgets(line, sizeof line, fp) != NULL) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n') {
            continue;
        }
        unsigned rows, bad;
        char hex[2 * ISO_POOL_MAX_BYTES + 2];
        if (sscanf(line, "%u %u %4609s", &rows, &bad, hex) != 3) {
            fprintf(stderr, "%s:%ld: not 'rows bad hex'\n", argv[1], lineno);
            rc = 2;
            break;
        }
        size_t nwant = strlen(hex) / 2;
        for (size_t i = 0; i < nwant; i++) {
            int b = hexbyte(hex + 2 * i);
            if (b < 0) {
                fprintf(stderr, "%s:%ld: bad hex at byte %zu\n", argv[1], lineno, i);
                return 2;
            }
            want[i] = (uint8_t)b;
        }
        size_t ngot = 0;
        if (iso_vt_pool(rows, bad != 0, got, sizeof got, &ngot) != 0) {
            fprintf(stderr, "%s:%ld: the C writer refused %u rows\n", argv[1], lineno, rows);
            rc = 1;
            break;
        }
        size_t common = ngot < nwant ? ngot : nwant;
        size_t at = 0;
        while (at < common && got[at] == want[at]) {
            at++;
        }
        if (at < common || ngot != nwant) {
            fprintf(stderr, "%s:%ld: %u rows%s: %zu bytes (Python %zu), first difference at "
                    "byte %zu\n", argv[1], lineno, rows, bad ? " (bad font)" : "", ngot, nwant,
                    at);
            rc = 1;
            break;
        }
        pools++;
    }
    fclose(fp);
    if (rc == 0 && pools == 0) {
        fprintf(stderr, "%s: no pools\n", argv[1]);
        rc = 2;
    }
    if (rc == 0) {
        uint8_t small[16];
        size_t n = 0;
        if (iso_vt_pool(0, false, got, sizeof got, &n) == 0 ||
            iso_vt_pool(ISO_POOL_MAX_ROWS + 1, false, got, sizeof got, &n) == 0 ||
            iso_vt_pool(4, false, small, sizeof small, &n) == 0) {
            fprintf(stderr, "the writer took 0 rows, 17 rows or a 16-byte buffer\n");
            rc = 1;
        } else {
            printf("%d pools identical\n", pools);
        }
    }
    return rc;
}
