#include "iso_vt.h"

#include <math.h>
#include <string.h>

#define VT_STATUS_TIMEOUT_S 3.0
#define MAINTENANCE_PERIOD_S 1.0
#define RESPONSE_TIMEOUT_S 3.0
#define UPLOAD_RECHECK_S 0.01 /* the Python client's next_due while uploading */
#define TIME_TOLERANCE_S 1e-9 /* hil.isobus.network: due within this of now is due now */
#define PRIORITY 5u
#define MASTER_PRIORITY 6u
#define ISO_PGN_WORKING_SET_MASTER_VT 0xFE0Du

static unsigned get16(const uint8_t *d, size_t at)
{
    return (unsigned)d[at] | ((unsigned)d[at + 1] << 8);
}

/* little-endian u32 of the bytes there are (Python's int.from_bytes of a slice) */
static uint32_t get32(const uint8_t *d, size_t len, size_t at)
{
    uint32_t v = 0;
    for (size_t i = 0; i < 4 && at + i < len; i++) {
        v |= (uint32_t)d[at + i] << (8 * i);
    }
    return v;
}

static bool waiting(vtc_state_t s)
{
    switch (s) {
    case VTC_WAIT_MEMORY:
    case VTC_WAIT_SOFT_KEYS:
    case VTC_WAIT_FONTS:
    case VTC_WAIT_HARDWARE:
    case VTC_WAIT_VERSIONS:
    case VTC_WAIT_LOAD:
    case VTC_WAIT_END_OF_POOL:
    case VTC_WAIT_STORE:
        return true;
    default:
        return false;
    }
}

static void send(vtc_t *c, const uint8_t *data, size_t len)
{
    iso_net_send(c->net, ISO_PGN_ECU_TO_VT, data, len, (uint8_t)c->vt, PRIORITY);
}

/* a message of up to 8 bytes, padded with 0xFF to 8 */
static void send_padded(vtc_t *c, const uint8_t *data, size_t len)
{
    uint8_t frame[8];
    memset(frame, 0xFF, sizeof frame);
    memcpy(frame, data, len);
    send(c, frame, sizeof frame);
}

static void send_function(vtc_t *c, uint8_t function)
{
    send_padded(c, &function, 1);
}

static void set_state(vtc_t *c, vtc_state_t state, double now_s)
{
    c->state = state;
    c->state_s = now_s;
}

int vtc_init(vtc_t *c, iso_net_t *net, const uint8_t *pool, size_t pool_len, const char *label,
             vtc_implement_t impl)
{
    memset(c, 0, sizeof *c);
    if (pool_len + 1 > ISO_VT_MAX_TRANSFER) {
        return -1;
    }
    c->net = net;
    c->impl = impl;
    c->transfer[0] = ISO_VT_OBJECT_POOL_TRANSFER;
    memcpy(c->transfer + 1, pool, pool_len);
    c->transfer_len = pool_len + 1;
    if (label != NULL) {
        /* padded with spaces (cut) to 7 bytes, as the Python client's */
        c->has_label = true;
        memset(c->label, ' ', sizeof c->label);
        size_t n = strlen(label);
        memcpy(c->label, label, n < sizeof c->label ? n : sizeof c->label);
    }
    c->vt_version = 4;
    c->state = VTC_WAIT_STATUS;
    c->vt = -1;
    c->vt_data_mask = 0xFFFF;
    c->next_maintenance_s = INFINITY;
    return 0;
}

bool vtc_connected(const vtc_t *c)
{
    return c->state == VTC_CONNECTED;
}

void vtc_forget_status(vtc_t *c)
{
    c->has_status = false;
}

/* --- the implement's commands ---------------------------------------------------------------- */

static void command(vtc_t *c, const uint8_t *data, size_t len)
{
    if (c->ncommands >= ISO_VT_COMMANDS || len > ISO_VT_COMMAND_BYTES) {
        c->dropped_commands++;
        return;
    }
    /* a ring, never moved: a command longer than 8 bytes goes by TP straight from its slot */
    vtc_command_t *cmd = &c->commands[(c->head + c->ncommands) % ISO_VT_COMMANDS];
    memset(cmd->data, 0xFF, sizeof cmd->data);
    memcpy(cmd->data, data, len);
    cmd->len = (uint8_t)(len < 8 ? 8 : len); /* padded to 8 */
    cmd->sent = false;
    c->ncommands++;
}

