#include "lsbus_node.h"

#include <string.h>

#include "fmi3LsBusCan.h"

void lsbus_node_init(lsbus_node_t *n)
{
    memset(n, 0, sizeof *n);
}

bool lsbus_node_set_rx(lsbus_node_t *n, const uint8_t *data, size_t len)
{
    if (len > sizeof n->rx) {
        return false;
    }
    if (len > 0) {
        memcpy(n->rx, data, len);
    }
    n->rx_len = len;
    return true;
}

static bool append(lsbus_node_t *n, const void *op, size_t len)
{
    if (n->tx_taken) {
        n->tx_len = 0;
        n->tx_taken = false;
    }
    if (len > sizeof n->tx - n->tx_len) {
        return false;
    }
    memcpy(n->tx + n->tx_len, op, len);
    n->tx_len += len;
    n->tx_clock = true;
    return true;
}

static uint32_t u32_at(const uint8_t *p)
{
    uint32_t v;
    memcpy(&v, p, sizeof v);
    return v;
}

bool lsbus_node_read(lsbus_node_t *n, void (*on_frame)(void *ctx, const hal_can_frame_t *f),
                     void *ctx)
{
    if (!n->rx_clock) {
        return true;
    }
    n->rx_clock = false;
    size_t pos = 0;
    bool ok = true;
    const size_t header = sizeof(fmi3LsBusOperationHeader);
    while (pos + header <= n->rx_len) {
        const uint32_t code = u32_at(n->rx + pos);
        const uint32_t length = u32_at(n->rx + pos + 4);
        if (length < header || length > n->rx_len - pos) {
            ok = false;
            break;
        }
        const uint8_t *body = n->rx + pos + header;
        const size_t body_len = length - header;
        if (code == FMI3_LS_BUS_CAN_OP_CAN_TRANSMIT && body_len >= 8) {
            hal_can_frame_t f;
            memset(&f, 0, sizeof f);
            f.id = u32_at(body);
            f.extended = body[4] != 0;
            uint16_t dlen;
            memcpy(&dlen, body + 6, sizeof dlen);
            if (dlen > 8 || (size_t)dlen + 8 != body_len) {
                ok = false;
                break;
            }
            f.len = (uint8_t)dlen;
            memcpy(f.data, body + 8, dlen);
            n->frames_in++;
            on_frame(ctx, &f);
        } else if (code == FMI3_LS_BUS_CAN_OP_CONFIRM && body_len == 4) {
            n->confirms++;
            n->last_confirmed_id = u32_at(body);
        } else if (code == FMI3_LS_BUS_CAN_OP_ARBITRATION_LOST && body_len == 4) {
            n->arbitration_lost++;
        } else if (code == FMI3_LS_BUS_CAN_OP_BUS_ERROR && body_len == 7) {
            n->bus_errors++;
            if (body[6] != 0) {
                n->bus_errors_as_sender++;
            }
        } else if (code == FMI3_LS_BUS_CAN_OP_STATUS && body_len == 1) {
            n->status = body[0];
        } else if (code == FMI3_LS_BUS_CAN_OP_CONFIGURATION && body_len == 5) {
            n->baudrate = u32_at(body + 1);
        } else if (code == FMI3_LS_BUS_CAN_OP_WAKEUP && body_len == 0) {
            n->wakeups++;
        } else {
            n->unknown_ops++;
        }
        pos += length;
    }
    const size_t len = n->rx_len;
    n->rx_len = 0;
    return ok && pos == len;
}

bool lsbus_node_transmit(lsbus_node_t *n, const hal_can_frame_t *f)
{
    uint8_t op[sizeof(fmi3LsBusCanOperationCanTransmit) + 8];
    fmi3LsBusCanOperationCanTransmit head;
    uint8_t len = f->len > 8 ? 8 : f->len;
    head.header.opCode = FMI3_LS_BUS_CAN_OP_CAN_TRANSMIT;
    head.header.length = (fmi3UInt32)(sizeof head + len);
    head.id = f->id;
    head.ide = f->extended ? FMI3_LS_BUS_TRUE : FMI3_LS_BUS_FALSE;
    head.rtr = FMI3_LS_BUS_FALSE;
    head.dataLength = len;
    memcpy(op, &head, sizeof head);
    memcpy(op + sizeof head, f->data, len);
    return append(n, op, sizeof head + len);
}

bool lsbus_node_transmit_fd(lsbus_node_t *n, uint32_t id, const uint8_t *data, uint16_t len)
{
    uint8_t op[sizeof(fmi3LsBusCanOperationCanFdTransmit) + 64];
    fmi3LsBusCanOperationCanFdTransmit head;
    if (len > 64) {
        return false;
    }
    head.header.opCode = FMI3_LS_BUS_CAN_OP_CANFD_TRANSMIT;
    head.header.length = (fmi3UInt32)(sizeof head + len);
    head.id = id;
    head.ide = FMI3_LS_BUS_FALSE;
    head.brs = FMI3_LS_BUS_TRUE;
    head.esi = FMI3_LS_BUS_FALSE;
    head.dataLength = len;
    memcpy(op, &head, sizeof head);
    memcpy(op + sizeof head, data, len);
    return append(n, op, sizeof head + len);
}

bool lsbus_node_configure_baudrate(lsbus_node_t *n, uint32_t baudrate)
{
    uint8_t op[13];
    const uint32_t code = FMI3_LS_BUS_CAN_OP_CONFIGURATION;
    const uint32_t length = sizeof op;
    memcpy(op, &code, 4);
    memcpy(op + 4, &length, 4);
    op[8] = FMI3_LS_BUS_CAN_CONFIG_PARAM_TYPE_CAN_BAUDRATE;
    memcpy(op + 9, &baudrate, 4);
    return append(n, op, sizeof op);
}

bool lsbus_node_configure_arbitration(lsbus_node_t *n, uint8_t behavior)
{
    uint8_t op[10];
    const uint32_t code = FMI3_LS_BUS_CAN_OP_CONFIGURATION;
    const uint32_t length = sizeof op;
    memcpy(op, &code, 4);
    memcpy(op + 4, &length, 4);
    op[8] = FMI3_LS_BUS_CAN_CONFIG_PARAM_TYPE_ARBITRATION_LOST_BEHAVIOR;
    op[9] = behavior;
    return append(n, op, sizeof op);
}

const uint8_t *lsbus_node_tx(lsbus_node_t *n, size_t *len)
{
    if (n->tx_taken) {
        *len = 0;
        return n->tx;
    }
    *len = n->tx_len;
    n->tx_taken = true;
    return n->tx;
}

bool lsbus_node_take_tx_clock(lsbus_node_t *n)
{
    bool active = n->tx_clock;
    n->tx_clock = false;
    return active;
}
