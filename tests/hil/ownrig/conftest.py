"""The worked example's rig, built once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.rig.registry import RIG_FILES_ENV
from tests.hil.ownrig.example import example_copy


@pytest.fixture(autouse=True)
def _rig_files_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """A test that registers a rig file leaves the environment as it found it (its temporary
    rig file must not reach the processes later tests start)."""
    monkeypatch.delenv(RIG_FILES_ENV, raising=False)


@pytest.fixture(scope="session")
def motor_rig_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The motor-and-meter rig file, its FMU built from the Reference-FMUs sources."""
    return example_copy(tmp_path_factory.mktemp("own-rig") / "motor-meter")
