#include "iso_tc.h"

#include <math.h>
#include <string.h>

#define CLIENT_TASK_PERIOD_S 2.0
#define TC_STATUS_TIMEOUT_S 6.0
#define RESPONSE_TIMEOUT_S 2.0
#define TRANSFER_TIMEOUT_S 10.0
#define LANGUAGE_TIMEOUT_S 2.0
#define PRIORITY_DEFAULT 5u
#define PRIORITY_TRANSFER 7u
#define PRIORITY_ACK 4u
#define MEMBERS 1u

/* process data commands (low nibble of byte 1) */
enum { CMD_TECHNICAL = 0x0, CMD_DEVICE_DESCRIPTOR = 0x1, CMD_REQUEST_VALUE = 0x2,
       CMD_VALUE = 0x3, CMD_TIME_INTERVAL = 0x4, CMD_DISTANCE_INTERVAL = 0x5,
       CMD_MINIMUM = 0x6, CMD_MAXIMUM = 0x7, CMD_CHANGE = 0x8, CMD_SET_AND_ACK = 0xA,
       CMD_ACKNOWLEDGE = 0xD, CMD_STATUS = 0xE, CMD_CLIENT_TASK = 0xF };
/* device descriptor sub-commands (high nibble) */
enum { DD_STRUCTURE_LABEL = 0x1, DD_LOCALIZATION_LABEL = 0x3,
       DD_REQUEST_TRANSFER_RESPONSE = 0x5, DD_TRANSFER = 0x6, DD_TRANSFER_RESPONSE = 0x7,
       DD_ACTIVATE = 0x8, DD_ACTIVATE_RESPONSE = 0x9 };

void tcc_init(tcc_t *c, iso_net_t *net, const iso_ddop_info_t *pool, tcc_implement_t impl,
              int (*write_pool)(void *ctx, unsigned version, uint8_t *buf, size_t cap,
                                size_t *size))
{
    memset(c, 0, sizeof *c);
    c->net = net;
    c->pool = pool;
    c->impl = impl;
    c->write_pool = write_pool;
    c->state = TCC_STARTING;
    c->last_status_s = -INFINITY;
    c->last_status_from = -1;
    c->next_task_s = INFINITY;
    unsigned sections = pool->sections;
    uint8_t options = (uint8_t)(0x01u | (sections ? 0x10u : 0u)); /* documentation, section
                                                                     * control */
    uint8_t v[8] = {0x10, 4, 0xFF, options, 0x00, (uint8_t)(sections ? 1 : 0),
                    (uint8_t)(sections > 255 ? 255 : sections), 0};
    memcpy(c->version_msg, v, sizeof v);
}

bool tcc_connected(const tcc_t *c)
{
    return c->state == TCC_CONNECTED;
}

/* --- sending ----------------------------------------------------------------------------------- */

static void send_pd(tcc_t *c, const uint8_t *data, size_t len, uint8_t priority)
{
    if (!c->conn) {
        return;
    }
    iso_net_send(c->net, ISO_PGN_PROCESS_DATA, data, len, c->tc_address, priority);
}

static void send_simple(tcc_t *c, uint8_t first, uint8_t priority)
{
    uint8_t d[8];
    memset(d, 0xFF, sizeof d);
    d[0] = first;
    send_pd(c, d, sizeof d, priority);
}

static void send_client_task(tcc_t *c)
{
    uint8_t d[8] = {0xFF, 0xFF, 0xFF, 0xFF, (uint8_t)(c->task_active ? 1 : 0), 0, 0, 0};
    send_pd(c, d, sizeof d, PRIORITY_DEFAULT);
}

static void send_working_set_master(tcc_t *c)
{
    uint8_t d[8];
    memset(d, 0xFF, sizeof d);
    d[0] = MEMBERS;
    iso_net_send(c->net, ISO_PGN_WORKING_SET_MASTER, d, sizeof d, ISO_GLOBAL, 7);
}

static void element_head(uint8_t *d, unsigned command, uint16_t element, uint16_t ddi)
{
    d[0] = (uint8_t)((command & 0x0Fu) | ((element & 0x0Fu) << 4));
    d[1] = (uint8_t)(element >> 4);
    d[2] = (uint8_t)(ddi & 0xFFu);
    d[3] = (uint8_t)(ddi >> 8);
}

