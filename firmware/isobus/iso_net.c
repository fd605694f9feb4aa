#include "iso_net.h"

#include <math.h>
#include <string.h>

#define CLAIM_WAIT_S 0.25
#define CLAIM_PRIORITY 6u
#define SELF_CONFIG_FIRST 128
#define SELF_CONFIG_LAST 247
#define TP_PRIORITY 7u
#define TP_T3_S 1.25
#define TP_T4_S 1.05
#define TP_MAX_RETRANSMITS 2
#define TP_T1_S 0.75
#define TP_T2_S 1.25
#define TP_CTS_PACKETS 16

enum { CM_RTS = 16, CM_CTS = 17, CM_EOMA = 19, CM_BAM = 32, CM_ETP_RTS = 20, CM_ETP_CTS = 21,
       CM_ETP_DPO = 22, CM_ETP_EOMA = 23, CM_ABORT = 255 };
enum { ABORT_ALREADY_IN_SESSION = 1, ABORT_RESOURCES = 2, ABORT_TIMEOUT = 3,
       ABORT_MAX_RETRANSMIT = 5, ABORT_UNEXPECTED_DATA = 6, ABORT_BAD_SEQUENCE = 7,
       ABORT_DUPLICATE_SEQUENCE = 8, ABORT_CTS_PGN = 14, ABORT_CTS_EXCEEDS_SIZE = 15,
       ABORT_OTHER = 250 };

uint32_t iso_can_id(uint8_t priority, uint32_t pgn, uint8_t source, uint8_t destination)
{
    uint32_t pf = (pgn >> 8) & 0xFFu;
    uint32_t ps = pf < 240 ? destination : (pgn & 0xFFu);
    return ((uint32_t)priority << 26) | ((pgn & 0x3FF00u) << 8) | (ps << 8) | source;
}

void iso_net_init(iso_net_t *n, uint64_t name, uint8_t preferred, iso_deliver_fn deliver,
                  void *ctx)
{
    memset(n, 0, sizeof *n);
    n->name = name;
    n->preferred = preferred;
    n->self_configurable = (name >> 63) != 0;
    n->current = ISO_NO_ADDRESS;
    n->settle_at = INFINITY;
    n->deliver = deliver;
    n->ctx = ctx;
}

int iso_net_address(const iso_net_t *n)
{
    if (n->settled && n->current != ISO_NO_ADDRESS && n->current != (int)ISO_NULL) {
        return n->current;
    }
    return ISO_NO_ADDRESS;
}

/* --- the address table --------------------------------------------------------------------- */

static void table_on_claim(iso_net_t *n, uint8_t source, uint64_t name)
{
    for (unsigned a = 0; a < 256; a++) {
        if (n->table_used[a] && n->table_name[a] == name && a != source) {
            n->table_used[a] = false; /* the NAME moved */
        }
    }
    if (source == ISO_NULL) {
        return;
    }
    if (n->table_used[source] && n->table_name[source] < name) {
        return; /* the lower NAME keeps the address */
    }
    n->table_used[source] = true;
    n->table_name[source] = name;
}

/* --- frames out ------------------------------------------------------------------------------ */

static void emit(iso_net_t *n, uint8_t priority, uint32_t pgn, uint8_t source,
                 uint8_t destination, const uint8_t *data, size_t len)
{
    if (n->nout >= ISO_NET_MAX_OUT) {
        n->dropped++;
        return;
    }
    hal_can_frame_t *f = &n->out[n->nout++];
    memset(f, 0, sizeof *f);
    f->id = iso_can_id(priority, pgn, source, destination);
    f->extended = true;
    f->len = (uint8_t)len;
    memcpy(f->data, data, len);
    if (pgn == ISO_PGN_ADDRESS_CLAIMED && len == 8) {
        table_on_claim(n, source, n->name); /* our own claim, as the bus echoes it */
    }
}

static void send_claim(iso_net_t *n, uint8_t source)
{
    uint8_t data[8];
    for (int i = 0; i < 8; i++) {
        data[i] = (uint8_t)(n->name >> (8 * i));
    }
    emit(n, CLAIM_PRIORITY, ISO_PGN_ADDRESS_CLAIMED, source, ISO_GLOBAL, data, 8);
}

static void claim(iso_net_t *n, uint8_t address)
{
    n->current = address;
    n->settled = false;
    n->settle_at = n->now + CLAIM_WAIT_S;
    send_claim(n, address);
}

