#include "socketcand_proto.h"

#include <ctype.h>
#include <stdio.h>
#include <string.h>

static void drop(char *buf, size_t *len, size_t n)
{
    memmove(buf, buf + n, *len - n);
    *len -= n;
}

int scd_next_message(char *buf, size_t *len, char *body, size_t cap)
{
    char *open = memchr(buf, '<', *len);
    if (open == NULL) {
        *len = 0; /* nothing but noise between messages */
        return 0;
    }
    drop(buf, len, (size_t)(open - buf));
    char *close = memchr(buf, '>', *len);
    if (close == NULL) {
        if (*len > SCD_MAX_MESSAGE) {
            *len = 0;
            return -1;
        }
        return 0;
    }
    const char *start = buf + 1;
    const char *end = close;
    while (start < end && isspace((unsigned char)*start)) {
        start++;
    }
    while (end > start && isspace((unsigned char)end[-1])) {
        end--;
    }
    size_t n = (size_t)(end - start);
    size_t consumed = (size_t)(close - buf) + 1;
    if (n >= cap) {
        drop(buf, len, consumed);
        return -1;
    }
    memcpy(body, start, n);
    body[n] = '\0';
    drop(buf, len, consumed);
    return 1;
}

static int hex_value(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    c = (char)tolower((unsigned char)c);
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    return -1;
}

/* Next whitespace-separated token of *p: sets *tok and *tok_len, advances *p. 0 if none. */
static int next_token(const char **p, const char **tok, size_t *tok_len)
{
    const char *s = *p;
    while (*s != '\0' && isspace((unsigned char)*s)) {
        s++;
    }
    if (*s == '\0') {
        *p = s;
        return 0;
    }
    const char *e = s;
    while (*e != '\0' && !isspace((unsigned char)*e)) {
        e++;
    }
    *tok = s;
    *tok_len = (size_t)(e - s);
    *p = e;
    return 1;
}

int scd_parse_frame(const char *body, hal_can_frame_t *frame)
{
    const char *p = body;
    const char *tok;
    size_t n;
    if (!next_token(&p, &tok, &n) || n != 5 || strncmp(tok, "frame", 5) != 0) {
        return 0;
    }
    /* identifier */
    if (!next_token(&p, &tok, &n) || n > 8) {
        return -1;
    }
    uint32_t id = 0;
    for (size_t i = 0; i < n; i++) {
        int v = hex_value(tok[i]);
        if (v < 0) {
            return -1;
        }
        id = (id << 4) | (uint32_t)v;
    }
    bool extended = n > 3 || id > 0x7FFu;
    if (id > 0x1FFFFFFFu) {
        return -1;
    }
    /* timestamp SEC.USEC: checked for shape, not used (the firmware stamps frames itself) */
    if (!next_token(&p, &tok, &n)) {
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        if (!isdigit((unsigned char)tok[i]) && tok[i] != '.') {
            return -1;
        }
    }
    /* data: the rest, hex digits, spaces between bytes allowed */
    uint8_t len = 0;
    int high = -1;
    for (; *p != '\0'; p++) {
        if (isspace((unsigned char)*p)) {
            if (high >= 0) {
                return -1; /* odd digit count inside a byte */
            }
            continue;
        }
        int v = hex_value(*p);
        if (v < 0) {
            return -1;
        }
        if (high < 0) {
            high = v;
        } else {
            if (len == 8) {
                return -1;
            }
            frame->data[len++] = (uint8_t)((high << 4) | v);
            high = -1;
        }
    }
    if (high >= 0) {
        return -1;
    }
    frame->id = id;
    frame->extended = extended;
    frame->len = len;
    return 1;
}

int scd_format_send(const hal_can_frame_t *frame, char *out, size_t cap)
{
    if (frame->len > 8 || frame->id > (frame->extended ? 0x1FFFFFFFu : 0x7FFu)) {
        return -1;
    }
    int n = frame->extended ? snprintf(out, cap, "< send %08X %u", (unsigned)frame->id,
                                       (unsigned)frame->len)
                            : snprintf(out, cap, "< send %03X %u", (unsigned)frame->id,
                                       (unsigned)frame->len);
    if (n < 0 || (size_t)n >= cap) {
        return -1;
    }
    size_t used = (size_t)n;
    for (uint8_t i = 0; i < frame->len; i++) {
        n = snprintf(out + used, cap - used, " %02X", (unsigned)frame->data[i]);
        if (n < 0 || (size_t)n >= cap - used) {
            return -1;
        }
        used += (size_t)n;
    }
    n = snprintf(out + used, cap - used, " >");
    if (n < 0 || (size_t)n >= cap - used) {
        return -1;
    }
    return (int)(used + (size_t)n);
}
