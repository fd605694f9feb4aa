"""Replay a recorded fertilizer run's commands through the exported plant FMU (fmpy).

The rig traces the drive's command voltage every 10 ms (``command_v``: the value the plant
stepped with since the row before); the FMU is stepped 10 ms at a time with it, its draws set
to the run's (:func:`~plant_emulators.fmu_export.variables.run_draws` of the run's seed) and
rig.toml's parameters to the run's config, and its outputs are read at the rows' times.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fmu_export.variables import CONFIG_PARAMETERS, ROWS, run_draws

#: the truth traces of the fertilizer rig the FMU has as outputs (same names)
TRUTH = ("shaft_speed_rpm", "motor_speed_rpm", "motor_current_a", "delivered_total_g",
         *(f"{name}_{r}_{unit}" for r in range(1, ROWS + 1)
           for name, unit in (("flow_at_meter", "gps"), ("flow_at_sensor", "gps"),
                              ("delivered", "g"))))


def run_parameters(overrides: Mapping[str, Any] | None, seed: int) -> dict[str, float]:
    """The FMU's real parameters of a run: its config's rig.toml values and its draws."""
    config = load_rig_config(overrides=overrides)
    out = {f"{section}.{key}": float(getattr(getattr(config, section), key))
           for section, keys in CONFIG_PARAMETERS.items() for key, _ in keys}
    draws = run_draws(config, seed)
    for r in range(ROWS):
        out[f"run.row_gain_{r + 1}"] = draws.row_gain[r]
        out[f"run.flute_offset_{r + 1}"] = draws.flute_offset[r]
    out["run.density_offset_frac"] = draws.density_offset_frac
    out["run.density_wander"] = draws.density_wander
    return out


def replay(fmu: Path, traces: Mapping[str, np.ndarray], *, seed: int,
           overrides: Mapping[str, Any] | None = None) -> dict[str, np.ndarray]:
    """The FMU's outputs at the trace rows' times, driven by the traces' ``command_v``."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(fmu))
    v3 = md.fmiVersion.startswith("3")
    cls = FMU3Slave if v3 else FMU2Slave
    slave = cls(guid=md.guid, unzipDirectory=unzipped,
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="replay")
    slave.instantiate()
    set_real = slave.setFloat64 if v3 else slave.setReal
    get_real = slave.getFloat64 if v3 else slave.getReal
    if v3:
        slave.enterInitializationMode(startTime=0.0)
    else:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
    params = run_parameters(overrides, seed)
    set_real([vr[k] for k in params], list(params.values()))
    slave.exitInitializationMode()
    times = np.asarray(traces["time_s"], dtype=float)
    command = np.asarray(traces["command_v"], dtype=float)
    refs = [vr[name] for name in TRUTH]
    out = np.zeros((len(times), len(TRUTH)))
    t = 0.0
    try:
        for k, t_next in enumerate(times):
            if t_next > t:
                set_real([vr["command_v"]], [float(command[k])])
                slave.doStep(t, float(t_next) - t)
                t = float(t_next)
            out[k] = get_real(refs)
    finally:
        slave.terminate()
        slave.freeInstance()
    return {name: out[:, i] for i, name in enumerate(TRUTH)}