static void ack(tcc_t *c, uint16_t element, uint16_t ddi, uint8_t errors, unsigned command)
{
    uint8_t d[8];
    element_head(d, CMD_ACKNOWLEDGE, element, ddi);
    d[4] = errors;
    d[5] = (uint8_t)(0xF0u | (command & 0x0Fu));
    d[6] = 0xFF;
    d[7] = 0xFF;
    send_pd(c, d, sizeof d, PRIORITY_ACK);
}

static void send_value(tcc_t *c, uint16_t element, uint16_t ddi, int64_t value)
{
    uint8_t d[8];
    element_head(d, CMD_VALUE, element, ddi);
    uint32_t u = (uint32_t)((uint64_t)value & 0xFFFFFFFFu);
    for (int i = 0; i < 4; i++) {
        d[4 + i] = (uint8_t)(u >> (8 * i));
    }
    send_pd(c, d, sizeof d, PRIORITY_DEFAULT);
}

/* --- state ------------------------------------------------------------------------------------- */

static void set_state(tcc_t *c, tcc_state_t state, double t)
{
    c->state = state;
    c->state_s = t;
}

static void drop_connection(tcc_t *c)
{
    c->conn = false;
    c->ntriggers = 0;
    c->next_task_s = INFINITY;
}

static void lose(tcc_t *c, double t)
{
    bool was = c->state == TCC_CONNECTED;
    drop_connection(c);
    c->task_active = false;
    set_state(c, TCC_WAIT_STATUS, t);
    if (was) {
        c->impl.on_connection(c->impl.ctx, false);
    }
}

static void begin(tcc_t *c, uint8_t tc, double t)
{
    c->conn = true;
    c->tc_address = tc;
    c->has_tc_version = false;
    c->ntriggers = 0;
    send_working_set_master(c);
    send_client_task(c);
    c->next_task_s = t + CLIENT_TASK_PERIOD_S;
    send_simple(c, 0x00, PRIORITY_DEFAULT); /* request version */
    set_state(c, TCC_WAIT_VERSION, t);
}

static void restart(tcc_t *c, double t)
{
    bool had = c->conn;
    uint8_t tc = c->tc_address;
    bool was = c->state == TCC_CONNECTED;
    drop_connection(c);
    set_state(c, TCC_WAIT_STATUS, t);
    if (was) {
        c->impl.on_connection(c->impl.ctx, false);
    }
    if (had && t - c->last_status_s < TC_STATUS_TIMEOUT_S) {
        begin(c, tc, t);
    }
}

static void refuse(tcc_t *c, double t, uint8_t activation, uint16_t parent, uint16_t object,
                   uint8_t pool_errors)
{
    c->refused = true;
    c->refusal_activation_errors = activation;
    c->refusal_parent = parent;
    c->refusal_object = object;
    c->refusal_pool_errors = pool_errors;
    bool was = c->state == TCC_CONNECTED;
    drop_connection(c);
    set_state(c, TCC_REFUSED, t);
    if (was) {
        c->impl.on_connection(c->impl.ctx, false);
    }
}

static void request_structure_label(tcc_t *c, double t)
{
    send_simple(c, 0x01, PRIORITY_DEFAULT);
    set_state(c, TCC_WAIT_STRUCTURE_LABEL, t);
}

static void request_transfer(tcc_t *c, double t)
{
    if (c->transfer_len == 0) {
        /* the pool's bytes in the TC's version when the TC is older than the pool (4);
         * written once, as the Python caches them */
        unsigned version = c->has_tc_version ? c->tc_version : 4u;
        if (!(version > 0 && version < 4)) {
            version = 4;
        }
        size_t size = 0;
        if (c->write_pool(c->impl.ctx, version, c->transfer + 1, sizeof c->transfer - 1,
                          &size) != 0) {
            refuse(c, t, 0, 0xFFFF, 0xFFFF, 0);
            return;
        }
        c->transfer[0] = (uint8_t)(CMD_DEVICE_DESCRIPTOR | (DD_TRANSFER << 4));
        c->transfer_len = size + 1;
    }
    uint8_t d[8] = {0x41, 0, 0, 0, 0, 0xFF, 0xFF, 0xFF};
    uint32_t size = (uint32_t)(c->transfer_len - 1);
    for (int i = 0; i < 4; i++) {
        d[1 + i] = (uint8_t)(size >> (8 * i));
    }
    send_pd(c, d, sizeof d, PRIORITY_DEFAULT);
    set_state(c, TCC_WAIT_TRANSFER_PERMISSION, t);
}