static bool is_free(const iso_net_t *n, unsigned address)
{
    return !n->table_used[address] || n->table_name[address] == n->name;
}

static void on_claim(iso_net_t *n, uint8_t source, uint64_t name)
{
    if (n->current == ISO_NO_ADDRESS || n->current == (int)ISO_NULL || source != n->current ||
        name == n->name) {
        return;
    }
    if (name > n->name) {
        send_claim(n, source); /* defended */
        return;
    }
    if (n->self_configurable) {
        for (unsigned a = SELF_CONFIG_FIRST; a <= SELF_CONFIG_LAST; a++) {
            if (a != source && is_free(n, a)) {
                claim(n, (uint8_t)a);
                return;
            }
        }
    }
    n->current = ISO_NULL; /* cannot claim */
    n->settled = false;
    n->settle_at = INFINITY;
    send_claim(n, ISO_NULL);
}

/* --- TP sender ------------------------------------------------------------------------------- */

static void tp_cm(iso_net_t *n, const iso_tp_sender_t *s, const uint8_t body[5])
{
    uint8_t data[8] = {body[0], body[1], body[2], body[3], body[4], (uint8_t)(s->pgn & 0xFFu),
                       (uint8_t)((s->pgn >> 8) & 0xFFu), (uint8_t)((s->pgn >> 16) & 0xFFu)};
    emit(n, TP_PRIORITY, s->etp ? ISO_PGN_ETP_CM : ISO_PGN_TP_CM, s->source, s->destination,
         data, 8);
}

/* the open session to `destination`, or NULL */
static iso_tp_sender_t *tp_to(iso_net_t *n, uint8_t destination)
{
    for (size_t i = 0; i < ISO_NET_TP_SENDERS; i++) {
        if (n->tp[i].open && n->tp[i].destination == destination) {
            return &n->tp[i];
        }
    }
    return NULL;
}

static iso_tp_sender_t *tp_free(iso_net_t *n)
{
    for (size_t i = 0; i < ISO_NET_TP_SENDERS; i++) {
        if (!n->tp[i].open) {
            return &n->tp[i];
        }
    }
    return NULL;
}

static void tp_start(iso_net_t *n, iso_tp_sender_t *s, const iso_group_t *g, uint8_t source)
{
    memset(s, 0, sizeof *s);
    s->open = true;
    s->order = n->tp_started++;
    s->pgn = g->pgn;
    s->source = source;
    s->destination = g->destination;
    s->priority = g->priority;
    s->data = g->big;
    s->size = g->big_len;
    s->total = (g->big_len + 6u) / 7u;
    s->next_packet = 1;
    s->etp = g->big_len > ISO_TP_MAX_BYTES;
    if (s->etp) {
        uint8_t rts[5] = {CM_ETP_RTS, (uint8_t)(s->size & 0xFFu), (uint8_t)((s->size >> 8) & 0xFFu),
                          (uint8_t)((s->size >> 16) & 0xFFu), (uint8_t)(s->size >> 24)};
        tp_cm(n, s, rts);
    } else {
        uint8_t rts[5] = {CM_RTS, (uint8_t)(s->size & 0xFFu), (uint8_t)(s->size >> 8),
                          (uint8_t)s->total, 0xFF};
        tp_cm(n, s, rts);
    }
    s->waiting = TP_WAIT_CTS;
    s->deadline = n->now + TP_T3_S;
}

/* Start what waits for a session: the groups to peers with none open, in queue order. */
static void tp_start_waiting(iso_net_t *n, uint8_t source)
{
    size_t i = 0;
    while (i < n->ntp_queue) {
        iso_tp_sender_t *s = tp_free(n);
        if (s == NULL) {
            return;
        }
        if (tp_to(n, n->tp_queue[i].destination) != NULL) {
            i++;
            continue;
        }
        iso_group_t next = n->tp_queue[i];
        memmove(&n->tp_queue[i], &n->tp_queue[i + 1], (n->ntp_queue - i - 1) * sizeof next);
        n->ntp_queue--;
        tp_start(n, s, &next, source);
    }
}

static void tp_end(iso_net_t *n, iso_tp_sender_t *s)
{
    s->open = false;
    tp_start_waiting(n, s->source);
}

static void tp_abort(iso_net_t *n, iso_tp_sender_t *s, uint8_t reason)
{
    uint8_t body[5] = {CM_ABORT, reason, 0xFF, 0xFF, 0xFF};
    tp_cm(n, s, body);
    tp_end(n, s);
}

