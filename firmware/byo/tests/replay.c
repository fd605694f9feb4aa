#include "replay.h"

#include <stdbool.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    hal_can_frame_t frames[REPLAY_MAX_OUT];
    size_t n;    /* what the adapter sent in answer to the last event */
    size_t next; /* how many of them the file's out lines matched so far */
    long line;   /* the event's line */
} pending_t;

static int parse_frame(const char *text, hal_can_frame_t *f)
{
    unsigned long id;
    char kind;
    char hex[40];
    if (sscanf(text, "%lx %c %39s", &id, &kind, hex) != 3 || (kind != 's' && kind != 'x')) {
        if (sscanf(text, "%lx %c", &id, &kind) != 2 || (kind != 's' && kind != 'x')) {
            return -1;
        }
        hex[0] = '\0'; /* no data */
    }
    size_t len = strlen(hex);
    if (len % 2 != 0 || len > 16) {
        return -1;
    }
    memset(f, 0, sizeof *f);
    f->id = (uint32_t)id;
    f->extended = kind == 'x';
    f->len = (uint8_t)(len / 2);
    for (size_t i = 0; i < f->len; i++) {
        unsigned byte;
        if (sscanf(hex + 2 * i, "%2x", &byte) != 1) {
            return -1;
        }
        f->data[i] = (uint8_t)byte;
    }
    return 0;
}

static void format_frame(const hal_can_frame_t *f, char *buf, size_t size)
{
    int used = snprintf(buf, size, "%x %c ", (unsigned)f->id, f->extended ? 'x' : 's');
    for (size_t i = 0; i < f->len && used > 0 && (size_t)used + 3 < size; i++) {
        used += snprintf(buf + used, size - (size_t)used, "%02x", f->data[i]);
    }
}

/* The answers of the last event not matched by an out line: a difference. */
static int check_done(const char *path, const pending_t *p)
{
    if (p->next == p->n) {
        return 0;
    }
    char got[64];
    format_frame(&p->frames[p->next], got, sizeof got);
    fprintf(stderr, "%s:%ld: the C build sent %zu frame(s), the Python build %zu; first extra: %s\n",
            path, p->line, p->n, p->next, got);
    return 1;
}

/* One out line against the next frame the adapter sent. */
static int check_out(const char *path, long line, const char *text, pending_t *p)
{
    hal_can_frame_t f;
    if (parse_frame(text, &f) != 0) {
        fprintf(stderr, "%s:%ld: not a frame: out %s", path, line, text);
        return 1;
    }
    if (p->next >= p->n) {
        fprintf(stderr, "%s:%ld: the Python build sent %s", path, line, text);
        fprintf(stderr, "%s:%ld: the C build sent only %zu frame(s) here\n", path, p->line, p->n);
        return 1;
    }
    const hal_can_frame_t *g = &p->frames[p->next++];
    if (g->id != f.id || g->extended != f.extended || g->len != f.len ||
        memcmp(g->data, f.data, f.len) != 0) {
        char got[64];
        format_frame(g, got, sizeof got);
        fprintf(stderr, "%s:%ld: the C build sent %s, the Python build %s", path, line, got,
                text);
        return 1;
    }
    return 0;
}

static int replay(const char *path, const replay_ops_t *ops)
{
    FILE *in = fopen(path, "r");
    if (in == NULL) {
        fprintf(stderr, "%s: missing or unreadable\n", path);
        return 1;
    }
    ops->reset();
    static pending_t p;
    p = (pending_t){.n = 0, .next = 0, .line = 0};
    char text[256];
    long line = 0, steps = 0, frames = 0;
    int failed = 0;
    while (!failed && fgets(text, sizeof text, in) != NULL) {
        line++;
        hal_can_frame_t f;
        if (text[0] == '#' || text[0] == '\n') {
            continue;
        } else if (strncmp(text, "params ", 7) == 0) {
            failed = ops->params(path, line, text + 7);
        } else if (strncmp(text, "out ", 4) == 0) {
            failed = check_out(path, line, text + 4, &p);
            frames += !failed;
        } else {
            failed = check_done(path, &p);
            p = (pending_t){.n = 0, .next = 0, .line = line};
            if (failed) {
                break;
            } else if (strcmp(text, "boot\n") == 0) {
                p.n = ops->boot(p.frames);
            } else if (strcmp(text, "step\n") == 0) {
                p.n = ops->step(p.frames);
                steps++;
            } else if (strncmp(text, "in ", 3) == 0 && parse_frame(text + 3, &f) == 0) {
                p.n = ops->on_frame(&f, p.frames);
            } else {
                fprintf(stderr, "%s:%ld: not an event: %s", path, line, text);
                failed = 1;
            }
        }
    }
    failed = failed || check_done(path, &p);
    fclose(in);
    if (!failed && steps == 0) {
        fprintf(stderr, "%s: no step in the file\n", path);
        failed = 1;
    }
    if (!failed) {
        printf("%s: %ld steps, %ld frames equal\n", path, steps, frames);
    }
    return failed;
}

int replay_main(int argc, char **argv, const replay_ops_t *ops)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s FILE...\n", ops->program);
        return 2;
    }
    int failed = 0;
    for (int i = 1; i < argc; i++) {
        failed |= replay(argv[i], ops);
    }
    return failed;
}