static void activate(tcc_t *c, double t)
{
    uint8_t d[8];
    memset(d, 0xFF, sizeof d);
    d[0] = 0x81;
    send_pd(c, d, sizeof d, PRIORITY_DEFAULT);
    set_state(c, TCC_WAIT_ACTIVATION, t);
}

/* --- timers ------------------------------------------------------------------------------------ */

static double state_timeout(tcc_state_t s)
{
    switch (s) {
    case TCC_WAIT_VERSION:
    case TCC_WAIT_STRUCTURE_LABEL:
    case TCC_WAIT_LOCALIZATION_LABEL:
    case TCC_WAIT_TRANSFER_PERMISSION:
    case TCC_WAIT_ACTIVATION:
        return RESPONSE_TIMEOUT_S;
    case TCC_WAIT_LANGUAGE:
        return LANGUAGE_TIMEOUT_S;
    case TCC_WAIT_TRANSFER_RESPONSE:
        return TRANSFER_TIMEOUT_S;
    default:
        return -1.0;
    }
}

static bool read(tcc_t *c, uint16_t element, uint16_t ddi, int64_t *value)
{
    return c->impl.read_value(c->impl.ctx, element, ddi, value);
}

static void run_triggers(tcc_t *c, double now)
{
    for (size_t i = 0; i < c->ntriggers; i++) {
        tcc_trigger_t *tr = &c->triggers[i];
        bool send = false;
        if (tr->has_time && now >= tr->next_time_s) {
            send = true;
            double step = tr->time_ms / 1000.0;
            while (tr->next_time_s <= now) {
                tr->next_time_s += step;
            }
        }
        int64_t value = 0;
        bool has_value = false;
        if (tr->has_change || tr->has_min || tr->has_max) {
            has_value = read(c, tr->element, tr->ddi, &value);
        }
        if (has_value) {
            if (tr->has_change) {
                int64_t diff = value - tr->last_sent;
                if (!tr->has_last || (diff < 0 ? -diff : diff) >= tr->change) {
                    send = true;
                }
            }
            if (tr->has_min || tr->has_max) {
                bool inside = (!tr->has_min || value > tr->minimum) &&
                              (!tr->has_max || value < tr->maximum);
                if (inside && !tr->inside) {
                    send = true;
                }
                tr->inside = inside;
            }
        }
        if (!send) {
            continue;
        }
        if (!has_value) {
            has_value = read(c, tr->element, tr->ddi, &value);
        }
        if (has_value) {
            send_value(c, tr->element, tr->ddi, value);
            tr->last_sent = value;
            tr->has_last = true;
        }
    }
}

void tcc_tick(tcc_t *c, double now)
{
    if (!c->started) {
        c->started = true;
        c->started_s = now;
    }
    if (iso_net_address(c->net) == ISO_NO_ADDRESS || c->state == TCC_REFUSED) {
        return;
    }
    if (c->state == TCC_STARTING) {
        if (now >= c->started_s) { /* no start-up delay */
            set_state(c, TCC_WAIT_STATUS, now);
            if (c->last_status_from >= 0 && now - c->last_status_s < CLIENT_TASK_PERIOD_S) {
                begin(c, (uint8_t)c->last_status_from, now);
            }
        }
        return;
    }
    if (c->conn && now - c->last_status_s >= TC_STATUS_TIMEOUT_S) {
        lose(c, now);
        return;
    }
    double timeout = state_timeout(c->state);
    if (timeout >= 0.0 && now - c->state_s >= timeout) {
        if (c->state == TCC_WAIT_LANGUAGE) {
            request_structure_label(c, now); /* no language command: on without it */
        } else {
            lose(c, now);
            return;
        }
    }
    if (c->conn && now >= c->next_task_s) {
        send_client_task(c);
        while (c->next_task_s <= now) {
            c->next_task_s += CLIENT_TASK_PERIOD_S;
        }
    }
    if (c->state == TCC_CONNECTED) {
        run_triggers(c, now);
    }
}