/* A CTS (TP) or an ETP CTS (next: the packet number, 1-based; the ETP's 24-bit one). */
static void tp_on_cts(iso_net_t *n, iso_tp_sender_t *s, uint8_t packets, uint32_t next,
                      uint32_t pgn)
{
    if (s->etp && pgn != s->pgn) {
        tp_abort(n, s, ABORT_CTS_PGN);
        return;
    }
    if (packets == 0) {
        s->waiting = TP_HELD;
        s->deadline = n->now + TP_T4_S;
        return;
    }
    uint32_t last = next + packets - 1u;
    if (next < 1 || last > s->total) {
        tp_abort(n, s, s->etp ? ABORT_CTS_EXCEEDS_SIZE : ABORT_OTHER);
        return;
    }
    if (next < s->next_packet) {
        s->retransmits++;
        if (s->retransmits > TP_MAX_RETRANSMITS) {
            tp_abort(n, s, ABORT_MAX_RETRANSMIT);
            return;
        }
    }
    uint32_t offset = 0;
    if (s->etp) {
        /* the data packet offset: the packets that follow count from it */
        offset = next - 1u;
        uint8_t dpo[5] = {CM_ETP_DPO, packets, (uint8_t)(offset & 0xFFu),
                          (uint8_t)((offset >> 8) & 0xFFu), (uint8_t)((offset >> 16) & 0xFFu)};
        tp_cm(n, s, dpo);
    }
    for (uint32_t k = next; k <= last; k++) {
        uint8_t data[8];
        memset(data, 0xFF, sizeof data);
        data[0] = (uint8_t)(k - offset);
        size_t at = (size_t)(k - 1u) * 7u;
        size_t take = s->size - at < 7u ? s->size - at : 7u;
        memcpy(data + 1, s->data + at, take);
        emit(n, TP_PRIORITY, s->etp ? ISO_PGN_ETP_DT : ISO_PGN_TP_DT, s->source,
             s->destination, data, 8);
        if (k + 1u > s->next_packet) {
            s->next_packet = k + 1u;
        }
    }
    s->waiting = s->next_packet > s->total ? TP_WAIT_EOMA : TP_WAIT_CTS;
    s->deadline = n->now + TP_T3_S;
}

/* --- TP receiver ----------------------------------------------------------------------------- */

static void cm_from(iso_net_t *n, bool etp, uint8_t from, uint8_t to, uint32_t pgn,
                   const uint8_t body[5])
{
    uint8_t data[8] = {body[0], body[1], body[2], body[3], body[4], (uint8_t)(pgn & 0xFFu),
                       (uint8_t)((pgn >> 8) & 0xFFu), (uint8_t)((pgn >> 16) & 0xFFu)};
    emit(n, TP_PRIORITY, etp ? ISO_PGN_ETP_CM : ISO_PGN_TP_CM, from, to, data, 8);
}

static void rx_abort(iso_net_t *n, iso_tp_receiver_t *r, uint8_t reason)
{
    uint8_t body[5] = {CM_ABORT, reason, 0xFF, 0xFF, 0xFF};
    if (!r->bam) {
        cm_from(n, false, r->destination, r->source, r->pgn, body);
    }
    r->open = false;
}

static iso_tp_receiver_t *rx_find(iso_net_t *n, uint8_t source, uint8_t destination)
{
    for (size_t i = 0; i < ISO_NET_RX_SESSIONS; i++) {
        iso_tp_receiver_t *r = &n->rx[i];
        if (r->open && r->source == source && r->destination == destination) {
            return r;
        }
    }
    return NULL;
}

static void rx_send_cts(iso_net_t *n, iso_tp_receiver_t *r)
{
    unsigned left = (unsigned)r->total - r->next_packet + 1u;
    unsigned count = r->window_packets < left ? r->window_packets : left;
    r->window_end = (uint16_t)(r->next_packet + count - 1u);
    uint8_t body[5] = {CM_CTS, (uint8_t)count, (uint8_t)r->next_packet, 0xFF, 0xFF};
    cm_from(n, false, r->destination, r->source, r->pgn, body);
    r->deadline = n->now + TP_T2_S;
}

