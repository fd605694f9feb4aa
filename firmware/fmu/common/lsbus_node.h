/* One CAN terminal of an FMI-LS-BUS 1.0 node FMU: its Rx_Data / Tx_Data buffers and clocks.
 *
 * The importer (the bus simulation) writes Rx_Data and activates Rx_Clock; the node reads the
 * operations in its event update (lsbus_node_read), handing each CAN transmit operation to the
 * model as a frame and keeping count of what the bus told it (confirm, arbitration lost, bus
 * error, status, configuration, wake-up). The model's frames go out as CAN transmit operations
 * in Tx_Data (lsbus_node_transmit), which activates Tx_Clock; the importer reads the clock and
 * the buffer, and the buffer is emptied before the next operation is written to it.
 * Fixed buffers: no allocation. Operations are written in the host's byte order, as the
 * LS-BUS headers' own macros do (every FMI platform agrihil runs on is little-endian). */
#ifndef AGRIHIL_LSBUS_NODE_H
#define AGRIHIL_LSBUS_NODE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal_can.h"

#define LSBUS_NODE_BUFFER 2048

typedef struct {
    uint8_t rx[LSBUS_NODE_BUFFER];
    size_t rx_len;
    bool rx_clock;      /* Rx_Clock activated since the last read */
    uint8_t tx[LSBUS_NODE_BUFFER];
    size_t tx_len;
    bool tx_clock;      /* Tx_Clock active, not yet reported by getClock */
    bool tx_taken;      /* the importer has read Tx_Data: empty it before the next write */
    bool notifications; /* Can_BusNotifications */
    /* what the bus told the node */
    uint32_t frames_in;
    uint32_t confirms;
    uint32_t arbitration_lost;
    uint32_t bus_errors;
    uint32_t bus_errors_as_sender;
    uint32_t wakeups;
    uint32_t unknown_ops;
    uint32_t last_confirmed_id;
    uint8_t status; /* 1 error active, 2 error passive, 3 bus off; 0 none heard */
    uint32_t baudrate;
} lsbus_node_t;

void lsbus_node_init(lsbus_node_t *n);

/* Rx_Data set by the importer; false when it does not fit the buffer. */
bool lsbus_node_set_rx(lsbus_node_t *n, const uint8_t *data, size_t len);

/* Read the operations of Rx_Data (when Rx_Clock was activated) and forget them; each CAN
 * transmit operation goes to on_frame. Returns false on a malformed buffer. */
bool lsbus_node_read(lsbus_node_t *n, void (*on_frame)(void *ctx, const hal_can_frame_t *f),
                     void *ctx);

/* Append a CAN transmit operation for `f` and activate Tx_Clock; false when the buffer is
 * full. */
bool lsbus_node_transmit(lsbus_node_t *n, const hal_can_frame_t *f);

/* Append a CAN FD transmit operation (the probe uses it to test that a classic bus refuses
 * it); false when the buffer is full. */
bool lsbus_node_transmit_fd(lsbus_node_t *n, uint32_t id, const uint8_t *data, uint16_t len);

/* Append a configuration operation: the CAN baud rate, or the arbitration-lost behaviour
 * (1 buffer and retransmit, 2 discard and notify). */
bool lsbus_node_configure_baudrate(lsbus_node_t *n, uint32_t baudrate);
bool lsbus_node_configure_arbitration(lsbus_node_t *n, uint8_t behavior);

/* Tx_Data for getBinary (marks it taken) and Tx_Clock for getClock (reported once). */
const uint8_t *lsbus_node_tx(lsbus_node_t *n, size_t *len);
bool lsbus_node_take_tx_clock(lsbus_node_t *n);

#endif
