"""``hil rig check``: a rig file against its FMU (fmpy's validation) and its DBC, before any run.

Everything a run would find later is found here: the file's keys and values, the FMU's model
description (``fmpy.validation.validate_fmu``), every device's messages, signals, nodes and
units against the DBC, every FMU variable's name and causality, that the FMU instantiates with
the file's parameters and steps, and that the rig's scenario files fit the rig.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hil.errors import ConfigError
from hil.ownrig.fmu import FmuPlant
from hil.ownrig.plan import RigPlan, binding_path


def validate_fmu_file(path: Path, source: str) -> None:
    """fmpy's validation of the FMU's model description; its problems refuse the rig file.

    Raises
    ------
    ConfigError
        Naming the rig file's ``fmu.path`` and fmpy's first problems.
    """
    from fmpy.validation import validate_fmu

    try:
        problems = validate_fmu(str(path))
    except Exception as exc:  # fmpy raises plain Exceptions for unreadable archives
        raise ConfigError(f"fmpy cannot validate {path.name}: {exc}", path=source,
                          key="fmu.path") from exc
    if problems:
        shown = "; ".join(str(p).strip() for p in problems[:3])
        more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
        raise ConfigError(f"fmpy finds {len(problems)} problem(s) in {path.name}: "
                          f"{shown}{more}", path=source, key="fmu.path")


@dataclass(frozen=True)
class CheckReport:
    """What ``hil rig check`` prints of a rig file that passed."""

    lines: tuple[str, ...]


def try_instance(plan: RigPlan) -> None:
    """Instantiate the FMU with the file's parameters and take one step.

    Raises
    ------
    ConfigError
        The FMU refuses a parameter, its initialisation or its first step (naming
        ``fmu.parameters`` and fmpy's word).
    """
    spec = plan.loaded.spec
    try:
        plant = FmuPlant(plan.fmu, plan.loaded.fmu_parameters, spec.fmu.step_ms / 1000.0,
                         plan.watched())
    except ConfigError:
        raise
    except Exception as exc:  # fmpy's FMICallException and the like
        raise ConfigError(f"the FMU refuses its parameters or initialisation: {exc}",
                          path=plan.loaded.source, key="fmu.parameters") from exc
    try:
        plant.advance(1, spec.fmu.step_ms / 1000.0)
        plant.values()
    except Exception as exc:
        raise ConfigError(f"the FMU fails its first step of {spec.fmu.step_ms:g} ms: {exc}",
                          path=plan.loaded.source, key="fmu.step_ms") from exc
    finally:
        plant.close()


def _source(spec: object) -> str:
    fmu, inp = getattr(spec, "fmu", ""), getattr(spec, "input", "")
    if fmu or inp:
        return str(fmu or inp)
    return "counter" if getattr(spec, "counter", False) else f"{getattr(spec, 'value', 0.0):g}"


def check_rig_file(path: str | Path) -> CheckReport:
    """Check a rig file completely (see the module); the summary of a file that passes.

    Raises
    ------
    ConfigError
        The first problem, naming the file and the key.
    """
    from hil.ownrig.rig import rig_class

    cls = rig_class(path)
    plan = cls.plan()
    try_instance(plan)
    for name, _ in cls.scenario_names():
        cls.load_scenario(name)
    spec = plan.loaded.spec
    fmu = plan.fmu
    lines = [f"rig {spec.name}: {plan.loaded.path}",
             f"  FMU {fmu.path.name}: FMI {fmu.fmi_version} co-simulation, model "
             f"{fmu.md.modelName!r}, fmpy validation: no problems; step {spec.fmu.step_ms:g} ms",
             f"  DBC {plan.loaded.dbc.name}: controller node {spec.dut_node}, SYNC every "
             f"{spec.control_period_ms:g} ms"]
    for m in plan.sent:
        period = f"every {m.period_s * 1000:g} ms" if m.period_s else "on change"
        lines.append(f"  {m.device} sends {m.message} (0x{m.frame_id:X}) {period}: "
                     + ", ".join(f"{s.signal} <- {_source(s.spec)}" for s in m.sent))
    for m in plan.received:
        lines.append(f"  {m.device} takes {m.message} (0x{m.frame_id:X}): "
                     + ", ".join(f"{r.signal} -> {r.target.text}" for r in m.received))
    for name, c in plan.controlled.items():
        lines.append(f"  controlled {name}: target {c.target}, sensed {c.sensed}, truth "
                     f"{c.truth.text} [{c.unit}], band +/-{c.band:g}")
    lines.append(f"  binding (generated): {binding_path(plan)}")
    scenarios = cls.scenario_names()
    if scenarios:
        lines.append(f"  scenarios: {', '.join(n for n, _ in scenarios)}")
    return CheckReport(tuple(lines))
