"""What ``hil run``/``qualify``/``campaign``/``gate`` do for ``--rig FILE`` (a rig of your own)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hil.errors import ConfigError

#: the package of the standard suites that judge any rig of your own
OWN_SUITES = "test_suites.own_rig"


def register_option_rig(rig: str | None) -> Any:
    """Register ``--rig FILE`` (before any profile naming it is read); None for a rig name.

    Raises
    ------
    ConfigError
        The rig file is refused (naming the file and the key).
    """
    if not rig:
        return None
    from hil.rig.registry import is_rig_file, register_rig_file

    if not is_rig_file(rig):
        return None
    if not Path(rig).is_file():
        raise ConfigError(f"rig file not found: {rig}", key="--rig")
    return register_rig_file(rig)


def check_profile_rig(rig_cls: Any, profile: Any) -> None:
    """A profile qualified with ``--rig FILE`` must be wired to that rig (by its name)."""
    if rig_cls is None:
        return
    if profile.dut.rig.replace("-", "_") != rig_cls.name:
        raise ConfigError(f"the profile is wired to the {profile.dut.rig} rig, --rig "
                          f"{rig_cls.rig_file.name} is the {rig_cls.name} rig ([dut] rig = "
                          f"\"{rig_cls.name}\")", path=str(profile.path), key="dut.rig")


def suite_location_of(rig: str) -> tuple[Path, Path]:
    """The suites of ``rig``: the own-rig suites for a rig file's rig, else the registered."""
    from hil.cli.suites import suite_location
    from hil.rig.registry import rig_file_of

    if rig_file_of(rig) is None:
        return suite_location(rig)
    import importlib.util

    spec = importlib.util.find_spec(OWN_SUITES)
    assert spec is not None and spec.submodule_search_locations
    directory = Path(next(iter(spec.submodule_search_locations))).resolve()
    return directory, directory.parent / "pytest.ini"