void vtc_change_numeric_value(vtc_t *c, uint16_t object_id, uint32_t value)
{
    uint8_t d[8] = {ISO_VT_CHANGE_NUMERIC_VALUE, (uint8_t)(object_id & 0xFFu),
                    (uint8_t)(object_id >> 8), 0xFF, (uint8_t)(value & 0xFFu),
                    (uint8_t)((value >> 8) & 0xFFu), (uint8_t)((value >> 16) & 0xFFu),
                    (uint8_t)(value >> 24)};
    command(c, d, sizeof d);
}

void vtc_change_active_mask(vtc_t *c, uint16_t working_set_id, uint16_t mask_id)
{
    uint8_t d[5] = {ISO_VT_CHANGE_ACTIVE_MASK, (uint8_t)(working_set_id & 0xFFu),
                    (uint8_t)(working_set_id >> 8), (uint8_t)(mask_id & 0xFFu),
                    (uint8_t)(mask_id >> 8)};
    command(c, d, sizeof d);
}

void vtc_change_string_value(vtc_t *c, uint16_t object_id, const uint8_t *text, size_t len)
{
    uint8_t d[ISO_VT_COMMAND_BYTES];
    if (len + 5 > sizeof d) {
        c->dropped_commands++;
        return;
    }
    d[0] = ISO_VT_CHANGE_STRING_VALUE;
    d[1] = (uint8_t)(object_id & 0xFFu);
    d[2] = (uint8_t)(object_id >> 8);
    d[3] = (uint8_t)(len & 0xFFu);
    d[4] = (uint8_t)(len >> 8);
    memcpy(d + 5, text, len);
    command(c, d, len + 5);
}

void vtc_hide_show(vtc_t *c, uint16_t object_id, bool show)
{
    uint8_t d[4] = {ISO_VT_HIDE_SHOW, (uint8_t)(object_id & 0xFFu), (uint8_t)(object_id >> 8),
                    show ? 1u : 0u};
    command(c, d, sizeof d);
}

/* --- timers ---------------------------------------------------------------------------------- */

static bool head_unsent(const vtc_t *c)
{
    return c->ncommands > 0 && !c->commands[c->head].sent;
}

/* VtClient.next_due */
static double next_due(const vtc_t *c, double now_s)
{
    double due = c->next_maintenance_s;
    if (c->transfer_waits || (c->state == VTC_CONNECTED && head_unsent(c))) {
        due = now_s;
    }
    if (c->has_status) {
        due = fmin(due, c->status_s + VT_STATUS_TIMEOUT_S);
    }
    if (waiting(c->state)) {
        due = fmin(due, c->state_s + RESPONSE_TIMEOUT_S);
    }
    if (c->state == VTC_UPLOADING || c->state == VTC_END_OF_POOL) {
        due = fmin(due, now_s + UPLOAD_RECHECK_S);
    }
    return fmax(due, now_s);
}

static void restart(vtc_t *c, double now_s)
{
    c->vt = -1;
    c->has_status = false;
    c->next_maintenance_s = INFINITY;
    c->transfer_waits = false;
    for (size_t i = 0; i < c->ncommands; i++) {
        c->commands[(c->head + i) % ISO_VT_COMMANDS].sent = false;
    }
    c->has_connected_s = false;
    set_state(c, VTC_WAIT_STATUS, now_s);
}

static void send_maintenance(vtc_t *c, bool initiating)
{
    uint8_t d[3] = {ISO_VT_WORKING_SET_MAINTENANCE, initiating ? 1u : 0u, c->vt_version};
    send_padded(c, d, sizeof d);
}

void vtc_tick(vtc_t *c, double now_s)
{
    if (!(next_due(c, now_s) <= now_s + TIME_TOLERANCE_S)) {
        return; /* nothing due: the Python network does not tick it */
    }
    if (c->has_status && now_s - c->status_s >= VT_STATUS_TIMEOUT_S) {
        restart(c, now_s);
        return;
    }
    if (c->vt < 0) {
        return;
    }
    if (now_s >= c->next_maintenance_s - TIME_TOLERANCE_S) {
        send_maintenance(c, false);
        while (c->next_maintenance_s <= now_s + TIME_TOLERANCE_S) {
            c->next_maintenance_s += MAINTENANCE_PERIOD_S;
        }
    }
    if (waiting(c->state) && now_s - c->state_s >= RESPONSE_TIMEOUT_S) {
        restart(c, now_s);
        return;
    }
    if ((c->state == VTC_UPLOADING || c->state == VTC_END_OF_POOL) && !iso_net_busy(c->net)) {
        if (c->transfer_waits) {
            c->transfer_waits = false;
            c->uploads++;
            send(c, c->transfer, c->transfer_len);
        } else if (c->state == VTC_UPLOADING) {
            c->state = VTC_END_OF_POOL; /* the Python sets the state alone, not its time */
        } else {
            send_function(c, ISO_VT_END_OF_OBJECT_POOL);
            set_state(c, VTC_WAIT_END_OF_POOL, now_s);
        }
    }
    if (c->state == VTC_CONNECTED && head_unsent(c)) {
        vtc_command_t *cmd = &c->commands[c->head];
        cmd->sent = true;
        send(c, cmd->data, cmd->len);
    }
}