static void rx_on_rts(iso_net_t *n, uint8_t control, const uint8_t *d, uint32_t pgn,
                      uint8_t source, uint8_t destination)
{
    bool bam = control == CM_BAM;
    bool etp = control == CM_ETP_RTS;
    if (bam != (destination == ISO_GLOBAL)) {
        return; /* a BAM to one address or an RTS to everyone: no connection */
    }
    uint32_t size = etp ? (uint32_t)d[1] | ((uint32_t)d[2] << 8) | ((uint32_t)d[3] << 16) |
                              ((uint32_t)d[4] << 24)
                        : (uint32_t)d[1] | ((uint32_t)d[2] << 8);
    uint32_t total = (size + 6u) / 7u;
    iso_tp_receiver_t *old = rx_find(n, source, destination);
    if (old != NULL) {
        old->open = false; /* replaced by the new connection */
    }
    uint8_t abort_body[5] = {CM_ABORT, ABORT_OTHER, 0xFF, 0xFF, 0xFF};
    if (etp) {
        if (size > ISO_TP_MAX_BYTES && size <= 117440505u) {
            abort_body[1] = ABORT_RESOURCES; /* no room for ETP here (see iso_net.h) */
        }
        cm_from(n, true, destination, source, pgn, abort_body);
        return;
    }
    if (size < 9 || size > ISO_TP_MAX_BYTES || d[3] != total) {
        if (!bam) {
            cm_from(n, false, destination, source, pgn, abort_body);
        }
        return;
    }
    iso_tp_receiver_t *r = NULL;
    size_t peers = 0;
    for (size_t i = 0; i < ISO_NET_RX_SESSIONS; i++) {
        if (!n->rx[i].open && r == NULL) {
            r = &n->rx[i];
        } else if (n->rx[i].open && !n->rx[i].bam) {
            peers++;
        }
    }
    if (r == NULL) {
        if (!bam) {
            abort_body[1] = ABORT_ALREADY_IN_SESSION;
            cm_from(n, false, destination, source, pgn, abort_body);
        }
        return;
    }
    (void)peers;
    memset(r, 0, sizeof *r);
    r->open = true;
    r->bam = bam;
    r->pgn = pgn;
    r->source = source;
    r->destination = destination;
    r->size = (uint16_t)size;
    r->total = (uint16_t)total;
    r->next_packet = 1;
    if (bam) {
        r->deadline = n->now + TP_T1_S;
        return;
    }
    unsigned limit = d[4] != 0xFF ? d[4] : 255u;
    r->window_packets = (uint16_t)(limit < TP_CTS_PACKETS ? limit : TP_CTS_PACKETS);
    rx_send_cts(n, r);
}

static void rx_on_data(iso_net_t *n, iso_tp_receiver_t *r, const uint8_t *d, size_t len)
{
    unsigned seq = d[0];
    if (r->bam) {
        if (seq != r->next_packet) {
            r->open = false; /* dropped */
            return;
        }
    } else {
        if (r->next_packet > r->window_end) {
            rx_abort(n, r, ABORT_UNEXPECTED_DATA);
            return;
        }
        if (seq < r->next_packet) {
            rx_abort(n, r, ABORT_DUPLICATE_SEQUENCE);
            return;
        }
        if (seq > r->next_packet) {
            rx_abort(n, r, ABORT_BAD_SEQUENCE);
            return;
        }
    }
    size_t at = (size_t)(r->next_packet - 1u) * 7u;
    memset(r->data + at, 0xFF, 7);
    memcpy(r->data + at, d + 1, len - 1 < 7 ? len - 1 : 7);
    r->next_packet++;
    if (r->next_packet > r->total) {
        if (!r->bam) {
            uint8_t body[5] = {CM_EOMA, (uint8_t)(r->size & 0xFFu), (uint8_t)(r->size >> 8),
                               (uint8_t)r->total, 0xFF};
            cm_from(n, false, r->destination, r->source, r->pgn, body);
        }
        r->open = false;
        bool to_us = r->destination == ISO_GLOBAL ||
                     (n->current == r->destination && r->destination != ISO_NULL);
        if (to_us && n->current != r->source) {
            n->deliver(n->ctx, r->pgn, r->data, r->size, r->source, r->destination, n->now);
        }
        return;
    }
    if (!r->bam && r->next_packet > r->window_end) {
        rx_send_cts(n, r);
    } else {
        r->deadline = n->now + TP_T1_S;
    }
}

