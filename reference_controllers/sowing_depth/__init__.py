"""[D]'s sowing-depth controller: the fuzzy self-tuning PID core and the CAN adapter."""

from reference_controllers.sowing_depth.fuzzy_pid import FuzzyPid, FuzzyPidParams

__all__ = ["FuzzyPid", "FuzzyPidParams"]
