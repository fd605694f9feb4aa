#include "bus_spec.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int fail(char *err, size_t errlen, const char *text, const char *why)
{
    snprintf(err, errlen, "bus spec '%s': %s", text, why);
    return -1;
}

static int copy_text(char *dst, const char *src, size_t n)
{
    if (n == 0 || n >= BUS_SPEC_TEXT) {
        return -1;
    }
    memcpy(dst, src, n);
    dst[n] = '\0';
    return 0;
}

static int valid_name(const char *s, const char *extra)
{
    if (*s == '\0') {
        return 0;
    }
    for (; *s != '\0'; s++) {
        if (!isalnum((unsigned char)*s) && strchr(extra, *s) == NULL) {
            return 0;
        }
    }
    return 1;
}

/* One option key=value (value up to `end`): 0 if fine (or not ours), -1 if ours and bad. */
static int parse_option(const char *key, const char *eq, const char *end, bus_spec_t *out)
{
    static const char name[] = "busy_poll_us";
    if ((size_t)(eq - key) != sizeof name - 1 || strncmp(key, name, sizeof name - 1) != 0) {
        return 0;
    }
    size_t n = (size_t)(end - eq - 1);
    char value[16];
    if (n == 0 || n >= sizeof value) {
        return -1;
    }
    memcpy(value, eq + 1, n);
    value[n] = '\0';
    char *stop = NULL;
    double us = strtod(value, &stop);
    if (*stop != '\0' || !(us >= 0.0 && us <= 1e6)) {
        return -1;
    }
    out->busy_poll_us = (uint32_t)us;
    return 0;
}

int bus_spec_parse(const char *text, bus_spec_t *out, char *err, size_t errlen)
{
    memset(out, 0, sizeof *out);
    if (text == NULL || *text == '\0') {
        snprintf(err, errlen, "empty bus spec; expected socketcan:IFACE or "
                              "socketcand:HOST:PORT[/CHANNEL]");
        return -1;
    }
    /* options after the first ',' must look like key=value; busy_poll_us is read, the rest
     * ignored (bitrate and the like belong to the interface) */
    size_t head_len = strcspn(text, ",");
    for (const char *opt = text + head_len; *opt == ',';) {
        const char *next = opt + 1 + strcspn(opt + 1, ",");
        const char *eq = memchr(opt + 1, '=', (size_t)(next - opt - 1));
        if (eq == NULL || eq == opt + 1) {
            return fail(err, errlen, text, "options must be key=value");
        }
        if (parse_option(opt + 1, eq, next, out) != 0) {
            return fail(err, errlen, text, "busy_poll_us must be a number of microseconds "
                                           "0-1000000");
        }
        opt = next;
    }
    const char *colon = memchr(text, ':', head_len);
    size_t tlen = colon ? (size_t)(colon - text) : head_len;
    const char *rest = colon ? colon + 1 : text + head_len;
    size_t rest_len = head_len - (size_t)(rest - text);
    char transport[32];
    if (tlen == 0 || tlen >= sizeof transport) {
        return fail(err, errlen, text, "no transport name");
    }
    for (size_t i = 0; i < tlen; i++) {
        transport[i] = (char)tolower((unsigned char)text[i]);
    }
    transport[tlen] = '\0';

    if (strcmp(transport, "socketcan") == 0) {
        out->transport = BUS_SOCKETCAN;
        if (copy_text(out->iface, rest, rest_len) != 0) {
            return fail(err, errlen, text, "socketcan needs an interface: socketcan:can0");
        }
        if (!valid_name(out->iface, "_.-") || strlen(out->iface) >= 16) {
            return fail(err, errlen, text, "not a network interface name");
        }
        return 0;
    }
    if (strcmp(transport, "socketcand") == 0) {
        out->transport = BUS_SOCKETCAND;
        /* HOST:PORT[/CHANNEL]; the port is after the last ':' */
        const char *slash = memchr(rest, '/', rest_len);
        size_t addr_len = slash ? (size_t)(slash - rest) : rest_len;
        const char *port_colon = NULL;
        for (size_t i = 0; i < addr_len; i++) {
            if (rest[i] == ':') {
                port_colon = rest + i;
            }
        }
        if (port_colon == NULL) {
            return fail(err, errlen, text, "socketcand needs HOST:PORT, e.g. "
                                           "socketcand:127.0.0.1:29536/can0");
        }
        if (copy_text(out->host, rest, (size_t)(port_colon - rest)) != 0 ||
            !valid_name(out->host, "_.-:")) {
            return fail(err, errlen, text, "bad or missing host");
        }
        char port_text[8];
        size_t plen = addr_len - (size_t)(port_colon + 1 - rest);
        if (plen == 0 || plen >= sizeof port_text) {
            return fail(err, errlen, text, "bad or missing port");
        }
        memcpy(port_text, port_colon + 1, plen);
        port_text[plen] = '\0';
        char *end = NULL;
        long port = strtol(port_text, &end, 10);
        if (*end != '\0' || !isdigit((unsigned char)port_text[0]) || port < 1 || port > 65535) {
            return fail(err, errlen, text, "port must be a number 1-65535");
        }
        out->port = (uint16_t)port;
        if (slash != NULL) {
            size_t clen = rest_len - addr_len - 1;
            if (copy_text(out->channel, slash + 1, clen) != 0 ||
                !valid_name(out->channel, "_.-")) {
                return fail(err, errlen, text, "bad channel name after '/'");
            }
        } else {
            strcpy(out->channel, "can0");
        }
        return 0;
    }
    snprintf(err, errlen, "bus spec '%s': unsupported transport '%s' (the firmware speaks "
                          "socketcan:IFACE and socketcand:HOST:PORT[/CHANNEL])", text, transport);
    return -1;
}
