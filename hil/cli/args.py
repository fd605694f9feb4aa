"""Argument helpers shared by subcommands."""

from __future__ import annotations

import argparse

from hil.softbus.server import DEFAULT_PORT


def add_host_port(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default="127.0.0.1", help="address (default: 127.0.0.1)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"TCP port (default: {DEFAULT_PORT}; 0 picks a free one)")


def add_bus_clock(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--bus", default="softbus",
                        help="bus spec: 'softbus' (start an embedded software bus, the default), "
                             "'virtual', 'socketcan:vcan0', 'socketcand:HOST:PORT/CH', "
                             "'<python-can interface>:<channel>,key=value', or 'inline' "
                             "(lockstep with an in-process controller: no threads, fastest)")
    parser.add_argument("--clock", choices=["lockstep", "realtime"], default="lockstep",
                        help="lockstep (virtual time, fast, deterministic) or realtime")
