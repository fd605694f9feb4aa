"""``hil fmu``: agrihil's plants as Functional Mock-up Units.

    hil fmu export fertilizer --out fertilizer-plant.fmu
    hil fmu export fertilizer --out plant.fmu --fmi 2 --seed 7 --rig-override meter.flutes=10

``export`` builds the rig's plant (the C core of its native engine behind the Reference-FMUs
skeleton, CMake) as an FMI 3.0 co-simulation FMU for linux64 at ``--out``, and with ``--fmi
both`` (the default) an FMI 2.0 one beside it (``NAME-fmi2.fmu``); rig.toml's parameters
(with ``--rig-override``), the draws of the run with ``--seed`` and the seed are its
parameters. Exit 0 with the FMUs written, 2 on a bad option or a failed build. The sowing-depth
rig has no export yet (docs/guide/plant-fmu-export.md says what its physics lacks).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hil.errors import ConfigError

EXPORTABLE = ("fertilizer",)


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    fmu = subparsers.add_parser("fmu", help="export a rig's plant as an FMU")
    sub = fmu.add_subparsers(dest="fmu_command", metavar="ACTION")
    sub.required = True
    export = sub.add_parser("export", help="build a rig's plant as FMI 2.0/3.0 co-simulation "
                                           "FMUs (linux64)")
    export.add_argument("rig", help=f"the rig ({', '.join(EXPORTABLE)})")
    export.add_argument("--out", required=True, help="the FMU to write (FMI 3.0)")
    export.add_argument("--fmi", choices=("2", "3", "both"), default="both",
                        help="FMI version(s) (default: both; FMI 2.0 as NAME-fmi2.fmu)")
    export.add_argument("--seed", type=int, default=0,
                        help="the run whose draws start the FMU's draw parameters, and its "
                             "noise generator's seed (default: 0)")
    export.add_argument("--rig-override", metavar="KEY=VALUE", action="append", default=[],
                        help="override a rig.toml parameter (dotted key, TOML value)")
    export.set_defaults(func=_export)


def _export(args: argparse.Namespace) -> int:
    from hil.campaign.overrides import parse_overrides
    from plant_emulators.fmu_export.build import export_fmu

    rig = args.rig.replace("-", "_")
    if rig not in EXPORTABLE:
        raise ConfigError(f"no FMU export for the {args.rig} rig (exportable: "
                          f"{', '.join(EXPORTABLE)}; docs/guide/plant-fmu-export.md)",
                          key="rig")
    if not 0 <= args.seed < 2**31:
        raise ConfigError(f"the seed is an FMU Int32 parameter: 0 .. 2^31-1, got {args.seed}",
                          key="--seed")
    out = Path(args.out)
    if out.suffix != ".fmu":
        raise ConfigError(f"{out} does not end in .fmu", key="--out")
    overrides = parse_overrides(args.rig_override, rig=rig) if args.rig_override else {}
    versions = (3, 2) if args.fmi == "both" else (int(args.fmi),)
    for version in versions:
        path = out if version == 3 or args.fmi == "2" else out.with_name(
            f"{out.stem}-fmi2.fmu")
        export_fmu(path, fmi_version=version, seed=args.seed, overrides=overrides,
                   source="--rig-override")
        print(f"hil: wrote {path} (FMI {version}.0 co-simulation, linux64)")
    return 0
