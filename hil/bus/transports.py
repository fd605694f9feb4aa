"""The built-in bus transports.

In-process virtual, kernel SocketCAN, the software bus, and any other python-can interface.
"""

from __future__ import annotations

import socket
from pathlib import Path

import can

from hil.bus.spec import BusSpec
from hil.errors import BusError, BusSpecError


def open_virtual(spec: BusSpec) -> can.BusABC:
    """``virtual[:channel]``: python-can's in-process bus (threads of one process only)."""
    return can.Bus(interface="virtual", channel=spec.channel or "agrihil", **spec.options)


def kernel_has_socketcan() -> tuple[bool, str]:
    """Whether this kernel accepts AF_CAN sockets, and why not when it does not."""
    if not hasattr(socket, "AF_CAN"):
        return False, "this Python/OS has no AF_CAN (SocketCAN is Linux-only)"
    try:
        sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    except OSError as exc:
        return False, f"the kernel refuses AF_CAN sockets ({exc.strerror}): no SocketCAN support"
    sock.close()
    return True, "ok"


#: receive buffer asked for on kernel CAN sockets: the default (~208 KiB) loses frames when a
#: busy machine (or an emulated one) schedules the reader late; 10,000 frames each way between
#: two processes arrived as 3,059 with it in a user-mode Linux guest
SOCKETCAN_RCVBUF = 8 * 1024 * 1024
#: ARPHRD_CAN, the link type of every CAN interface in /sys/class/net/<iface>/type
_ARPHRD_CAN = 280
_IFF_UP = 0x1


def _sysfs(iface: str, name: str) -> str | None:
    try:
        return (Path("/sys/class/net") / iface / name).read_text().strip()
    except OSError:
        return None


def check_socketcan_interface(iface: str) -> None:
    """Refuse, with the fix, an interface that is missing, not CAN, or down."""
    if "/" in iface or iface in (".", "..") or not Path(f"/sys/class/net/{iface}").exists():
        raise BusError(f"socketcan:{iface}: no network interface {iface!r}; for a virtual "
                       f"one: `ip link add dev {iface} type vcan && ip link set up {iface}`")
    link_type = _sysfs(iface, "type")
    if link_type is not None and link_type.isdigit() and int(link_type) != _ARPHRD_CAN:
        raise BusError(f"socketcan:{iface}: {iface!r} is not a CAN interface (link type "
                       f"{link_type}, CAN is {_ARPHRD_CAN})")
    flags = _sysfs(iface, "flags")
    if flags is not None:
        try:
            up = int(flags, 0) & _IFF_UP
        except ValueError:
            up = 1
        if not up:
            raise BusError(f"socketcan:{iface}: the interface is down; bring it up with "
                           f"`ip link set up {iface}` (a real CAN interface also needs its "
                           f"bit rate: `ip link set {iface} type can bitrate 250000`)")


def _raise_receive_buffer(bus: can.BusABC) -> None:
    """Ask for :data:`SOCKETCAN_RCVBUF` (forced past rmem_max when privileged)."""
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        return
    force = getattr(socket, "SO_RCVBUFFORCE", None)
    if force is not None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, force, SOCKETCAN_RCVBUF)
            return
        except OSError:
            pass  # not privileged: the plain option, capped by net.core.rmem_max
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SOCKETCAN_RCVBUF)


def open_socketcan(spec: BusSpec) -> can.BusABC:
    """``socketcan:<iface>``: a kernel CAN interface (vcan0, can0, …).

    The interface must exist, be a CAN interface and be up; the socket's receive buffer is
    raised to :data:`SOCKETCAN_RCVBUF`.
    """
    if not spec.channel:
        raise BusSpecError("socketcan needs an interface: 'socketcan:vcan0' or 'socketcan:can0'")
    ok, why = kernel_has_socketcan()
    if not ok:
        raise BusError(f"cannot open socketcan:{spec.channel}: {why}; use the software bus "
                       "instead (`hil bus serve`, spec 'socketcand:127.0.0.1:29536/can0')")
    check_socketcan_interface(spec.channel)
    bus = can.Bus(interface="socketcan", channel=spec.channel, **spec.options)
    try:
        _raise_receive_buffer(bus)
    except OSError as exc:
        bus.shutdown()
        raise BusError(f"socketcan:{spec.channel}: cannot size the receive buffer: "
                       f"{exc}") from exc
    return bus


#: spec options that select and tune agrihil's own socketcand client (hil.bus.socketcand)
AGRIHIL_CLIENT_OPTIONS = ("batch", "max_batch", "busy_poll_us")


def open_socketcand(spec: BusSpec) -> can.BusABC:
    """``socketcand:<host>:<port>[/<channel>]``: a socketcand server, e.g. the software bus.

    python-can's client by default; agrihil's (:mod:`hil.bus.socketcand`) with
    ``client=agrihil`` or with one of its options (``batch=true``, ``max_batch=N``,
    ``busy_poll_us=N``).
    """
    from hil.softbus.server import DEFAULT_CHANNEL, raise_if_unreachable

    target = spec.channel or ""
    address, _, channel = target.partition("/")
    host, sep, port_text = address.rpartition(":")
    if not sep or not host or not port_text.isdigit():
        raise BusSpecError(f"socketcand spec needs host and port: 'socketcand:127.0.0.1:29536"
                           f"[/can0]', got 'socketcand:{target}'")
    port = int(port_text)
    options = dict(spec.options)
    client = str(options.pop("client", "python-can")).lower()
    ours = {key: options.pop(key) for key in AGRIHIL_CLIENT_OPTIONS if key in options}
    if client not in ("python-can", "agrihil"):
        raise BusSpecError(f"socketcand spec: client={client!r}; known: python-can, agrihil")
    if ours and client == "python-can" and "client" in spec.options:
        raise BusSpecError(f"socketcand spec: {', '.join(ours)} need client=agrihil")
    raise_if_unreachable(host, port)
    if ours or client == "agrihil":
        from hil.bus.socketcand import SocketcandBus

        options.pop("tcp_tune", None)  # always on in agrihil's client (TCP_NODELAY)
        return SocketcandBus(channel or DEFAULT_CHANNEL, host, port, **ours, **options)
    options = {"tcp_tune": True, **options}
    return can.Bus(interface="socketcand", host=host, port=port,
                   channel=channel or DEFAULT_CHANNEL, **options)


def open_python_can(spec: BusSpec) -> can.BusABC:
    """Any other installed python-can interface: ``<interface>:<channel>[,key=value…]``."""
    kwargs = dict(spec.options)
    if spec.channel is not None:
        kwargs["channel"] = spec.channel
    return can.Bus(interface=spec.transport, **kwargs)
