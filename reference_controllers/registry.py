"""The reference controllers by name, as the daemon and DUT profiles know them.

=========================  ==============================================  ==============
name                       what                                            control period
=========================  ==============================================  ==============
fertilizer-piecewise-pid   [F] piecewise PID, ``mode`` physical (default)  100 ms
                           or paper-literal
fertilizer-open-loop       [F] constant-speed baseline (feedforward only)  100 ms
fertilizer-piecewise-pid-  [F] piecewise PID as an ISOBUS implement: rate  100 ms
isobus                     and sections from a TC, speed from the TECU
fertilizer-rc400           [F] piecewise PID speaking the RC-400's own      100 ms
                           database (docs/examples/byo-fertilizer)
sowing-depth-fuzzy-pid     [D] fuzzy self-tuning PID, CiA 402 master       10 ms
sowing-depth-dp200         [D] fuzzy PID speaking the DP-200's own         10 ms
                           database, remapping the drive's PDOs at boot
                           (docs/examples/byo-depth)
=========================  ==============================================  ==============
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from hil.dut import Controller
from reference_controllers.params import ParamError, ParamValue


@dataclass(frozen=True)
class ControllerKind:
    name: str
    description: str
    period_s: float
    make: Callable[[dict[str, ParamValue], bool], Controller]


def _piecewise(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.fertilizer.adapter import FlowController

    mode = str(params.pop("mode", "physical"))
    if mode not in ("physical", "paper-literal"):
        raise ParamError(f"parameter 'mode' must be physical or paper-literal, got {mode!r}")
    return FlowController(mode, params, step_on_sync=step_on_sync)


def _piecewise_isobus(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.fertilizer.isobus_mode import IsobusFlowController

    mode = str(params.pop("mode", "physical"))
    if mode not in ("physical", "paper-literal"):
        raise ParamError(f"parameter 'mode' must be physical or paper-literal, got {mode!r}")
    return IsobusFlowController(mode, params, step_on_sync=step_on_sync)


def _piecewise_isobus_vt(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.fertilizer.isobus_vt import IsobusVtFlowController

    mode = str(params.pop("mode", "physical"))
    if mode not in ("physical", "paper-literal"):
        raise ParamError(f"parameter 'mode' must be physical or paper-literal, got {mode!r}")
    return IsobusVtFlowController(mode, params, step_on_sync=step_on_sync)


def _open_loop(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.fertilizer.adapter import OpenLoopFlowController

    return OpenLoopFlowController(params=params, step_on_sync=step_on_sync)


def _rc400(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.fertilizer.dbc_adapter import (
        RC400_DATABASE,
        RC400_SIGNALS,
        DbcFlowController,
    )

    return DbcFlowController(RC400_DATABASE, RC400_SIGNALS, params, step_on_sync=step_on_sync)


def _depth(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.sowing_depth.adapter import DepthController

    return DepthController(params, step_on_sync=step_on_sync)


def _depth_isobus(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.sowing_depth.isobus_mode import IsobusDepthController

    return IsobusDepthController(params, step_on_sync=step_on_sync)


def _dp200(params: dict[str, ParamValue], step_on_sync: bool) -> Controller:
    from reference_controllers.sowing_depth.dbc_adapter import (
        DP200_DATABASE,
        DP200_SIGNALS,
        DbcDepthController,
    )

    return DbcDepthController(DP200_DATABASE, DP200_SIGNALS, params, step_on_sync=step_on_sync)


CONTROLLERS: dict[str, ControllerKind] = {k.name: k for k in (
    ControllerKind("fertilizer-piecewise-pid", "[F] piecewise PID (mode physical or "
                   "paper-literal)", 0.1, _piecewise),
    ControllerKind("fertilizer-piecewise-pid-isobus", "[F] piecewise PID as an ISOBUS "
                   "implement (TC rate and sections, TECU speed)", 0.1, _piecewise_isobus),
    ControllerKind("fertilizer-piecewise-pid-isobus-vt", "[F] piecewise PID as an ISOBUS "
                   "implement with its operator interface on the tractor's VT", 0.1,
                   _piecewise_isobus_vt),
    ControllerKind("fertilizer-open-loop", "[F] constant-speed baseline", 0.1, _open_loop),
    ControllerKind("fertilizer-rc400", "[F] piecewise PID on a foreign database (the RC-400 "
                   "of docs/examples/byo-fertilizer)", 0.1, _rc400),
    ControllerKind("sowing-depth-fuzzy-pid", "[D] fuzzy self-tuning PID", 0.01, _depth),
    ControllerKind("sowing-depth-fuzzy-pid-isobus", "[D] fuzzy PID as an ISOBUS implement "
                   "(TC seeding depth, DDI 56)", 0.01, _depth_isobus),
    ControllerKind("sowing-depth-dp200", "[D] fuzzy PID on a foreign database, remapping the "
                   "drive's PDOs at boot (the DP-200 of docs/examples/byo-depth)", 0.01, _dp200),
)}


def make_controller(name: str, params: Mapping[str, ParamValue] | None = None, *,
                    step_on_sync: bool = True) -> Controller:
    """The controller called ``name`` with ``params``.

    Raises
    ------
    ParamError
        Unknown controller name, unknown parameter name, or a bad value (all named).
    """
    kind = CONTROLLERS.get(name)
    if kind is None:
        raise ParamError(f"unknown controller {name!r} (known: {', '.join(CONTROLLERS)})")
    return kind.make(dict(params or {}), step_on_sync)
