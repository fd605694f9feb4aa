/* CAN hardware abstraction: open a bus by spec string, send, receive with a timeout, close.
 *
 * Host backends (chosen by the spec's transport):
 *   socketcan:IFACE                Linux SocketCAN raw socket (can0, vcan0, ...)
 *   socketcand:HOST:PORT[/CHANNEL] the socketcand text protocol over TCP (agrihil's software
 *                                  bus speaks it); CHANNEL defaults to can0
 * Options after a ',' (",bitrate=250000") are accepted and ignored: the bit rate belongs to the
 * interface, not to a raw socket. Except, for socketcand, ",busy_poll_us=N": before blocking
 * for a frame, poll the socket without blocking for up to N us (an adaptive window, as
 * Linux's halt polling: it grows while frames come within N us of a wait and shrinks to
 * nothing when they do not, so an idle bus costs no CPU). It spares a lockstep DUT the
 * wake-up of a sleeping vCPU per step (~35-45 us on a VM) at the price of a busy CPU.
 *
 * socketcand sends are written behind: hal_can_send queues the frame's text and the next
 * hal_can_recv (or hal_can_close, or a full queue) writes everything queued in one write, so
 * that the frames a step produces reach the bus as one TCP segment and wake the bus once.
 * A loop that sends and then waits for the bus (every agrihil app does) sees no difference;
 * a send error then shows as HAL_CAN_ERROR from the next hal_can_recv.
 *
 * To port to an MCU, implement these five functions over the CAN peripheral's driver (hal_can_t
 * can hold whatever the driver needs; `spec` may be ignored). No allocation: the caller owns the
 * hal_can_t, usually as a static. */
#ifndef AGRIHIL_HAL_CAN_H
#define AGRIHIL_HAL_CAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "bus_spec.h"

typedef struct {
    uint32_t id;      /* 11-bit or 29-bit identifier */
    bool extended;    /* 29-bit identifier */
    uint8_t len;      /* 0..8 */
    uint8_t data[8];
} hal_can_frame_t;

/* The lockstep step-end frame (extended id, no data; hil.clock.STEP_END_ID): a DUT that does
 * not send its command frame last sends one after its boot-up and one after each answer to
 * SYNC (docs/guide/clocks.md, "Where a step ends"). The reference adapters send the command
 * last and do not need it. */
#define HAL_CAN_STEP_END_ID 0x1FFFFFF0u

#define HAL_CAN_RXBUF 4096
#define HAL_CAN_TXBUF 2048
#define HAL_CAN_ERRLEN 256

typedef struct {
    bus_transport_t transport;
    int fd;
    /* socketcand: bytes received but not yet parsed into messages */
    char rx[HAL_CAN_RXBUF];
    size_t rx_len;
    /* socketcand: frames sent but not yet written (written by the next recv) */
    char tx[HAL_CAN_TXBUF];
    size_t tx_len;
    /* socketcand busy polling: limit and current adaptive window, ns (0: off), and when
     * data last came */
    int64_t busy_poll_limit_ns;
    int64_t busy_poll_window_ns;
    int64_t busy_poll_last_ns;
    /* last error, for the caller to print */
    char error[HAL_CAN_ERRLEN];
} hal_can_t;

/* Result of hal_can_recv */
enum { HAL_CAN_ERROR = -1, HAL_CAN_TIMEOUT = 0, HAL_CAN_FRAME = 1 };

/* Open the bus named by `spec`; 0 on success, -1 with bus->error set. */
int hal_can_open(hal_can_t *bus, const char *spec);

/* Send one frame; 0 on success, -1 with bus->error set (e.g. the server went away). */
int hal_can_send(hal_can_t *bus, const hal_can_frame_t *frame);

/* Wait up to timeout_us (0: poll) for a frame. HAL_CAN_FRAME with *frame filled,
 * HAL_CAN_TIMEOUT (also when a signal interrupted the wait) or HAL_CAN_ERROR. */
int hal_can_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us);

void hal_can_close(hal_can_t *bus);

/* Backends (hal_can.c dispatches to them) */
int hal_socketcan_open(hal_can_t *bus, const bus_spec_t *spec);
int hal_socketcan_send(hal_can_t *bus, const hal_can_frame_t *frame);
int hal_socketcan_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us);
int hal_socketcand_open(hal_can_t *bus, const bus_spec_t *spec);
int hal_socketcand_send(hal_can_t *bus, const hal_can_frame_t *frame);
int hal_socketcand_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us);
int hal_socketcand_flush(hal_can_t *bus);

#endif
