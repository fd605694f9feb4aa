/* Replay the shared test vectors through the C cores (docs/reference-controllers.md section 3).
 *
 *   replay_vectors [--all] DIR FILE...
 *
 * Each FILE (in DIR) must exist: a missing file is a failure, not a skip. With --all, every
 * other *.csv in DIR is replayed as well. Line 1 is
 * "#params key=value ...", line 2 the column header, then one row per step: the inputs followed
 * by the expected outputs. Every output must match within 1e-9 (absolute), the segment exactly.
 * The file's kind comes from its header; the fertilizer law from a law= or mode= parameter, or
 * else from the file name (fertilizer-<law>.csv). */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "depth_adapter.h"
#include "fertilizer_adapter.h"

#define TOL 1e-9
#define MAX_LINE 4096
#define MAX_COLS 16
#define MAX_REPORTED 10

static const char *FERT_HEADER = "target_gps,measured_gps,has_measurement,new_report,volts,segment";
static const char *DEPTH_HEADER = "target_mm,depth_mm,valid,enabled,speed_mm_s,kp,ki,kd";

static void chomp(char *s)
{
    size_t n = strlen(s);
    while (n > 0 && (s[n - 1] == '\n' || s[n - 1] == '\r' || s[n - 1] == ' ')) {
        s[--n] = '\0';
    }
}

/* A number cell: %.17g text, or True/False for the flags. */
static int parse_cell(const char *text, double *out)
{
    if (strcmp(text, "True") == 0 || strcmp(text, "true") == 0) {
        *out = 1.0;
        return 0;
    }
    if (strcmp(text, "False") == 0 || strcmp(text, "false") == 0) {
        *out = 0.0;
        return 0;
    }
    char *end = NULL;
    *out = strtod(text, &end);
    return end == text || *end != '\0' ? -1 : 0;
}

static int split_row(char *line, double *cells, int want)
{
    int n = 0;
    char *save = line;
    for (;;) {
        char *comma = strchr(save, ',');
        if (comma != NULL) {
            *comma = '\0';
        }
        if (n == want || parse_cell(save, &cells[n]) != 0) {
            return -1;
        }
        n++;
        if (comma == NULL) {
            break;
        }
        save = comma + 1;
    }
    return n == want ? 0 : -1;
}

static bool is_law_key(const char *key)
{
    return param_name_equal(key, "law") || param_name_equal(key, "mode");
}

/* Apply "#params k=v k=v"; returns 0, or -1 after printing the offending key. */
static int apply_params(const char *path, char *line, const param_ref_t *refs, size_t n,
                        bool fertilizer)
{
    char *p = line + strlen("#params");
    char *tok = strtok(p, " \t");
    int rc = 0;
    while (tok != NULL) {
        char *value = param_split(tok);
        if (value == NULL) {
            fprintf(stderr, "%s: line 1: '%s' is not key=value\n", path, tok);
            rc = -1;
        } else if (fertilizer && is_law_key(tok)) {
            /* taken earlier */
        } else {
            param_status_t st = param_set(refs, n, tok, value);
            if (st == PARAM_UNKNOWN) {
                fprintf(stderr, "%s: line 1: unknown parameter '%s' (the C core has no such "
                                "parameter: contract mismatch)\n", path, tok);
                rc = -1;
            } else if (st == PARAM_BAD_VALUE) {
                fprintf(stderr, "%s: line 1: parameter '%s': '%s' is not a number\n", path, tok,
                        value);
                rc = -1;
            }
        }
        tok = strtok(NULL, " \t");
    }
    return rc;
}

/* The fertilizer law: a law=/mode= parameter, else the file name. */
static int find_law(const char *name, const char *params_line, ppid_law_t *law)
{
    char copy[MAX_LINE];
    snprintf(copy, sizeof copy, "%s", params_line + strlen("#params"));
    for (char *tok = strtok(copy, " \t"); tok != NULL; tok = strtok(NULL, " \t")) {
        char *value = param_split(tok);
        if (value != NULL && is_law_key(tok)) {
            return ppid_law_parse(value, law) ? 0 : -1;
        }
    }
    const char *dash = strchr(name, '-');
    char text[64];
    if (dash == NULL) {
        return -1;
    }
    snprintf(text, sizeof text, "%s", dash + 1);
    char *dot = strstr(text, ".csv");
    if (dot != NULL) {
        *dot = '\0';
    }
    return ppid_law_parse(text, law) ? 0 : -1;
}

