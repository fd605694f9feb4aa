/* SocketCAN backend: a Linux CAN_RAW socket bound to one interface (can0, vcan0, ...).
 * Builds everywhere; on a kernel without CAN support opening fails with a message that says so
 * and points at the socketcand transport. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "hal_can.h"

#if defined(__linux__)

#include <linux/can.h>
#include <linux/can/raw.h>
#include <linux/if_arp.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

/* receive buffer asked for: the kernel's default (~208 KiB) drops frames when the firmware is
 * scheduled late (a loaded machine, an emulated kernel); capped by net.core.rmem_max */
#define SOCKETCAN_RCVBUF (8 * 1024 * 1024)
/* how long a send waits for room in a full transmit queue (ENOBUFS) before it is an error */
#define SOCKETCAN_SEND_WAIT_US 1000000

/* The interface must be a CAN interface and up: say which, and how to fix it. */
static int check_interface(hal_can_t *bus, int fd, const char *iface)
{
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", iface);
    if (ioctl(fd, SIOCGIFHWADDR, &ifr) == 0 && ifr.ifr_hwaddr.sa_family != ARPHRD_CAN) {
        snprintf(bus->error, sizeof bus->error, "socketcan:%s: not a CAN interface (link type "
                 "%d)", iface, (int)ifr.ifr_hwaddr.sa_family);
        return -1;
    }
    if (ioctl(fd, SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) == 0) {
        snprintf(bus->error, sizeof bus->error, "socketcan:%s: the interface is down; bring it "
                 "up with 'ip link set up %s'", iface, iface);
        return -1;
    }
    return 0;
}

int hal_socketcan_open(hal_can_t *bus, const bus_spec_t *spec)
{
    int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        int err = errno;
        if (err == EAFNOSUPPORT || err == EPROTONOSUPPORT) {
            snprintf(bus->error, sizeof bus->error,
                     "socketcan:%s: this kernel has no SocketCAN (socket(PF_CAN): %s); use a "
                     "socketcand:HOST:PORT bus such as agrihil's software bus", spec->iface,
                     strerror(err));
        } else {
            snprintf(bus->error, sizeof bus->error, "socketcan:%s: cannot open a CAN_RAW "
                     "socket: %s", spec->iface, strerror(err));
        }
        return -1;
    }
    if (strlen(spec->iface) >= IFNAMSIZ) {
        snprintf(bus->error, sizeof bus->error, "socketcan:%s: interface names are at most %d "
                 "characters", spec->iface, IFNAMSIZ - 1);
        close(fd);
        return -1;
    }
    unsigned int index = if_nametoindex(spec->iface);
    if (index == 0) {
        snprintf(bus->error, sizeof bus->error, "socketcan:%s: no such CAN interface (%s); for a "
                 "virtual one: 'ip link add dev %s type vcan && ip link set up %s'",
                 spec->iface, strerror(errno), spec->iface, spec->iface);
        close(fd);
        return -1;
    }
    if (check_interface(bus, fd, spec->iface) != 0) {
        close(fd);
        return -1;
    }
    int rcvbuf = SOCKETCAN_RCVBUF;
    /* a bigger buffer is best effort: the kernel caps it at net.core.rmem_max */
    (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)index;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) != 0) {
        snprintf(bus->error, sizeof bus->error, "socketcan:%s: bind failed: %s", spec->iface,
                 strerror(errno));
        close(fd);
        return -1;
    }
    bus->fd = fd;
    return 0;
}

int hal_socketcan_send(hal_can_t *bus, const hal_can_frame_t *frame)
{
    struct can_frame cf;
    memset(&cf, 0, sizeof cf);
    cf.can_id = frame->extended ? (frame->id & CAN_EFF_MASK) | CAN_EFF_FLAG
                                : frame->id & CAN_SFF_MASK;
    cf.can_dlc = frame->len;
    memcpy(cf.data, frame->data, frame->len);
    int64_t waited_us = 0;
    for (;;) {
        ssize_t n = write(bus->fd, &cf, sizeof cf);
        if (n == (ssize_t)sizeof cf) {
            return 0;
        }
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n < 0 && (errno == ENOBUFS || errno == EAGAIN) &&
            waited_us < SOCKETCAN_SEND_WAIT_US) {
            /* the transmit queue is full: wait for room, as a CAN controller's driver does */
            fd_set set;
            FD_ZERO(&set);
            FD_SET(bus->fd, &set);
            struct timespec ts = {0, 1000000L};
            (void)pselect(bus->fd + 1, NULL, &set, NULL, &ts, NULL);
            waited_us += 1000;
            continue;
        }
        snprintf(bus->error, sizeof bus->error, "socketcan: write failed: %s",
                 n < 0 ? strerror(errno) : "short write");
        return -1;
    }
}

int hal_socketcan_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us)
{
    for (;;) {
        fd_set set;
        FD_ZERO(&set);
        FD_SET(bus->fd, &set);
        int64_t t = timeout_us > 0 ? timeout_us : 0;
        struct timespec ts = {(time_t)(t / 1000000), (long)(t % 1000000) * 1000L};
        int rc = pselect(bus->fd + 1, &set, NULL, NULL, &ts, NULL);
        if (rc < 0) {
            if (errno == EINTR) {
                return HAL_CAN_TIMEOUT;
            }
            snprintf(bus->error, sizeof bus->error, "socketcan: select failed: %s",
                     strerror(errno));
            return HAL_CAN_ERROR;
        }
        if (rc == 0) {
            return HAL_CAN_TIMEOUT;
        }
        struct can_frame cf;
        ssize_t n = read(bus->fd, &cf, sizeof cf);
        if (n < 0) {
            if (errno == EINTR || errno == EAGAIN) {
                return HAL_CAN_TIMEOUT;
            }
            snprintf(bus->error, sizeof bus->error, "socketcan: read failed: %s",
                     strerror(errno));
            return HAL_CAN_ERROR;
        }
        if (n != (ssize_t)sizeof cf || (cf.can_id & (CAN_ERR_FLAG | CAN_RTR_FLAG)) != 0) {
            timeout_us = 0; /* error and remote frames are not data: look for the next one */
            continue;
        }
        frame->extended = (cf.can_id & CAN_EFF_FLAG) != 0;
        frame->id = cf.can_id & (frame->extended ? CAN_EFF_MASK : CAN_SFF_MASK);
        frame->len = cf.can_dlc > 8 ? 8 : cf.can_dlc;
        memcpy(frame->data, cf.data, frame->len);
        return HAL_CAN_FRAME;
    }
}

#else /* not Linux: no SocketCAN */

int hal_socketcan_open(hal_can_t *bus, const bus_spec_t *spec)
{
    snprintf(bus->error, sizeof bus->error, "socketcan:%s: SocketCAN exists only on Linux; use "
             "a socketcand:HOST:PORT bus", spec->iface);
    return -1;
}

int hal_socketcan_send(hal_can_t *bus, const hal_can_frame_t *frame)
{
    (void)frame;
    snprintf(bus->error, sizeof bus->error, "socketcan: not available");
    return -1;
}

int hal_socketcan_recv(hal_can_t *bus, hal_can_frame_t *frame, int64_t timeout_us)
{
    (void)frame;
    (void)timeout_us;
    snprintf(bus->error, sizeof bus->error, "socketcan: not available");
    return HAL_CAN_ERROR;
}

#endif