/* --- the VT's messages ----------------------------------------------------------------------- */

static void upload(vtc_t *c, double now_s)
{
    c->transfer_waits = true;
    set_state(c, VTC_UPLOADING, now_s);
}

static void connected(vtc_t *c, double now_s)
{
    set_state(c, VTC_CONNECTED, now_s);
    c->has_connected_s = true;
    c->connected_s = now_s;
    c->connections++;
}

static void send_label(vtc_t *c, uint8_t function)
{
    uint8_t d[1 + ISO_VT_LABEL_LENGTH];
    d[0] = function;
    memcpy(d + 1, c->label, ISO_VT_LABEL_LENGTH);
    send(c, d, sizeof d);
}

static void refuse(vtc_t *c, uint8_t codes, uint16_t parent, uint16_t object, uint8_t pool_errors,
                   double now_s)
{
    c->refused = true;
    c->refusal_error_codes = codes;
    c->refusal_parent = parent;
    c->refusal_object = object;
    c->refusal_pool_errors = pool_errors;
    set_state(c, VTC_REFUSED, now_s);
}

static void on_status(vtc_t *c, const uint8_t *d, size_t len, uint8_t source, double t)
{
    if (c->vt < 0 && c->state == VTC_WAIT_STATUS && !c->refused) {
        c->vt = source;
        uint8_t master[1] = {1};
        uint8_t frame[8];
        memset(frame, 0xFF, sizeof frame);
        memcpy(frame, master, sizeof master);
        iso_net_send(c->net, ISO_PGN_WORKING_SET_MASTER_VT, frame, sizeof frame, ISO_GLOBAL,
                     MASTER_PRIORITY);
        send_maintenance(c, true);
        c->next_maintenance_s = t + MAINTENANCE_PERIOD_S;
        uint32_t size = (uint32_t)(c->transfer_len - 1);
        uint8_t memory[6] = {ISO_VT_GET_MEMORY, 0xFF, (uint8_t)(size & 0xFFu),
                             (uint8_t)((size >> 8) & 0xFFu), (uint8_t)((size >> 16) & 0xFFu),
                             (uint8_t)(size >> 24)};
        send_padded(c, memory, sizeof memory);
        set_state(c, VTC_WAIT_MEMORY, t);
    }
    if ((int)source == c->vt) {
        c->has_status = true;
        c->status_s = t;
        if (len >= 4) {
            c->vt_data_mask = (uint16_t)get16(d, 2);
        }
    }
}

static bool has_label(const vtc_t *c, const uint8_t *d, size_t len)
{
    unsigned count = d[1];
    for (unsigned i = 0; i < count; i++) {
        size_t at = 2u + (size_t)ISO_VT_LABEL_LENGTH * i;
        if (at + ISO_VT_LABEL_LENGTH <= len &&
            memcmp(d + at, c->label, ISO_VT_LABEL_LENGTH) == 0) {
            return true;
        }
    }
    return false;
}

/* the bytes each function's handling reads (the Python would fail on fewer) */
static size_t needed(uint8_t function)
{
    switch (function) {
    case ISO_VT_GET_MEMORY:
        return 3;
    case ISO_VT_GET_VERSIONS_RESPONSE:
        return 2;
    case ISO_VT_LOAD_VERSION:
        return 6;
    case ISO_VT_END_OF_OBJECT_POOL:
    case ISO_VT_SOFT_KEY_ACTIVATION:
    case ISO_VT_BUTTON_ACTIVATION:
        return 7;
    case ISO_VT_VT_CHANGE_NUMERIC_VALUE:
        return 3;
    case ISO_VT_VT_CHANGE_STRING_VALUE:
        return 4;
    default:
        return 1;
    }
}

