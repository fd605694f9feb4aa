/* The implement's Task Controller client (ISO 11783-10, version 4), the C twin of
 * hil.isobus.tc_client.TaskControllerClient as the reference controller runs it: same
 * messages, same order, same timeouts, frame for frame (the isobus_vectors ctest).
 *
 * Connection: wait for a TC status (process data command 0xE) and bind to that TC; send the
 * working-set master message (PGN 0xFE0D) and the client task message (every 2 s after,
 * echoing the TC's task-totals bit); request the TC's version (and answer its request);
 * request the language command (PGN 0xFE0F; 2 s, then on without it); request the structure
 * label, and the localization label when it matches: both match -> activate without a
 * transfer; else request the transfer (the pool's size), transfer it (TP), activate.
 * Connected: request value, value and set value commands through on_setpoint (a process data
 * acknowledge with the standard's error bits when refused, always after set-value-and-ack),
 * request value of DDI 0xDFFF (the default set), measurement commands time interval, change
 * threshold, minimum and maximum within threshold (distance interval: "trigger method not
 * supported", the controller has no distance source), and the values they trigger.
 * Losses: no TC status for 6 s -> back to waiting for one; a NACK of process data from the TC
 * (a restart) -> start over with the same TC; an answer not coming within 2 s (the transfer
 * response: 10 s) -> back to waiting for a status; a refused pool (activation error bits, not
 * enough memory, transfer error) -> quiet, for good (the Python's retry() has no caller in
 * the controller).
 *
 * Pure: no I/O, no clock, no allocation; sends through iso_net. */
#ifndef AGRIHIL_ISO_TC_H
#define AGRIHIL_ISO_TC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "iso_ddop.h"
#include "iso_net.h"

#define ISO_PGN_PROCESS_DATA 0xCB00u
#define ISO_PGN_ACKNOWLEDGEMENT 0xE800u
#define ISO_PGN_WORKING_SET_MASTER 0xFE0Du
#define ISO_PGN_LANGUAGE 0xFE0Fu

/* Process data acknowledge error bits */
#define ISO_ACK_COMMAND_NOT_SUPPORTED 0x01u
#define ISO_ACK_INVALID_ELEMENT 0x02u
#define ISO_ACK_DDI_NOT_SUPPORTED 0x04u
#define ISO_ACK_TRIGGER_NOT_SUPPORTED 0x08u
#define ISO_ACK_NOT_SETTABLE 0x10u
#define ISO_ACK_INVALID_INTERVAL 0x20u
#define ISO_ACK_VALUE_NOT_CONFORMING 0x40u
#define ISO_ACK_OUT_OF_RANGE 0x80u

typedef enum {
    TCC_STARTING,
    TCC_WAIT_STATUS,
    TCC_WAIT_VERSION,
    TCC_WAIT_LANGUAGE,
    TCC_WAIT_STRUCTURE_LABEL,
    TCC_WAIT_LOCALIZATION_LABEL,
    TCC_WAIT_TRANSFER_PERMISSION,
    TCC_WAIT_TRANSFER_RESPONSE,
    TCC_WAIT_ACTIVATION,
    TCC_CONNECTED,
    TCC_REFUSED
} tcc_state_t;

typedef struct {
    uint16_t element, ddi;
    bool has_time;
    int32_t time_ms;
    double next_time_s;
    bool has_change, has_min, has_max, has_last;
    int32_t change, minimum, maximum;
    int64_t last_sent;
    bool inside;
} tcc_trigger_t;

/* What the implement does with the TC's commands and what it reports. */
typedef struct {
    void *ctx;
    /* a value command: returns the acknowledge error bits (0: accepted) */
    uint8_t (*on_setpoint)(void *ctx, uint16_t element, uint16_t ddi, int32_t value);
    /* the current raw value; false when the implement has none */
    bool (*read_value)(void *ctx, uint16_t element, uint16_t ddi, int64_t *value);
    /* the pool became active (true) or the connection was lost (false) */
    void (*on_connection)(void *ctx, bool connected);
} tcc_implement_t;

typedef struct {
    iso_net_t *net;
    tcc_implement_t impl;
    const iso_ddop_info_t *pool;
    /* the object pool transfer message: command byte + the pool in the TC's version (written
     * by the caller into transfer[] via the write_pool hook at the first transfer request) */
    int (*write_pool)(void *ctx, unsigned version, uint8_t *buf, size_t cap, size_t *size);
    uint8_t transfer[1 + ISO_DDOP_MAX_BYTES];
    size_t transfer_len; /* 0: not written yet */
    uint8_t version_msg[8];
    tcc_state_t state;
    double state_s;
    bool started;
    double started_s;
    double last_status_s;
    int last_status_from; /* -1: none heard */
    double next_task_s;
    bool task_active;
    /* the connection attempt */
    bool conn;
    uint8_t tc_address;
    bool has_tc_version;
    uint8_t tc_version;
    tcc_trigger_t triggers[ISO_DDOP_MAX_DPD];
    size_t ntriggers;
    /* what happened */
    unsigned connections, transfers;
    bool refused;
    uint8_t refusal_activation_errors, refusal_pool_errors;
    uint16_t refusal_parent, refusal_object;
} tcc_t;

void tcc_init(tcc_t *c, iso_net_t *net, const iso_ddop_info_t *pool, tcc_implement_t impl,
              int (*write_pool)(void *ctx, unsigned version, uint8_t *buf, size_t cap,
                                size_t *size));

/* Whether the pool is active on the TC. */
bool tcc_connected(const tcc_t *c);

/* Advance to now_s (the owner's step): client task, timeouts, triggers. */
void tcc_tick(tcc_t *c, double now_s);

/* A whole group addressed to us or to everyone (iso_net's deliver). Returns true if taken. */
bool tcc_on_group(tcc_t *c, uint32_t pgn, const uint8_t *data, size_t len, uint8_t source,
                  uint8_t destination, double now_s);

#endif
