"""``hil isobus serve``: the rig's tractor (TECU and Task Controller) alone on any bus."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from hil.validation import help_with_range, option_type

__all__ = ["add_subparser"]


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    isobus = subparsers.add_parser("isobus", help="the rig's ISOBUS tractor (TECU, Task "
                                                  "Controller) on its own")
    sub = isobus.add_subparsers(dest="isobus_command", metavar="ACTION")
    sub.required = True
    serve = sub.add_parser(
        "serve", help="run the tractor ECU and the Task Controller in real time on a bus, "
                      "driving a field path over a prescription map")
    serve.add_argument("--bus", required=True,
                       help="bus spec, e.g. socketcan:can0, socketcand:127.0.0.1:29536/can0 (the "
                            "software bus of `hil bus serve`), virtual:bench")
    serve.add_argument("--path", "--field", dest="field", type=Path, required=True,
                       metavar="FILE",
                       help="field file: GeoJSON with the field boundary, the work area and the "
                            "path's legs (e.g. plant_emulators/fertilizer/fields/"
                            "field-rect.geojson; docs: guide/prescription-maps)")
    rate = serve.add_mutually_exclusive_group(required=True)
    rate.add_argument("--map", type=Path, metavar="FILE",
                      help="prescription map: GeoJSON polygons with a rate (e.g. "
                           "plant_emulators/fertilizer/fields/rates-3zones.geojson)")
    rate.add_argument("--no-map", action="store_true",
                      help="send no rate set-point (TC-BAS and section control only)")
    serve.add_argument("--duration", type=option_type("isobus serve --duration"),
                       default=math.inf, metavar="S",
                       help=help_with_range("isobus serve --duration",
                                            "stop after S seconds of run time (default: until "
                                            "Ctrl-C)"))
    serve.add_argument("--drive-after", type=option_type("isobus serve --drive-after"),
                       default=10.0, metavar="S",
                       help=help_with_range("isobus serve --drive-after",
                                            "stand still, key on, for S seconds before driving "
                                            "the path, so an implement can connect (default "
                                            "10)"))
    serve.add_argument("--wheel-slip", type=option_type("isobus serve --wheel-slip"),
                       default=0.0, metavar="F",
                       help=help_with_range("isobus serve --wheel-slip",
                                            "slip of the tractor's driven wheels: the "
                                            "wheel-based speed over-reads by it (default 0)"))
    serve.add_argument("--out", type=Path, default=Path("isobus-out"), metavar="DIR",
                       help="where bus.log, tc.jsonl, as-applied.geojson and summary.json go")
    serve.add_argument("--quiet", action="store_true", help="no line per connection event")
    serve.add_argument("--vt", action="store_true",
                       help="also the Virtual Terminal (address 0x26, ISO 11783-6 version 4): "
                            "the implement's screens and vt.json in OUT/vt/")
    serve.add_argument("--vt-browser", type=_port, default=None, metavar="PORT",
                       help="the VT in the browser at http://127.0.0.1:PORT/ (0: any free "
                            "port, printed); implies --vt")
    serve.set_defaults(func=_serve)


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port {port} is outside 0 .. 65535")
    return port


def _serve(args: argparse.Namespace) -> int:
    from hil.isobus.field.path import load_field
    from hil.isobus.field.prescription import load_prescription
    from hil.isobus.serve import serve
    from hil.isobus.tractor import Tractor, TractorSetup

    field = load_field(args.field)
    rx = None if args.no_map else load_prescription(args.map, frame=field.frame)
    tractor = Tractor(TractorSetup(field=field, prescription=rx, drive_after_s=args.drive_after,
                                   wheel_slip=args.wheel_slip))
    say = None if args.quiet else (lambda line: print(line, flush=True))
    if say is not None:
        say(f"hil isobus serve: TECU 0x80, TC 0xF7 on {args.bus}; path "
            f"{field.path.duration_s:.0f} s after {args.drive_after:g} s; writing {args.out}/")
    from hil.isobus.serve import ServeVt
    vt = ServeVt(browser_port=args.vt_browser) if args.vt or args.vt_browser is not None else None
    result = serve(tractor, args.bus, args.out, duration_s=args.duration, console=say, vt=vt)
    print(f"hil isobus serve: {result.run_time_s:.1f} s, {result.frames} frames, "
          f"{result.events} TC events, {result.values} values; DDOP "
          f"{'activated' if result.activated else 'never activated'}"
          + ("; interrupted" if result.interrupted else ""), file=sys.stderr)
    return 0