bool vtc_on_group(vtc_t *c, uint32_t pgn, const uint8_t *d, size_t len, uint8_t source,
                  uint8_t destination, double t)
{
    if (pgn != ISO_PGN_VT_TO_ECU) {
        return false;
    }
    if (len == 0) {
        return true;
    }
    uint8_t function = d[0];
    if (function == ISO_VT_STATUS) {
        on_status(c, d, len, source, t);
        return true;
    }
    if ((int)source != c->vt || (int)destination != iso_net_address(c->net) ||
        len < needed(function)) {
        return true;
    }
    vtc_state_t state = c->state;
    if (function == ISO_VT_GET_MEMORY && state == VTC_WAIT_MEMORY) {
        if (d[2] != 0) {
            refuse(c, d[2], 0xFFFF, 0xFFFF, 0, t); /* not enough memory */
            return true;
        }
        send_function(c, ISO_VT_GET_NUMBER_OF_SOFT_KEYS);
        set_state(c, VTC_WAIT_SOFT_KEYS, t);
    } else if (function == ISO_VT_GET_NUMBER_OF_SOFT_KEYS && state == VTC_WAIT_SOFT_KEYS) {
        send_function(c, ISO_VT_GET_TEXT_FONT_DATA);
        set_state(c, VTC_WAIT_FONTS, t);
    } else if (function == ISO_VT_GET_TEXT_FONT_DATA && state == VTC_WAIT_FONTS) {
        send_function(c, ISO_VT_GET_HARDWARE);
        set_state(c, VTC_WAIT_HARDWARE, t);
    } else if (function == ISO_VT_GET_HARDWARE && state == VTC_WAIT_HARDWARE) {
        if (c->has_label) {
            send_function(c, ISO_VT_GET_VERSIONS);
            set_state(c, VTC_WAIT_VERSIONS, t);
        } else {
            upload(c, t);
        }
    } else if (function == ISO_VT_GET_VERSIONS_RESPONSE && state == VTC_WAIT_VERSIONS) {
        if (c->has_label && has_label(c, d, len)) {
            send_label(c, ISO_VT_LOAD_VERSION);
            set_state(c, VTC_WAIT_LOAD, t);
        } else {
            upload(c, t);
        }
    } else if (function == ISO_VT_LOAD_VERSION && state == VTC_WAIT_LOAD) {
        if (d[5] == 0) {
            c->loaded = true;
            connected(c, t);
        } else {
            upload(c, t);
        }
    } else if (function == ISO_VT_END_OF_OBJECT_POOL && state == VTC_WAIT_END_OF_POOL) {
        if (d[1] != 0) {
            refuse(c, d[1], (uint16_t)get16(d, 2), (uint16_t)get16(d, 4), d[6], t);
        } else if (c->has_label) {
            send_label(c, ISO_VT_STORE_VERSION);
            set_state(c, VTC_WAIT_STORE, t);
        } else {
            connected(c, t);
        }
    } else if (function == ISO_VT_STORE_VERSION && state == VTC_WAIT_STORE) {
        connected(c, t);
    } else if (function == ISO_VT_SOFT_KEY_ACTIVATION || function == ISO_VT_BUTTON_ACTIVATION) {
        send_padded(c, d, 7); /* the activation response echoes it */
        if (c->impl.on_key != NULL) {
            c->impl.on_key(c->impl.ctx, (uint16_t)get16(d, 2), (uint16_t)get16(d, 4), d[6],
                           d[1] & 0x03u, function == ISO_VT_BUTTON_ACTIVATION);
        }
    } else if (function == ISO_VT_VT_CHANGE_NUMERIC_VALUE) {
        uint16_t oid = (uint16_t)get16(d, 1);
        uint32_t value = get32(d, len, 4);
        uint8_t r[8] = {function, (uint8_t)(oid & 0xFFu), (uint8_t)(oid >> 8), 0xFF,
                        (uint8_t)(value & 0xFFu), (uint8_t)((value >> 8) & 0xFFu),
                        (uint8_t)((value >> 16) & 0xFFu), (uint8_t)(value >> 24)};
        send(c, r, sizeof r); /* the response echoes it */
        if (c->impl.on_number != NULL) {
            c->impl.on_number(c->impl.ctx, oid, value);
        }
    } else if (function == ISO_VT_VT_CHANGE_STRING_VALUE) {
        uint8_t r[3] = {function, d[1], d[2]};
        send_padded(c, r, sizeof r);
    } else if (c->ncommands > 0 && c->commands[c->head].sent &&
               function == c->commands[c->head].data[0]) {
        c->head = (c->head + 1) % ISO_VT_COMMANDS; /* answered: the next may go */
        c->ncommands--;
    }
    return true;
}
