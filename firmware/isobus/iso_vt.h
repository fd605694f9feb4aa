/* The implement's Virtual Terminal client (ISO 11783-6), the C twin of
 * hil.isobus.vt.client.VtClient as the reference implement runs it
 * (reference_controllers/fertilizer/isobus_vt.py): same messages, same order, same timeouts,
 * frame for frame (the isobus_vt_vectors ctest).
 *
 * Connection: wait for a VT status message (function 0xFE) and bind to that VT; send the
 * working set master message (PGN 0xFE0D) and the working set maintenance message with the
 * initiating bit (then every second, without it); get memory with the pool's size (refused:
 * quiet, for good), get number of soft keys, get text font data, get hardware; with a version
 * label, get versions: when the VT has the label, load version (connected when it loads, else
 * upload); otherwise upload: the object pool transfer (0x11 + the pool, by TP or ETP) once the
 * network has no transfer open or waiting, then end of object pool (refused: the response's
 * error codes and faulty object are kept, quiet for good); with a label, store version;
 * connected.
 * Connected: the implement's commands (change numeric value, change active mask, change string
 * value, hide/show) go one at a time, the next after the VT's response to the one before;
 * soft key and button activations are answered (the response echoes them) and handed to
 * on_key, the VT's change numeric value is answered and handed to on_number, its change
 * string value answered.
 * Losses: no VT status for 3 s, or no answer to a connection step within 3 s: back to waiting
 * for a status (the commands not yet answered go again once connected).
 *
 * Time as the Python's: the client is ticked in the owner's step only when it has something
 * due (vtc_tick checks that itself, as the Python network asks its next_due), so that what it
 * sends falls on the same steps.
 *
 * Pure: no I/O, no clock, no allocation; sends through iso_net. */
#ifndef AGRIHIL_ISO_VT_H
#define AGRIHIL_ISO_VT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "iso_net.h"

#define ISO_PGN_VT_TO_ECU 0xE600u
#define ISO_PGN_ECU_TO_VT 0xE700u
#define ISO_VT_LABEL_LENGTH 7
#define ISO_VT_MAX_TRANSFER 2305 /* 0x11 + a pool of up to 2,304 bytes (by ETP beyond 1,785) */
#define ISO_VT_COMMANDS 32     /* commands waiting for the VT (more are counted, not kept) */
#define ISO_VT_COMMAND_BYTES 40 /* the longest: change string value of 32 characters */

/* VT functions (first data byte) */
#define ISO_VT_SOFT_KEY_ACTIVATION 0x00u
#define ISO_VT_BUTTON_ACTIVATION 0x01u
#define ISO_VT_VT_CHANGE_NUMERIC_VALUE 0x05u
#define ISO_VT_VT_CHANGE_STRING_VALUE 0x08u
#define ISO_VT_OBJECT_POOL_TRANSFER 0x11u
#define ISO_VT_END_OF_OBJECT_POOL 0x12u
#define ISO_VT_HIDE_SHOW 0xA0u
#define ISO_VT_CHANGE_NUMERIC_VALUE 0xA8u
#define ISO_VT_CHANGE_ACTIVE_MASK 0xADu
#define ISO_VT_CHANGE_STRING_VALUE 0xB3u
#define ISO_VT_GET_MEMORY 0xC0u
#define ISO_VT_GET_NUMBER_OF_SOFT_KEYS 0xC2u
#define ISO_VT_GET_TEXT_FONT_DATA 0xC3u
#define ISO_VT_GET_HARDWARE 0xC7u
#define ISO_VT_STORE_VERSION 0xD0u
#define ISO_VT_LOAD_VERSION 0xD1u
#define ISO_VT_GET_VERSIONS 0xDFu
#define ISO_VT_GET_VERSIONS_RESPONSE 0xE0u
#define ISO_VT_STATUS 0xFEu
#define ISO_VT_WORKING_SET_MAINTENANCE 0xFFu