/* A TP/ETP connection management frame from `source` to `destination` (ours). */
static void tp_on_cm(iso_net_t *n, bool extended, const uint8_t *d, size_t len, uint8_t source,
                     uint8_t destination)
{
    if (len < 8) {
        return; /* malformed: the Python records it and goes on */
    }
    uint8_t c = d[0];
    bool etp = c == CM_ETP_RTS || c == CM_ETP_CTS || c == CM_ETP_DPO || c == CM_ETP_EOMA;
    bool known = etp || c == CM_RTS || c == CM_CTS || c == CM_EOMA || c == CM_BAM ||
                 c == CM_ABORT;
    if (!known || (c != CM_ABORT && etp != extended)) {
        return;
    }
    uint32_t pgn = (uint32_t)d[5] | ((uint32_t)d[6] << 8) | ((uint32_t)d[7] << 16);
    iso_tp_sender_t *s = tp_to(n, source);
    bool mine = s != NULL && s->source == destination;
    iso_tp_receiver_t *theirs = rx_find(n, source, destination);
    switch (c) {
    case CM_RTS:
    case CM_BAM:
    case CM_ETP_RTS:
        /* ISO 11783-5: no control function sends before its claim: a transfer from an
         * address that never claimed is not answered (hil/isobus/transport.py) */
        if (n->table_used[source]) {
            rx_on_rts(n, c, d, pgn, source, destination);
        }
        break;
    case CM_CTS:
        if (mine && !s->etp && pgn == s->pgn) {
            tp_on_cts(n, s, d[1], d[2], pgn);
        }
        break;
    case CM_ETP_CTS:
        if (mine && s->etp) {
            tp_on_cts(n, s, d[1], (uint32_t)d[2] | ((uint32_t)d[3] << 8) | ((uint32_t)d[4] << 16),
                      pgn);
        }
        break;
    case CM_EOMA:
    case CM_ETP_EOMA:
        if (mine && pgn == s->pgn) {
            tp_end(n, s);
        }
        break;
    case CM_ABORT:
        if (mine && pgn == s->pgn) {
            tp_end(n, s);
        }
        if (theirs != NULL && theirs->pgn == pgn && !theirs->bam) {
            theirs->open = false;
        }
        break;
    default:
        break; /* an ETP DPO: no ETP receiving here (see iso_net.h) */
    }
}

static void tp_poll(iso_net_t *n)
{
    /* the sessions open now, in the order they started (a session one of them hands over to
     * is not timed out in this poll) */
    iso_tp_sender_t *open[ISO_NET_TP_SENDERS];
    size_t nopen = 0;
    for (size_t i = 0; i < ISO_NET_TP_SENDERS; i++) {
        if (n->tp[i].open) {
            size_t at = nopen++;
            while (at > 0 && open[at - 1]->order > n->tp[i].order) {
                open[at] = open[at - 1];
                at--;
            }
            open[at] = &n->tp[i];
        }
    }
    for (size_t i = 0; i < nopen; i++) {
        if (open[i]->open && open[i]->deadline <= n->now) {
            tp_abort(n, open[i], ABORT_TIMEOUT);
        }
    }
    for (size_t i = 0; i < ISO_NET_RX_SESSIONS; i++) {
        iso_tp_receiver_t *r = &n->rx[i];
        if (r->open && r->deadline <= n->now) {
            rx_abort(n, r, ABORT_TIMEOUT); /* a BAM is dropped without a word */
        }
    }
}

/* --- sending groups -------------------------------------------------------------------------- */

static void flush(iso_net_t *n)
{
    int source = iso_net_address(n);
    if (source == ISO_NO_ADDRESS || !n->started) {
        return;
    }
    for (size_t i = 0; i < n->nqueue; i++) {
        const iso_group_t *g = &n->queue[i];
        if (g->big == NULL) {
            emit(n, g->priority, g->pgn, (uint8_t)source, g->destination, g->data, g->len);
        } else if (tp_to(n, g->destination) != NULL || tp_free(n) == NULL) {
            if (n->ntp_queue < ISO_NET_TP_QUEUE) {
                n->tp_queue[n->ntp_queue++] = *g;
            } else {
                n->dropped++;
            }
        } else {
            tp_start(n, tp_free(n), g, (uint8_t)source);
        }
    }
    n->nqueue = 0;
}

