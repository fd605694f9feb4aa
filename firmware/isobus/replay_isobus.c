/* replay_isobus FILE...: feed each shared ISOBUS vector (reference_controllers/vectors/
 * isobus-*.frames, written by python -m reference_controllers.vectors.isobus from the Python
 * controller) through the C controller, frame by frame, and require the same frames back, byte
 * for byte, in the same order. Exit 0 when every file matches, 1 on the first mismatch (named
 * by file, line and step), 2 on a file that cannot be read. The controller is replay_ctl.h's:
 * replay_fert.c (replay_isobus) or replay_depth.c (replay_isobus_depth, the depth vectors of
 * python -m reference_controllers.vectors.isobus_depth, which also carry 'G' GNSS lines). */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "replay_ctl.h"

#define LINE_MAX_LEN 512

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

static int replay(const char *path)
{
    FILE *fp = fopen(path, "r");
    if (fp == NULL) {
        fprintf(stderr, "%s: missing\n", path);
        return 2;
    }
    char line[LINE_MAX_LEN];
    bool configured = false;
    /* what the controller produced for the last input, checked against the '>' lines */
    static hal_can_frame_t got[REPLAY_MAX_OUT];
    size_t ngot = 0, next = 0;
    long lineno = 0, inputs = 0, outputs = 0;
    long input_line = 0;
    int rc = 0;
    while (rc == 0 && fgets(line, sizeof line, fp) != NULL) {
        lineno++;
        if (strncmp(line, "#params", 7) == 0) {
            rc = replay_configure(path, line + strlen("#params"));
            configured = true;
            got[0] = replay_bootup();
            ngot = 1;
            next = 0;
            continue;
        }
        if (line[0] == '#' || line[0] == '\n') {
            continue;
        }
        if (configured && replay_other(line) == 0) {
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
                        replay_steps(), have, input_line);
                rc = 1;
                break;
            }
            ngot = replay_on_frame(&f);
            memcpy(got, replay_out(), ngot * sizeof got[0]);
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
                    replay_steps(), want, input_line);
            rc = 1;
            break;
        }
        if (!same(&got[next], &f)) {
            frame_text(&got[next], have, sizeof have);
            fprintf(stderr, "%s:%ld (step %u): vector %s, C controller %s\n", path, lineno,
                    replay_steps(), want, have);
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
               outputs, replay_steps());
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
