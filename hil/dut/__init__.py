"""Controllers under test (DUTs) and how the rig runs them."""

from hil.dut.base import DutError, DutRunner
from hil.dut.inprocess import Controller, InProcessDut

__all__ = ["Controller", "DutError", "DutRunner", "InProcessDut"]