void iso_net_send(iso_net_t *n, uint32_t pgn, const uint8_t *data, size_t len,
                  uint8_t destination, uint8_t priority)
{
    size_t most = destination == ISO_GLOBAL ? ISO_TP_MAX_BYTES : ISO_ETP_MAX_BYTES;
    if (n->nqueue >= ISO_NET_QUEUE || len > most) {
        n->dropped++;
        return;
    }
    iso_group_t *g = &n->queue[n->nqueue++];
    memset(g, 0, sizeof *g);
    g->pgn = pgn;
    g->destination = destination;
    g->priority = priority;
    if (len <= 8) {
        g->len = (uint8_t)len;
        memcpy(g->data, data, len);
    } else {
        g->big = data;
        g->big_len = (uint32_t)len;
    }
    flush(n);
}

bool iso_net_busy(const iso_net_t *n)
{
    for (size_t i = 0; i < ISO_NET_TP_SENDERS; i++) {
        if (n->tp[i].open) {
            return true;
        }
    }
    for (size_t i = 0; i < ISO_NET_RX_SESSIONS; i++) {
        if (n->rx[i].open) {
            return true;
        }
    }
    return n->ntp_queue > 0;
}

/* --- time and frames in ---------------------------------------------------------------------- */

void iso_net_poll(iso_net_t *n, double now_s)
{
    if (now_s > n->now) {
        n->now = now_s;
    }
    if (!n->started && n->now >= 0.0) {
        n->started = true;
        claim(n, n->preferred);
    }
    if (!n->settled && n->now >= n->settle_at && n->current != ISO_NO_ADDRESS &&
        n->current != (int)ISO_NULL) {
        n->settled = true;
        n->settle_at = INFINITY;
    }
    flush(n);
    tp_poll(n);
}

static bool local(const iso_net_t *n, uint8_t address)
{
    return n->current == address && address != ISO_NULL;
}

void iso_net_on_frame(iso_net_t *n, const hal_can_frame_t *f, double now_s)
{
    if (!f->extended) {
        return;
    }
    if (now_s > n->now) {
        n->now = now_s;
    }
    uint32_t pf = (f->id >> 16) & 0xFFu;
    uint32_t ps = (f->id >> 8) & 0xFFu;
    uint8_t source = (uint8_t)(f->id & 0xFFu);
    uint32_t page = (f->id >> 24) & 0x3u;
    uint32_t pgn;
    uint8_t destination;
    if (pf < 240) {
        pgn = (page << 16) | (pf << 8);
        destination = (uint8_t)ps;
    } else {
        pgn = (page << 16) | (pf << 8) | ps;
        destination = ISO_GLOBAL;
    }
    const uint8_t *d = f->data;
    size_t len = f->len;
    if (source == ISO_GLOBAL ||
        (source == ISO_NULL && pgn != ISO_PGN_ADDRESS_CLAIMED && pgn != ISO_PGN_REQUEST)) {
        return; /* 0xFF is no one's source; from 0xFE only cannot-claim and requests */
    }
    if (pgn == ISO_PGN_ADDRESS_CLAIMED) {
        if (len != 8) {
            return;
        }
        uint64_t name = 0;
        for (int i = 7; i >= 0; i--) {
            name = (name << 8) | d[i];
        }
        table_on_claim(n, source, name);
        on_claim(n, source, name);
        return;
    }
    if (pgn == ISO_PGN_REQUEST && len >= 3 && d[0] == 0x00 && d[1] == 0xEE && d[2] == 0x00) {
        /* ISO 11783-5: a request for the address claimed, to everyone or to us */
        if (n->current != ISO_NO_ADDRESS &&
            (destination == ISO_GLOBAL || destination == n->current)) {
            send_claim(n, (uint8_t)n->current);
        }
    }
    if (pgn == ISO_PGN_TP_CM || pgn == ISO_PGN_TP_DT || pgn == ISO_PGN_ETP_CM ||
        pgn == ISO_PGN_ETP_DT) {
        if (destination != ISO_GLOBAL && !local(n, destination)) {
            return;
        }
        if (pgn == ISO_PGN_TP_CM || pgn == ISO_PGN_ETP_CM) {
            tp_on_cm(n, pgn == ISO_PGN_ETP_CM, d, len, source, destination);
        } else if (pgn == ISO_PGN_TP_DT && len >= 1) {
            iso_tp_receiver_t *r = rx_find(n, source, destination);
            if (r != NULL) {
                rx_on_data(n, r, d, len);
            }
        }
        return;
    }
    if (destination != ISO_GLOBAL && !local(n, destination)) {
        return;
    }
    if (n->current == source) {
        return; /* our own group (or one from our address) */
    }
    n->deliver(n->ctx, pgn, d, len, source, destination, n->now);
}
