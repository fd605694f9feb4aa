/* One ISOBUS control function on the bus, the implement's side of ISO 11783-5 and -3: address
 * claim, the address table, single-frame and TP (RTS/CTS) sending. The C twin of what
 * hil.isobus.network.IsobusNetwork, hil.isobus.address_claim and hil.isobus.transport do for
 * the reference controller's one internal control function (reference_controllers/fertilizer/
 * isobus_mode.py), frame for frame.
 *
 * Pure: no I/O, no clock, no allocation. The owner hands it frames (iso_net_on_frame) and the
 * run time (iso_net_poll); frames to send collect in the outbox (out[], nout), which the owner
 * empties. Whole parameter groups addressed to the function (or to everyone) go to the
 * deliver callback.
 *
 * Address claim (ISO 11783-5): the preferred address is claimed at the first poll; nothing
 * else is sent for 250 ms (what is sent meanwhile waits in a queue of ISO_NET_QUEUE groups);
 * a claim of the same address by a lower NAME is lost: a self-configurable NAME moves to the
 * first address of 128-247 that no claim in the table holds, else it sends cannot-claim
 * (source 0xFE); a higher NAME is answered with the claim again; a request for the
 * address-claimed PGN to everyone or to the function repeats its claim. As the Python, no
 * pseudo-random delay before a cannot-claim and no commanded address.
 *
 * Transport (ISO 11783-3), sending: groups of 9 .. 1785 bytes to one address go by TP RTS/CTS
 * (RTS with "no limit" 0xFF packets per CTS; every packet a CTS asks for at once; T3 = 1.25 s
 * for the next CTS or the end-of-message acknowledgement, T4 = 1.05 s after a hold; a timeout
 * aborts with reason 3; a CTS beyond the message aborts with 250, a third retransmission
 * request with 5). Beyond 1785 bytes, ETP (ISO 11783-3 clause 5.11: ETP RTS, for each ETP CTS
 * a DPO and its packets numbered from the DPO's offset, ETP EOMA; an ETP CTS for another PGN:
 * abort 14, beyond the message: abort 15). Up to ISO_NET_TP_SENDERS sessions at once, each to
 * another peer (the TC's DDOP and the VT's pool may go at the same time); a second long group
 * to the same peer waits for the first (ISO_NET_TP_QUEUE). Not implemented (the controller
 * sends none): BAM.
 *
 * Receiving: TP RTS/CTS (at most 16 packets per CTS, or the RTS's limit; T2 = 1.25 s for the
 * first packet after a CTS, T1 = 0.75 s between packets; out of order: abort 7, a repeat: 8,
 * outside the window: 6, a bad RTS: 250; end-of-message acknowledgement, then the group is
 * delivered) and BAM (T1; a packet out of order drops it), ISO_NET_RX_SESSIONS at once. Where
 * the Python (16 peer sessions, ETP up to 117 MB) has room and this has not, it differs: a TP
 * RTS beyond ISO_NET_RX_SESSIONS open sessions is aborted with reason 1 (the Python: beyond
 * 16), an ETP RTS is aborted with reason 2 (resources), a BAM without a free session is not
 * heard. */
#ifndef AGRIHIL_ISO_NET_H
#define AGRIHIL_ISO_NET_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal_can.h"

#define ISO_GLOBAL 0xFFu
#define ISO_NULL 0xFEu
#define ISO_NO_ADDRESS (-1)
#define ISO_TP_MAX_BYTES 1785u
#define ISO_ETP_MAX_BYTES 117440505u
#define ISO_NET_MAX_OUT 320 /* frames one call can produce: a CTS window of 255 packets + more */
#define ISO_NET_QUEUE 16    /* groups held while the claim settles */
#define ISO_NET_TP_QUEUE 2  /* long groups waiting for the TP session to the same peer */
#define ISO_NET_TP_SENDERS 2 /* TP sends at once, each to another peer (a TC's, a VT's) */
#define ISO_NET_RX_SESSIONS 4 /* TP and BAM groups being received at once */

