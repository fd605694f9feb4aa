"""[F]'s fertilizer-flow controllers: the cores (no CAN) and the CAN adapter."""

from reference_controllers.fertilizer.piecewise_pid import (
    OpenLoop,
    PiecewisePid,
    PiecewisePidParams,
    feedforward_volts,
)

__all__ = ["OpenLoop", "PiecewisePid", "PiecewisePidParams", "feedforward_volts"]
