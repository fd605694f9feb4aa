"""``hil rig``: rigs of your own (a plant FMU and your DBC's devices, in a rig file).

    hil rig check motor-meter.rig.toml
    hil rig scenarios motor-meter.rig.toml --write scenarios/suite

``check`` validates the rig file against its FMU (fmpy's validation, an instance with the
file's parameters and one step) and its DBC (messages, signals, nodes, units) and prints what
the rig will play; exit 0 when the file is good, 2 naming the file and the key when not.
``scenarios`` writes the scenarios the standard suites run on the rig as scenario files.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    rig = subparsers.add_parser("rig", help="check a rig of your own (a rig file: plant FMU "
                                            "and DBC devices)")
    sub = rig.add_subparsers(dest="rig_command", metavar="ACTION")
    sub.required = True
    check = sub.add_parser("check", help="validate a rig file against its FMU and DBC (exit "
                                         "2 naming the key when it is refused)")
    check.add_argument("file", help="the rig file (TOML)")
    check.set_defaults(func=_check)
    scenarios = sub.add_parser("scenarios", help="write the standard suites' scenarios of a "
                                                 "rig file as scenario files")
    scenarios.add_argument("file", help="the rig file (TOML)")
    scenarios.add_argument("--write", required=True, metavar="DIR",
                           help="directory to write them into")
    scenarios.set_defaults(func=_scenarios)


def _check(args: argparse.Namespace) -> int:
    from hil.ownrig.check import check_rig_file

    report = check_rig_file(args.file)
    print("\n".join(report.lines))
    print("hil: rig file OK")
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    from hil.ownrig.rig import rig_class
    from hil.ownrig.scenarios import scenario_toml, suite_scenarios

    cls = rig_class(args.file)
    out = Path(args.write)
    out.mkdir(parents=True, exist_ok=True)
    for scenario in suite_scenarios(cls):
        path = out / f"{scenario.name}.toml"
        path.write_text(scenario_toml(scenario), encoding="utf-8")
        print(path)
    return 0
