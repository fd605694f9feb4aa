"""``hil bus``: the software bus (``serve``) and its controls (``fault``, ``stats``)."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import sys
import threading

from hil.cli.args import add_host_port, check_log_path
from hil.errors import ConfigError
from hil.softbus.control import CONTROL_TOKEN_ENV, control
from hil.softbus.faults import FaultKind
from hil.softbus.server import SoftwareBus
from hil.validation import help_with_range, option_type

__all__ = ["add_subparser", "control"]


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    bus = subparsers.add_parser("bus", help="the software CAN bus")
    sub = bus.add_subparsers(dest="bus_command", metavar="ACTION")
    sub.required = True

    serve = sub.add_parser("serve", help="run a software bus (socketcand protocol on loopback)")
    add_host_port(serve)
    serve.add_argument("--bitrate", type=option_type("bus serve --bitrate"), default=None,
                       help=help_with_range("bus serve --bitrate",
                                            "pace frames to this bit rate with arbitration "
                                            "by id (e.g. 250000 for ISOBUS); default: "
                                            "unpaced"))
    serve.add_argument("--log", default=None,
                       help="write every frame to this bus log (.log candump, .asc, .blf …)")
    serve.add_argument("--seed", type=option_type("bus serve --seed"), default=0,
                       help=help_with_range("bus serve --seed",
                                            "seed for probabilistic faults"))
    serve.add_argument("--allow-remote", action="store_true",
                       help="allow binding to a non-loopback address")
    serve.add_argument("--busy-poll-us", type=option_type("bus serve --busy-poll-us"),
                       default=None, metavar="US",
                       help=help_with_range("bus serve --busy-poll-us",
                                            "after traffic, poll this long before sleeping "
                                            "(cuts round-trip latency; no CPU when the bus "
                                            "is idle; 0: off; default: "
                                            "$AGRIHIL_SOFTBUS_BUSY_POLL_US or 200)"))
    serve.add_argument("--exit-with-stdin", action="store_true",
                       help="stop when stdin reaches EOF (a parent that holds the pipe's other "
                            "end takes the bus with it when it dies)")
    serve.set_defaults(func=_serve)

    fault = sub.add_parser("fault", help="inject or clear faults on a running software bus")
    add_host_port(fault)
    fault.add_argument("action", choices=["add", "clear", "list", "errors"])
    fault.add_argument("kind", nargs="?", choices=[k.value for k in FaultKind],
                       help="with add: what to do to matching frames")
    fault.add_argument("--id", type=option_type("bus fault --id"), default=None,
                       help=help_with_range("bus fault --id", "frame id to match (decimal or "
                                                              "0x hexadecimal)"))
    fault.add_argument("--mask", type=option_type("bus fault --mask"), default=None,
                       help=help_with_range("bus fault --mask",
                                            "id mask (default: exact match when --id is "
                                            "given, else all)"))
    fault.add_argument("-p", "--probability", type=option_type("bus fault --probability"),
                       default=1.0, help=help_with_range("bus fault --probability",
                                                         "chance per matching frame "
                                                         "(default: 1)"))
    fault.add_argument("--count", type=option_type("bus fault --count"), default=0,
                       help=help_with_range("bus fault --count",
                                            "act on at most N frames (0: all)"))
    fault.add_argument("--delay", type=option_type("bus fault --delay"), default=0.0,
                       help=help_with_range("bus fault --delay", "seconds, with kind delay"))
    fault.add_argument("--rule", type=option_type("bus fault --rule"), default=None,
                       help=help_with_range("bus fault --rule", "with clear: only this rule"))
    fault.add_argument("-n", type=option_type("bus fault -n"), default=1,
                       help=help_with_range("bus fault -n",
                                            "with errors: how many error frames"))
    _add_token(fault)
    fault.set_defaults(func=_fault)

    stats = sub.add_parser("stats", help="print a running software bus's counters as JSON")
    add_host_port(stats)
    _add_token(stats)
    stats.set_defaults(func=_stats)


def _add_token(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--token", default=None,
                        help="the bus's control token (default: the file the bus wrote for "
                             f"its port, else ${CONTROL_TOKEN_ENV})")


def _check_serve_options(args: argparse.Namespace) -> None:
    """Every option of ``hil bus serve`` checked before the bus binds (exit 2, one line)."""
    if args.log is not None:
        check_log_path(args.log)
    if args.bitrate is not None and not 10_000 <= args.bitrate <= 1_000_000:
        raise ConfigError(f"--bitrate {args.bitrate}: a CAN bit rate is 10000 .. 1000000 "
                          "bit/s (ISOBUS: 250000)")
    if args.busy_poll_us is not None and not (math.isfinite(args.busy_poll_us)
                                              and 0 <= args.busy_poll_us <= 1_000_000):
        raise ConfigError(f"--busy-poll-us {args.busy_poll_us}: give 0 (off) .. 1000000 us",
                          )


def _serve(args: argparse.Namespace) -> int:
    _check_serve_options(args)
    bus = SoftwareBus(args.host, args.port, bitrate=args.bitrate, log_path=args.log,
                      seed=args.seed, allow_remote=args.allow_remote,
                      busy_poll_us=args.busy_poll_us,
                      control_token=os.environ.get(CONTROL_TOKEN_ENV) or None)

    def listening(server: SoftwareBus) -> None:
        pace = f", paced at {args.bitrate} bit/s" if args.bitrate else ""
        where = (f"; control token in {server.token_path}" if server.token_path is not None
                 else f"; control token not written (set ${CONTROL_TOKEN_ENV} to choose it)")
        print(f"hil: software bus listening on {server.host}:{server.port}{pace}; "
              f"spec {server.spec()}{where}", flush=True)

    if args.exit_with_stdin:
        threading.Thread(target=_stop_at_eof, args=(bus,), name="hil-softbus-stdin",
                         daemon=True).start()
    asyncio.run(bus.serve(on_listening=listening))
    return 0


def _stop_at_eof(bus: SoftwareBus) -> None:
    """Stop the bus when stdin ends (the parent closed it, or died)."""
    with contextlib.suppress(OSError, ValueError):
        while sys.stdin.buffer.read1(4096):
            pass
    bus.request_stop()


def _fault(args: argparse.Namespace) -> int:
    if args.action == "add":
        if args.kind is None:
            print("hil: error: 'fault add' needs a kind", file=sys.stderr)
            return 2
        words = ["fault", "add", args.kind, f"p={args.probability}", f"count={args.count}"]
        if args.id is not None:
            words.append(f"id={args.id:#x}")
        if args.mask is not None:
            words.append(f"mask={args.mask:#x}")
        if args.delay:
            words.append(f"delay={args.delay}")
    elif args.action == "clear":
        words = ["fault", "clear"] + ([str(args.rule)] if args.rule is not None else [])
    elif args.action == "list":
        words = ["fault", "list"]
    else:
        words = ["errors", str(args.n)]
    print(control(args.host, args.port, words, token=args.token))
    return 0


def _stats(args: argparse.Namespace) -> int:
    reply = control(args.host, args.port, ["stats"], token=args.token)
    print(json.dumps(json.loads(reply[len("< hil stats "):-2]), indent=2))
    return 0
