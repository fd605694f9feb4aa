"""The examples in the package's docstrings stay true."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["arm", "cia402", "cia402_objects", "cia402_states", "config", "frames",
           "gnss_serial", "motion_profile", "nmea", "physics", "sensors"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(f"plant_emulators.sowing_depth.{name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
