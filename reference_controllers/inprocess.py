"""The reference controllers as in-process DUTs, for DUT profiles' ``launch.inprocess``.

Each factory takes the profile's ``[parameters]`` as keyword arguments and returns the same
controller object the daemon runs, stepping on SYNC (lockstep on the inline bus).
"""

from __future__ import annotations

from hil.dut import Controller
from reference_controllers.params import ParamError, ParamValue
from reference_controllers.registry import make_controller


def _make(name: str, params: dict[str, ParamValue]) -> Controller:
    try:
        return make_controller(name, params, step_on_sync=True)
    except ParamError as exc:
        raise ValueError(str(exc)) from exc


def fertilizer_piecewise_pid(**params: ParamValue) -> Controller:
    return _make("fertilizer-piecewise-pid", params)


def fertilizer_piecewise_pid_isobus(**params: ParamValue) -> Controller:
    return _make("fertilizer-piecewise-pid-isobus", params)


def fertilizer_open_loop(**params: ParamValue) -> Controller:
    return _make("fertilizer-open-loop", params)


def sowing_depth_fuzzy_pid(**params: ParamValue) -> Controller:
    return _make("sowing-depth-fuzzy-pid", params)


def sowing_depth_fuzzy_pid_isobus(**params: ParamValue) -> Controller:
    return _make("sowing-depth-fuzzy-pid-isobus", params)


def sowing_depth_dp200(**params: ParamValue) -> Controller:
    return _make("sowing-depth-dp200", params)