#define ISO_PGN_REQUEST 0xEA00u
#define ISO_PGN_ADDRESS_CLAIMED 0xEE00u
#define ISO_PGN_TP_CM 0xEC00u
#define ISO_PGN_TP_DT 0xEB00u
#define ISO_PGN_ETP_CM 0xC800u
#define ISO_PGN_ETP_DT 0xC700u

typedef void (*iso_deliver_fn)(void *ctx, uint32_t pgn, const uint8_t *data, size_t len,
                               uint8_t source, uint8_t destination, double now_s);

typedef struct {
    uint32_t pgn;
    uint8_t destination;
    uint8_t priority;
    uint8_t len;          /* <= 8: data[]; otherwise the group is `big` */
    uint8_t data[8];
    const uint8_t *big;   /* a long group (the caller keeps it alive until sent) */
    uint32_t big_len;
} iso_group_t;

typedef enum { TP_IDLE, TP_WAIT_CTS, TP_WAIT_EOMA, TP_HELD } iso_tp_wait_t;

typedef struct {
    bool open;
    bool etp;             /* beyond ISO_TP_MAX_BYTES: ETP (RTS, CTS, DPO, data, EOMA) */
    uint32_t pgn;
    uint8_t source, destination, priority;
    const uint8_t *data;
    uint32_t size;
    uint32_t total;       /* packets */
    uint32_t next_packet; /* highest packet sent + 1 */
    uint8_t retransmits;
    iso_tp_wait_t waiting;
    double deadline;
    uint32_t order; /* when it started: timeouts are checked in start order, as the Python */
} iso_tp_sender_t;

typedef struct {
    bool open;
    bool bam;
    uint32_t pgn;
    uint8_t source, destination;
    uint16_t size, total;
    uint16_t next_packet;    /* next packet number expected */
    uint16_t window_end;     /* last packet of the current CTS window */
    uint16_t window_packets; /* packets one CTS asks for */
    double deadline;
    uint8_t data[ISO_TP_MAX_BYTES + 7];
} iso_tp_receiver_t;

typedef struct {
    /* who we are */
    uint64_t name;
    uint8_t preferred;
    bool self_configurable;
    /* the claim: current address (ISO_NO_ADDRESS before start, ISO_NULL after cannot-claim) */
    int current;
    bool settled;
    double settle_at;
    bool started;
    /* the address table (claims heard, ours included) */
    uint64_t table_name[256];
    bool table_used[256];
    /* sending */
    iso_group_t queue[ISO_NET_QUEUE];
    size_t nqueue;
    uint32_t dropped; /* groups lost to a full queue (not expected: a count for the logs) */
    iso_tp_sender_t tp[ISO_NET_TP_SENDERS];
    uint32_t tp_started;
    iso_group_t tp_queue[ISO_NET_TP_QUEUE];
    size_t ntp_queue;
    iso_tp_receiver_t rx[ISO_NET_RX_SESSIONS];
    /* the outbox */
    hal_can_frame_t out[ISO_NET_MAX_OUT];
    size_t nout;
    double now;
    iso_deliver_fn deliver;
    void *ctx;
} iso_net_t;

void iso_net_init(iso_net_t *n, uint64_t name, uint8_t preferred, iso_deliver_fn deliver,
                  void *ctx);

/* The claimed address once the 250 ms passed, else ISO_NO_ADDRESS. */
int iso_net_address(const iso_net_t *n);

/* Send a parameter group (single frame up to 8 bytes, else TP; `big` must stay valid). Held
 * until the claim settles. */
void iso_net_send(iso_net_t *n, uint32_t pgn, const uint8_t *data, size_t len,
                  uint8_t destination, uint8_t priority);

/* Advance to now_s: start the claim, settle it, send what waited, time out TP. */
void iso_net_poll(iso_net_t *n, double now_s);

/* Whether a TP session is open (either way) or a long group waits for one (the Python
 * TransportLayer.busy(): a VT client sends its next pool transfer only when it is not). */
bool iso_net_busy(const iso_net_t *n);

/* Take one extended frame from the bus, stamped now_s. */
void iso_net_on_frame(iso_net_t *n, const hal_can_frame_t *frame, double now_s);

/* The 29-bit identifier of (priority, PGN, source, destination). */
uint32_t iso_can_id(uint8_t priority, uint32_t pgn, uint8_t source, uint8_t destination);

#endif
