"""The sowing-depth modules import one way: the rig knows its built-in controller, not back."""

from __future__ import annotations

import subprocess
import sys


def _modules_after_import(module: str) -> set[str]:
    code = f"import sys, {module}; print('\\n'.join(sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    return set(out.split())


def test_controllers_do_not_import_the_rig() -> None:
    loaded = _modules_after_import("plant_emulators.sowing_depth.controllers")
    assert "plant_emulators.sowing_depth.rig" not in loaded


def test_rig_offers_its_builtin_controller() -> None:
    from plant_emulators.sowing_depth.controllers import PiDepthController
    from plant_emulators.sowing_depth.frames import EDS_PATH
    from plant_emulators.sowing_depth.rig import EDS, SowingDepthRig

    assert SowingDepthRig.builtin_controllers() == {"pi": PiDepthController}
    assert EDS == EDS_PATH and EDS.is_file()
