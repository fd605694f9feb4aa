"""Build the fertilizer plant FMU: generate its start values and model description, compile
the C core with the Reference-FMUs skeleton (CMake), zip the FMU."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hil.errors import ConfigError, HilError
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fmu_export.model_description import MODEL_IDENTIFIER, fmi2, fmi3
from plant_emulators.fmu_export.variables import (
    ROWS,
    check_against_header,
    run_draws,
    start_values_header,
    variables,
)

NATIVE = Path(__file__).parent / "native"
#: the fertilizer rig's physics step (the FMU's fixed step, FIXED_SOLVER_STEP in config.h)
STEP_S = 0.001
PLATFORMS = {2: "linux64", 3: "x86_64-linux"}


def documentation(vs: list[Any]) -> str:
    """The FMU's ``documentation/variables.md``: every variable with unit and causality."""
    lines = ["# agrihil fertilizer plant: variables", "",
             "| name | causality | unit | start | description |", "|---|---|---|---|---|"]
    lines += [f"| `{v.name}` | {v.causality} | {v.unit} | "
              f"{'' if v.start is None else v.start!r} | {v.description} |" for v in vs]
    return "\n".join(lines) + "\n"


def export_fmu(out: Path, *, fmi_version: int = 3, seed: int = 0,
               overrides: Mapping[str, Any] | None = None, source: str = "",
               third_party: Path | None = None) -> Path:
    """Build the fertilizer plant FMU into ``out``.

    Parameters
    ----------
    out : Path
        The ``.fmu`` file to write.
    fmi_version : {2, 3}
        FMI 2.0 or FMI 3.0 co-simulation.
    seed : int
        The run whose draws (row gains, flute phases, density offset and wander) are the
        draws' start values, and the FMU noise generator's seed.
    overrides : mapping, optional
        Overrides of ``rig.toml`` (as a profile's ``[rig]``).

    Raises
    ------
    ConfigError
        A configuration the FMU cannot carry (other than four rows), a bad FMI version.
    HilError
        The build failed (CMake's output in the message).
    """
    if fmi_version not in PLATFORMS:
        raise ConfigError(f"FMI version must be 2 or 3, got {fmi_version}", key="--fmi")
    config = load_rig_config(overrides=overrides, source=source)
    if config.meter.rows != ROWS:
        raise ConfigError(f"the plant FMU has {ROWS} rows; the config has "
                          f"{config.meter.rows}", key="meter.rows")
    vs = variables(config, run_draws(config, seed), seed)
    check_against_header(vs)
    from hil import __version__

    with tempfile.TemporaryDirectory(prefix="agrihil-fmu-export-") as tmp:
        work = Path(tmp)
        (work / "gen").mkdir()
        (work / "gen" / "start_values.h").write_text(start_values_header(vs))
        args = ["cmake", "-S", str(NATIVE), "-B", str(work / "build"),
                f"-DFMI_VERSION={fmi_version}", f"-DGENERATED={work / 'gen'}",
                "-DCMAKE_BUILD_TYPE=Release"]
        if third_party is not None:
            args.append(f"-DTHIRD_PARTY={third_party}")
        for step in (args, ["cmake", "--build", str(work / "build")]):
            done = subprocess.run(step, capture_output=True, text=True)
            if done.returncode != 0:
                raise HilError(f"building the plant FMU failed ({' '.join(step[:2])}):\n"
                               f"{(done.stdout + done.stderr)[-3000:]}")
        library = work / "build" / f"{MODEL_IDENTIFIER}.so"
        describe = fmi3 if fmi_version == 3 else fmi2
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = out.with_name(out.name + ".partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml", describe(vs, STEP_S, __version__))
            fmu.write(library, f"binaries/{PLATFORMS[fmi_version]}/{MODEL_IDENTIFIER}.so")
            fmu.writestr("documentation/variables.md", documentation(vs))
        shutil.move(partial, out)
    return out