/* key activation codes (byte 2 of a soft key or button activation) */
#define ISO_VT_KEY_RELEASED 0u
#define ISO_VT_KEY_PRESSED 1u
#define ISO_VT_KEY_HELD 2u
#define ISO_VT_KEY_ABORTED 3u

typedef enum {
    VTC_WAIT_STATUS,
    VTC_WAIT_MEMORY,
    VTC_WAIT_SOFT_KEYS,
    VTC_WAIT_FONTS,
    VTC_WAIT_HARDWARE,
    VTC_WAIT_VERSIONS,
    VTC_WAIT_LOAD,
    VTC_UPLOADING,
    VTC_END_OF_POOL,
    VTC_WAIT_END_OF_POOL,
    VTC_WAIT_STORE,
    VTC_CONNECTED,
    VTC_REFUSED
} vtc_state_t;

/* What the implement does with the operator's input (called from vtc_on_group). */
typedef struct {
    void *ctx;
    /* a soft key (button false) or button activation: object, parent, key code, activation */
    void (*on_key)(void *ctx, uint16_t object_id, uint16_t parent_id, uint8_t key_code,
                   uint8_t activation, bool button);
    /* the operator entered a number into an input object */
    void (*on_number)(void *ctx, uint16_t object_id, uint32_t value);
} vtc_implement_t;

typedef struct {
    uint8_t data[ISO_VT_COMMAND_BYTES];
    uint8_t len;
    bool sent;
} vtc_command_t;

typedef struct {
    iso_net_t *net;
    vtc_implement_t impl;
    uint8_t transfer[ISO_VT_MAX_TRANSFER]; /* 0x11 + the pool */
    size_t transfer_len;
    bool has_label;
    uint8_t label[ISO_VT_LABEL_LENGTH];
    uint8_t vt_version; /* reported in the maintenance message (4) */
    vtc_state_t state;
    double state_s;
    int vt; /* the VT's address, -1: none */
    bool has_status;
    double status_s; /* the last VT status heard from it */
    uint16_t vt_data_mask;
    double next_maintenance_s;
    bool transfer_waits; /* the pool transfer is to go once the network is idle */
    bool has_connected_s;
    double connected_s;
    /* the implement's commands, a ring: head is the one sent or to send next */
    vtc_command_t commands[ISO_VT_COMMANDS];
    size_t head, ncommands;
    uint32_t dropped_commands;
    /* what happened */
    bool refused;
    uint8_t refusal_error_codes, refusal_pool_errors;
    uint16_t refusal_parent, refusal_object;
    bool loaded;
    unsigned connections, uploads;
} vtc_t;

/* Set up with the pool (without the 0x11 byte) and its 7-byte version label (NULL: always
 * upload). Returns 0, -1 when the pool does not fit ISO_VT_MAX_TRANSFER. */
int vtc_init(vtc_t *c, iso_net_t *net, const uint8_t *pool, size_t pool_len, const char *label,
             vtc_implement_t impl);

/* Whether the pool is active on the VT. */
bool vtc_connected(const vtc_t *c);

/* Advance to now_s (the owner's step): does something only when the client has something
 * due (maintenance, a timeout, the upload, a command to send). */
void vtc_tick(vtc_t *c, double now_s);

/* A whole group addressed to us or to everyone (iso_net's deliver). Returns true if taken. */
bool vtc_on_group(vtc_t *c, uint32_t pgn, const uint8_t *data, size_t len, uint8_t source,
                  uint8_t destination, double now_s);

/* The implement's commands (queued; sent once connected, one at a time). */
void vtc_change_numeric_value(vtc_t *c, uint16_t object_id, uint32_t value);
void vtc_change_active_mask(vtc_t *c, uint16_t working_set_id, uint16_t mask_id);
void vtc_change_string_value(vtc_t *c, uint16_t object_id, const uint8_t *text, size_t len);
void vtc_hide_show(vtc_t *c, uint16_t object_id, bool show);

/* The no-reconnect defect's hook: forget when the VT status was last heard. */
void vtc_forget_status(vtc_t *c);

#endif
