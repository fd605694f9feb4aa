"""The worked example's rig, built once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.hil.ownrig.example import example_copy


@pytest.fixture(scope="session")
def motor_rig_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The motor-and-meter rig file, its FMU built from the Reference-FMUs sources."""
    return example_copy(tmp_path_factory.mktemp("own-rig") / "motor-meter")