/* --- receiving --------------------------------------------------------------------------------- */

static void on_status(tcc_t *c, const uint8_t *d, uint8_t source, double t)
{
    if (c->conn && source != c->tc_address) {
        return; /* another TC: this client talks to one */
    }
    c->last_status_s = t;
    c->last_status_from = source;
    c->task_active = (d[4] & 0x01u) != 0;
    if (!c->conn && c->state == TCC_WAIT_STATUS &&
        iso_net_address(c->net) != ISO_NO_ADDRESS) {
        begin(c, source, t);
    }
}

static uint16_t u16(const uint8_t *d)
{
    return (uint16_t)(d[0] | (d[1] << 8));
}

static void set_trigger(tcc_t *c, const iso_dpd_t *dpd, unsigned command, uint16_t element,
                        uint16_t ddi, int32_t value, double t)
{
    unsigned method = command == CMD_TIME_INTERVAL       ? ISO_TRIGGER_TIME
                      : command == CMD_DISTANCE_INTERVAL ? ISO_TRIGGER_DISTANCE
                      : command == CMD_MINIMUM || command == CMD_MAXIMUM ? ISO_TRIGGER_THRESHOLD
                      : command == CMD_CHANGE                            ? ISO_TRIGGER_ON_CHANGE
                                                                         : 0u;
    /* no distance source: distance interval triggers are not supported */
    if (method == 0 || !(dpd->triggers & method) || command == CMD_DISTANCE_INTERVAL) {
        ack(c, element, ddi, ISO_ACK_TRIGGER_NOT_SUPPORTED, command);
        return;
    }
    if ((command == CMD_TIME_INTERVAL || command == CMD_CHANGE) && value <= 0) {
        ack(c, element, ddi, ISO_ACK_INVALID_INTERVAL, command);
        return;
    }
    tcc_trigger_t *tr = NULL;
    for (size_t i = 0; i < c->ntriggers; i++) {
        if (c->triggers[i].element == element && c->triggers[i].ddi == ddi) {
            tr = &c->triggers[i];
        }
    }
    if (tr == NULL) {
        /* one per DPD of the pool at most: the table has room for every one */
        tr = &c->triggers[c->ntriggers++];
        memset(tr, 0, sizeof *tr);
        tr->element = element;
        tr->ddi = ddi;
        tr->next_time_s = INFINITY;
    }
    switch (command) {
    case CMD_TIME_INTERVAL:
        tr->has_time = true;
        tr->time_ms = value;
        tr->next_time_s = t + value / 1000.0;
        break;
    case CMD_CHANGE:
        tr->has_change = true;
        tr->change = value;
        break;
    case CMD_MINIMUM:
        tr->has_min = true;
        tr->minimum = value;
        tr->inside = false;
        break;
    default: /* CMD_MAXIMUM */
        tr->has_max = true;
        tr->maximum = value;
        tr->inside = false;
        break;
    }
}

static void send_default_set(tcc_t *c)
{
    for (size_t i = 0; i < c->pool->ndpd; i++) {
        const iso_dpd_t *p = &c->pool->dpd[i];
        int64_t value;
        if ((p->properties & ISO_DPD_DEFAULT_SET) && p->ddi != ISO_DDI_REQUEST_DEFAULT &&
            read(c, p->element, p->ddi, &value)) {
            send_value(c, p->element, p->ddi, value);
        }
    }
}

