/* replay_isobus FILE...: feed each shared ISOBUS vector (reference_controllers/vectors/
 * isobus-*.frames, written by python -m reference_controllers.vectors.isobus from the Python
 * controller) through the C controller, frame by frame, and require the same frames back, byte
 * for byte, in the same order. Exit 0 when every file matches, 1 on the first mismatch (named
 * by file, line and step), 2 on a file that cannot be read. */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_fert.h"

#define LINE_MAX_LEN 512
#define MAX_EXPECTED (ISO_FERT_MAX_OUT + 8)

static iso_fert_t ctl;

static int hexval(int c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    c = toupper(c);
    return c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

/* "ID#DATA" -> frame; false if malformed */
static bool parse_frame(const char *text, hal_can_frame_t *f)
{
    memset(f, 0, sizeof *f);
    const char *hash = strchr(text, '#');
    if (hash == NULL) {
        return false;
    }
    size_t idlen = (size_t)(hash - text);
    if (idlen != 3 && idlen != 8) {
        return false;
    }
    uint32_t id = 0;
    for (size_t i = 0; i < idlen; i++) {
        int v = hexval(text[i]);
        if (v < 0) {
            return false;
        }
        id = (id << 4) | (uint32_t)v;
    }
    f->id = id;
    f->extended = idlen == 8;
    const char *d = hash + 1;
    size_t n = 0;
    while (d[0] != '\0' && d[0] != '\n' && d[0] != '\r') {
        int hi = hexval(d[0]);
        int lo = d[1] != '\0' ? hexval(d[1]) : -1;
        if (hi < 0 || lo < 0 || n >= 8) {
            return false;
        }
        f->data[n++] = (uint8_t)(hi * 16 + lo);
        d += 2;
    }
    f->len = (uint8_t)n;
    return true;
}

static void frame_text(const hal_can_frame_t *f, char *buf, size_t cap)
{
    int at = snprintf(buf, cap, f->extended ? "%08X#" : "%03X#", (unsigned)f->id);
    for (unsigned i = 0; i < f->len && at > 0 && (size_t)at + 3 < cap; i++) {
        at += snprintf(buf + at, cap - (size_t)at, "%02X", f->data[i]);
    }
}

static bool same(const hal_can_frame_t *a, const hal_can_frame_t *b)
{
    return a->id == b->id && a->extended == b->extended && a->len == b->len &&
           memcmp(a->data, b->data, a->len) == 0;
}

/* #params law=... speed=... ddop=... key=value ... */
static int configure(const char *path, char *line, iso_fert_config_t *cfg)
{
    ppid_law_t law = PPID_LAW_PHYSICAL;
    char copy[LINE_MAX_LEN];
    snprintf(copy, sizeof copy, "%s", line + strlen("#params"));
    char *save = NULL;
    for (char *tok = strtok_r(copy, " \t\n", &save); tok; tok = strtok_r(NULL, " \t\n", &save)) {
        if (strncmp(tok, "law=", 4) == 0 && !ppid_law_parse(tok + 4, &law)) {
            fprintf(stderr, "%s: unknown law '%s'\n", path, tok + 4);
            return 2;
        }
    }
    iso_fert_config_defaults(cfg, law);
    param_ref_t refs[ISO_FERT_PARAM_COUNT];
    size_t n = iso_fert_param_refs(cfg, refs);
    for (char *tok = strtok_r(line + strlen("#params"), " \t\n", &save); tok;
         tok = strtok_r(NULL, " \t\n", &save)) {
        char *value = param_split(tok);
        if (value == NULL) {
            fprintf(stderr, "%s: '%s' is not key=value\n", path, tok);
            return 2;
        }
        if (param_name_equal(tok, "law") || param_name_equal(tok, "mode")) {
            continue;
        }
        if (param_name_equal(tok, "speed")) {
            cfg->speed_wheel = strcmp(value, "wheel") == 0;
            continue;
        }
        if (param_name_equal(tok, "ddop")) {
            cfg->ddop_broken = strcmp(value, "broken") == 0;
            continue;
        }
        if (param_set(refs, n, tok, value) != PARAM_OK) {
            fprintf(stderr, "%s: bad parameter %s=%s\n", path, tok, value);
            return 2;
        }
    }
    const char *why = iso_fert_check(cfg);
    if (why != NULL) {
        fprintf(stderr, "%s: %s\n", path, why);
        return 2;
    }
    return 0;
}

static int replay(const char *path)
{
    FILE *fp = fopen(path, "r");
    if (fp == NULL) {
        fprintf(stderr, "%s: missing\n", path);
        return 2;
    }
    char line[LINE_MAX_LEN];
    iso_fert_config_t cfg;
    bool configured = false;
    /* what the controller produced for the last input, checked against the '>' lines */
    static hal_can_frame_t got[ISO_FERT_MAX_OUT];
    size_t ngot = 0, next = 0;
    long lineno = 0, inputs = 0, outputs = 0;
    long input_line = 0;
    int rc = 0;
    while (rc == 0 && fgets(line, sizeof line, fp) != NULL) {
        lineno++;
        if (strncmp(line, "#params", 7) == 0) {
            rc = configure(path, line, &cfg);
            if (rc == 0 && iso_fert_init(&ctl, &cfg) != 0) {
                fprintf(stderr, "%s:%ld: the pool cannot be written\n", path, lineno);
                rc = 2;
            }
            configured = true;
            got[0] = iso_fert_bootup();
            ngot = 1;
            next = 0;
            continue;
        }
        if (line[0] == '#' || line[0] == '\n') {
            continue;
        }
        hal_can_frame_t f;
        if ((line[0] != '<' && line[0] != '>') || line[1] != ' ' || !parse_frame(line + 2, &f)) {
            fprintf(stderr, "%s:%ld: not '< ID#DATA' or '> ID#DATA': %s", path, lineno, line);
            rc = 2;
            break;
        }
        if (!configured) {
            fprintf(stderr, "%s:%ld: frames before the #params line\n", path, lineno);
            rc = 2;
            break;
        }
        char want[64], have[64];
        if (line[0] == '<') {
            if (next < ngot) {
                frame_text(&got[next], have, sizeof have);
                fprintf(stderr, "%s:%ld (step %u): the C controller also sent %s after the "
                        "input of line %ld, the vector has no more\n", path, lineno,
                        (unsigned)ctl.steps, have, input_line);
                rc = 1;
                break;
            }
            ngot = iso_fert_on_frame(&ctl, &f);
            memcpy(got, ctl.out, ngot * sizeof got[0]);
            next = 0;
            inputs++;
            input_line = lineno;
            continue;
        }
        outputs++;
        frame_text(&f, want, sizeof want);
        if (next >= ngot) {
            fprintf(stderr, "%s:%ld (step %u): the vector has %s, the C controller sent "
                    "nothing more after the input of line %ld\n", path, lineno,
                    (unsigned)ctl.steps, want, input_line);
            rc = 1;
            break;
        }
        if (!same(&got[next], &f)) {
            frame_text(&got[next], have, sizeof have);
            fprintf(stderr, "%s:%ld (step %u): vector %s, C controller %s\n", path, lineno,
                    (unsigned)ctl.steps, want, have);
            rc = 1;
            break;
        }
        next++;
    }
    if (rc == 0 && next < ngot) {
        char have[64];
        frame_text(&got[next], have, sizeof have);
        fprintf(stderr, "%s: at the end the C controller also sent %s\n", path, have);
        rc = 1;
    }
    if (rc == 0 && (!configured || inputs == 0)) {
        fprintf(stderr, "%s: no #params line or no frames\n", path);
        rc = 2;
    }
    fclose(fp);
    if (rc == 0) {
        printf("%s: %ld frames in, %ld frames out, %u steps: identical\n", path, inputs,
               outputs, (unsigned)ctl.steps);
    }
    return rc;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: replay_isobus FILE...\n");
        return 2;
    }
    for (int i = 1; i < argc; i++) {
        int rc = replay(argv[i]);
        if (rc != 0) {
            return rc;
        }
    }
    return 0;
}