static int replay(const char *dir, const char *name)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fh = fopen(path, "r");
    if (fh == NULL) {
        fprintf(stderr, "FAIL %s: missing (the Python build writes it: "
                        "python -m reference_controllers.vectors)\n", path);
        return 1;
    }
    static char params_line[MAX_LINE], header[MAX_LINE], line[MAX_LINE];
    if (fgets(params_line, sizeof params_line, fh) == NULL ||
        fgets(header, sizeof header, fh) == NULL) {
        fprintf(stderr, "FAIL %s: fewer than two lines\n", path);
        fclose(fh);
        return 1;
    }
    chomp(params_line);
    chomp(header);
    if (strncmp(params_line, "#params", 7) != 0) {
        fprintf(stderr, "FAIL %s: line 1 is not '#params ...'\n", path);
        fclose(fh);
        return 1;
    }
    bool fert = strcmp(header, FERT_HEADER) == 0;
    bool depth = strcmp(header, DEPTH_HEADER) == 0;
    if (!fert && !depth) {
        fprintf(stderr, "FAIL %s: header '%s' is neither\n  '%s' nor\n  '%s'\n", path, header,
                FERT_HEADER, DEPTH_HEADER);
        fclose(fh);
        return 1;
    }

    fert_config_t fcfg;
    depth_config_t dcfg;
    param_ref_t refs[FERT_PARAM_COUNT + DEPTH_PARAM_COUNT];
    size_t nrefs;
    ppid_law_t law = PPID_LAW_PHYSICAL;
    if (fert) {
        if (find_law(name, params_line, &law) != 0) {
            fprintf(stderr, "FAIL %s: no law (law=/mode= parameter or fertilizer-<law>.csv)\n",
                    path);
            fclose(fh);
            return 1;
        }
        fert_config_defaults(&fcfg, law);
        nrefs = fert_param_refs(&fcfg, refs);
    } else {
        depth_config_defaults(&dcfg);
        nrefs = depth_param_refs(&dcfg, refs);
    }
    if (apply_params(path, params_line, refs, nrefs, fert) != 0) {
        fclose(fh);
        return 1;
    }

    ppid_state_t fs;
    fpid_state_t ds;
    ppid_reset(&fs);
    fpid_reset(&ds);
    int rows = 0, mismatches = 0;
    double worst = 0.0;
    int lineno = 2;
    while (fgets(line, sizeof line, fh) != NULL) {
        lineno++;
        chomp(line);
        if (line[0] == '\0' || line[0] == '#') {
            continue;
        }
        double c[MAX_COLS];
        if (split_row(line, c, fert ? 6 : 8) != 0) {
            fprintf(stderr, "FAIL %s:%d: malformed row\n", path, lineno);
            fclose(fh);
            return 1;
        }
        rows++;
        double got[4], want[4];
        const char *names[4];
        int nout;
        if (fert) {
            ppid_output_t o = ppid_step(&fcfg.core, &fs, c[0], c[1], c[2] != 0.0, c[3] != 0.0);
            got[0] = o.volts;
            want[0] = c[4];
            names[0] = "volts";
            got[1] = o.segment;
            want[1] = c[5];
            names[1] = "segment";
            nout = 2;
        } else {
            fpid_output_t o = fpid_step(&dcfg.core, &ds, c[0], c[1], c[2] != 0.0, c[3] != 0.0);
            double g[4] = {o.speed_mm_s, o.kp, o.ki, o.kd};
            const char *nm[4] = {"speed_mm_s", "kp", "ki", "kd"};
            for (int k = 0; k < 4; k++) {
                got[k] = g[k];
                want[k] = c[4 + k];
                names[k] = nm[k];
            }
            nout = 4;
        }
        for (int k = 0; k < nout; k++) {
            double diff = fabs(got[k] - want[k]);
            bool exact = fert && k == 1;
            if (!(exact ? diff == 0.0 : diff <= TOL)) {
                if (mismatches < MAX_REPORTED) {
                    fprintf(stderr, "%s:%d (step %d): %s = %.17g, vector says %.17g\n", path,
                            lineno, rows - 1, names[k], got[k], want[k]);
                }
                mismatches++;
            }
            if (!exact && diff > worst) {
                worst = diff;
            }
        }
    }
    fclose(fh);
    if (rows == 0) {
        fprintf(stderr, "FAIL %s: no rows\n", path);
        return 1;
    }
    if (mismatches > 0) {
        fprintf(stderr, "FAIL %s: %d mismatches in %d steps (worst %.3g)\n", path, mismatches,
                rows, worst);
        return 1;
    }
    printf("ok   %s: %d steps%s%s, worst difference %.3g\n", path, rows, fert ? ", law " : "",
           fert ? ppid_law_name(law) : "", worst);
    return 0;
}

#define MAX_EXTRA 64

static int by_name(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* Replay the *.csv of dir that are not in required[]; returns the failure count. */
static int replay_others(const char *dir, char **required, int nrequired)
{
    static char names[MAX_EXTRA][256];
    const char *sorted[MAX_EXTRA];
    int n = 0;
    DIR *d = opendir(dir);
    if (d == NULL) {
        return 0; /* the required files already failed */
    }
    struct dirent *e;
    while ((e = readdir(d)) != NULL && n < MAX_EXTRA) {
        size_t len = strlen(e->d_name);
        if (len < 5 || len >= sizeof names[0] || strcmp(e->d_name + len - 4, ".csv") != 0) {
            continue;
        }
        bool listed = false;
        for (int i = 0; i < nrequired; i++) {
            listed = listed || strcmp(required[i], e->d_name) == 0;
        }
        if (!listed) {
            memcpy(names[n], e->d_name, len + 1);
            sorted[n] = names[n];
            n++;
        }
    }
    closedir(d);
    qsort(sorted, (size_t)n, sizeof sorted[0], by_name);
    int failed = 0;
    for (int i = 0; i < n; i++) {
        failed += replay(dir, sorted[i]);
    }
    return failed;
}

int main(int argc, char **argv)
{
    int first = 1;
    bool all = argc > 1 && strcmp(argv[1], "--all") == 0;
    if (all) {
        first = 2;
    }
    if (argc < first + 2) {
        fprintf(stderr, "usage: %s [--all] DIR FILE...\n", argv[0]);
        return 2;
    }
    const char *dir = argv[first];
    int failed = 0;
    for (int i = first + 1; i < argc; i++) {
        failed += replay(dir, argv[i]);
    }
    if (all) {
        failed += replay_others(dir, argv + first + 1, argc - first - 1);
    }
    return failed == 0 ? 0 : 1;
}
