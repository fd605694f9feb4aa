/* replay_isobus_net's controller (replay_ctl.h): the network layer alone, with the
 * implement's NAME at 0x81, sending the VT pool transfer of `rows` rows (0x11 + iso_vt_pool) to
 * the VT at 0x26 at the steps listed in `sends`; a SYNC (0x080) is a step of 0.1 s and what the
 * network answers between steps goes with the next, as the controller steps it. Its vector,
 * firmware/isobus/data/vt-net-etp.frames, is the Python network's (IsobusNetwork) sending the
 * same bytes (tests/firmware/isobus_vt_vectors.py): ETP sending, byte for byte. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_net.h"
#include "iso_pool.h"
#include "replay_ctl.h"

#define SYNC_ID 0x080u
#define VT_ADDRESS 0x26u
#define ME 0x81u
#define ECU_TO_VT 0xE700u
#define MAX_SENDS 16
#define STEP_S 0.1

_Static_assert(ISO_NET_MAX_OUT <= REPLAY_MAX_OUT, "a step's frames fit the replay");

static iso_net_t net;
static uint8_t payload[1 + ISO_POOL_MAX_BYTES];
static size_t payload_len;
static unsigned sends[MAX_SENDS];
static size_t nsends;
static unsigned steps;
static hal_can_frame_t out[ISO_NET_MAX_OUT];

static void deliver(void *ctx, uint32_t pgn, const uint8_t *data, size_t len, uint8_t source,
                    uint8_t destination, double now_s)
{
    (void)ctx;
    (void)pgn;
    (void)data;
    (void)len;
    (void)source;
    (void)destination;
    (void)now_s;
}

/* rows=N sends=a,b,c */
int replay_configure(const char *path, char *params)
{
    unsigned rows = 0;
    nsends = 0;
    char *save = NULL;
    for (char *tok = strtok_r(params, " \t\n", &save); tok; tok = strtok_r(NULL, " \t\n", &save)) {
        if (strncmp(tok, "rows=", 5) == 0) {
            rows = (unsigned)strtoul(tok + 5, NULL, 10);
        } else if (strncmp(tok, "sends=", 6) == 0) {
            for (char *s = tok + 6; *s != '\0' && nsends < MAX_SENDS;) {
                char *end = NULL;
                sends[nsends++] = (unsigned)strtoul(s, &end, 10);
                s = *end == ',' ? end + 1 : end;
            }
        } else {
            fprintf(stderr, "%s: unknown parameter '%s'\n", path, tok);
            return 2;
        }
    }
    size_t size = 0;
    if (iso_vt_pool(rows, false, payload + 1, sizeof payload - 1, &size) != 0) {
        fprintf(stderr, "%s: no pool of %u rows\n", path, rows);
        return 2;
    }
    payload[0] = 0x11;
    payload_len = size + 1;
    /* the implement's NAME (iso_fert.c implement_name(0x0F27)) */
    uint64_t name = 0x0F27u | ((uint64_t)128 << 40) | ((uint64_t)5 << 49) | ((uint64_t)2 << 60) |
                    ((uint64_t)1 << 63);
    iso_net_init(&net, name, ME, deliver, NULL);
    steps = 0;
    return 0;
}

hal_can_frame_t replay_bootup(void)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x710;
    f.len = 1;
    return f;
}

size_t replay_on_frame(const hal_can_frame_t *frame)
{
    double now = (double)steps * STEP_S;
    if (!frame->extended && frame->id == SYNC_ID) {
        iso_net_poll(&net, now);
        for (size_t i = 0; i < nsends; i++) {
            if (sends[i] == steps) { /* sent after the poll, as the VT client's tick sends */
                iso_net_send(&net, ECU_TO_VT, payload, payload_len, VT_ADDRESS, 5);
            }
        }
        size_t n = net.nout;
        memcpy(out, net.out, n * sizeof out[0]);
        net.nout = 0;
        steps++;
        return n;
    }
    /* stamped with the last step's time; the answer waits for the next step */
    iso_net_on_frame(&net, frame, steps > 0 ? (double)(steps - 1) * STEP_S : 0.0);
    return 0;
}

const hal_can_frame_t *replay_out(void)
{
    return out;
}

int replay_other(const char *line)
{
    (void)line;
    return -1;
}

unsigned replay_steps(void)
{
    return steps;
}