static void on_element_command(tcc_t *c, unsigned command, uint16_t element, uint16_t ddi,
                               int32_t value, double t)
{
    if (c->state != TCC_CONNECTED) {
        ack(c, element, ddi, ISO_ACK_COMMAND_NOT_SUPPORTED, command);
        return;
    }
    if (command == CMD_REQUEST_VALUE && ddi == ISO_DDI_REQUEST_DEFAULT) {
        send_default_set(c);
        return;
    }
    if (element >= c->pool->elements) {
        ack(c, element, ddi, ISO_ACK_INVALID_ELEMENT, command);
        return;
    }
    const iso_dpd_t *dpd = iso_ddop_dpd(c->pool, element, ddi);
    if (dpd == NULL) {
        ack(c, element, ddi, ISO_ACK_DDI_NOT_SUPPORTED, command);
        return;
    }
    switch (command) {
    case CMD_REQUEST_VALUE: {
        int64_t v;
        if (read(c, element, ddi, &v)) {
            send_value(c, element, ddi, v);
        } else {
            ack(c, element, ddi, ISO_ACK_DDI_NOT_SUPPORTED, command);
        }
        break;
    }
    case CMD_VALUE:
    case CMD_SET_AND_ACK: {
        uint8_t errors = (dpd->properties & ISO_DPD_SETTABLE)
                             ? c->impl.on_setpoint(c->impl.ctx, element, ddi, value)
                             : (uint8_t)ISO_ACK_NOT_SETTABLE;
        if (errors != 0 || command == CMD_SET_AND_ACK) {
            ack(c, element, ddi, errors, command);
        }
        break;
    }
    default:
        set_trigger(c, dpd, command, element, ddi, value, t);
        break;
    }
}

static bool labels_equal(const uint8_t *a, const uint8_t *b)
{
    return memcmp(a, b, 7) == 0;
}

/* A process data message from the TC to us (the Python's _handle). */
static void handle(tcc_t *c, const uint8_t *d, size_t len, double t)
{
    unsigned command = d[0] & 0x0Fu;
    unsigned high = d[0] >> 4;
    if (command == CMD_TECHNICAL) {
        if (high == 0) {
            send_pd(c, c->version_msg, sizeof c->version_msg, PRIORITY_DEFAULT);
        } else if (high == 1) {
            c->has_tc_version = true;
            c->tc_version = d[1];
            if (c->state == TCC_WAIT_VERSION) {
                uint8_t req[3] = {(uint8_t)(ISO_PGN_LANGUAGE & 0xFFu),
                                  (uint8_t)((ISO_PGN_LANGUAGE >> 8) & 0xFFu), 0x00};
                iso_net_send(c->net, ISO_PGN_REQUEST, req, sizeof req, ISO_GLOBAL, 6);
                set_state(c, TCC_WAIT_LANGUAGE, t);
            }
        }
        return;
    }
    if (command == CMD_DEVICE_DESCRIPTOR) {
        switch (high) {
        case DD_STRUCTURE_LABEL:
            if (c->state == TCC_WAIT_STRUCTURE_LABEL) {
                /* our extended structure label is empty: a TC that sends one names another
                 * pool */
                if (labels_equal(d + 1, c->pool->structure_label) && len == 8) {
                    send_simple(c, 0x21, PRIORITY_DEFAULT); /* request localization label */
                    set_state(c, TCC_WAIT_LOCALIZATION_LABEL, t);
                } else {
                    request_transfer(c, t);
                }
            }
            break;
        case DD_LOCALIZATION_LABEL:
            if (c->state == TCC_WAIT_LOCALIZATION_LABEL) {
                if (labels_equal(d + 1, c->pool->localization_label)) {
                    activate(c, t); /* the TC holds this pool: no transfer */
                } else {
                    request_transfer(c, t);
                }
            }
            break;
        case DD_REQUEST_TRANSFER_RESPONSE:
            if (c->state == TCC_WAIT_TRANSFER_PERMISSION) {
                if (d[1] != 0) {
                    refuse(c, t, 0, 0xFFFF, 0xFFFF, 0); /* not enough memory */
                    return;
                }
                c->transfers++;
                send_pd(c, c->transfer, c->transfer_len, PRIORITY_TRANSFER);
                set_state(c, TCC_WAIT_TRANSFER_RESPONSE, t);
            }
            break;
        case DD_TRANSFER_RESPONSE:
            if (c->state == TCC_WAIT_TRANSFER_RESPONSE) {
                if (d[1] != 0) {
                    refuse(c, t, 0, 0xFFFF, 0xFFFF, 0);
                    return;
                }
                activate(c, t);
            }
            break;
        case DD_ACTIVATE_RESPONSE:
            if (c->state == TCC_WAIT_ACTIVATION) {
                if (d[1] != 0) {
                    refuse(c, t, d[1], u16(d + 2), u16(d + 4), d[6]);
                    return;
                }
                set_state(c, TCC_CONNECTED, t);
                c->connections++;
                c->impl.on_connection(c->impl.ctx, true);
            }
            break;
        default:
            break;
        }
        return;
    }
    if (command == CMD_REQUEST_VALUE || command == CMD_VALUE || command == CMD_SET_AND_ACK ||
        (command >= CMD_TIME_INTERVAL && command <= CMD_CHANGE)) {
        uint16_t element = (uint16_t)(high | ((unsigned)d[1] << 4));
        uint32_t raw = (uint32_t)d[4] | ((uint32_t)d[5] << 8) | ((uint32_t)d[6] << 16) |
                       ((uint32_t)d[7] << 24);
        int32_t value = raw <= INT32_MAX ? (int32_t)raw : (int32_t)(raw - 0x80000000u) - INT32_MAX - 1;
        on_element_command(c, command, element, u16(d + 2), value, t);
    }
    /* acknowledgements, client task, identify: nothing to answer */
}

/* Whether the Python's decode() takes the payload (else it is a "bad frame", ignored). */
static bool decodable(const uint8_t *d, size_t len)
{
    if (len == 0) {
        return false;
    }
    unsigned command = d[0] & 0x0Fu;
    unsigned high = d[0] >> 4;
    if (command == CMD_DEVICE_DESCRIPTOR && high == DD_TRANSFER) {
        return true;
    }
    if (len < 8) {
        return false;
    }
    switch (command) {
    case CMD_TECHNICAL:
        return high <= 2;
    case CMD_DEVICE_DESCRIPTOR:
        if (high == DD_ACTIVATE && d[1] != 0x00 && d[1] != 0xFF) {
            return false;
        }
        return high <= 0xD;
    case 0x9:
    case 0xB:
    case 0xC:
        return false;
    default:
        return true;
    }
}

static void on_process_data(tcc_t *c, const uint8_t *d, size_t len, uint8_t source,
                            uint8_t destination, double t)
{
    if (c->state == TCC_REFUSED || !decodable(d, len)) {
        return;
    }
    if ((d[0] & 0x0Fu) == CMD_STATUS) {
        on_status(c, d, source, t);
        return;
    }
    int address = iso_net_address(c->net);
    if (address == ISO_NO_ADDRESS || !c->conn || source != c->tc_address ||
        destination != address) {
        return;
    }
    handle(c, d, len, t);
}

static void on_acknowledgement(tcc_t *c, const uint8_t *d, size_t len, uint8_t source,
                               uint8_t destination, double t)
{
    if (!c->conn || source != c->tc_address || len < 8 || d[0] != 0x01) {
        return;
    }
    uint32_t pgn = (uint32_t)d[5] | ((uint32_t)d[6] << 8) | ((uint32_t)d[7] << 16);
    if (pgn != ISO_PGN_PROCESS_DATA) {
        return;
    }
    if (destination == ISO_GLOBAL && d[4] != iso_net_address(c->net)) {
        return; /* a NACK to another client */
    }
    restart(c, t); /* the TC no longer knows us */
}

bool tcc_on_group(tcc_t *c, uint32_t pgn, const uint8_t *data, size_t len, uint8_t source,
                  uint8_t destination, double now_s)
{
    switch (pgn) {
    case ISO_PGN_PROCESS_DATA:
        on_process_data(c, data, len, source, destination, now_s);
        return true;
    case ISO_PGN_ACKNOWLEDGEMENT:
        on_acknowledgement(c, data, len, source, destination, now_s);
        return true;
    case ISO_PGN_REQUEST:
        if (len >= 3 && c->conn && data[0] == (ISO_PGN_WORKING_SET_MASTER & 0xFFu) &&
            data[1] == ((ISO_PGN_WORKING_SET_MASTER >> 8) & 0xFFu) && data[2] == 0) {
            send_working_set_master(c);
        }
        return true;
    case ISO_PGN_LANGUAGE:
        if (len >= 8 && c->state == TCC_WAIT_LANGUAGE) {
            request_structure_label(c, now_s);
        }
        return true;
    default:
        return false;
    }
}
