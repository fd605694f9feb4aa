"""The data of one scenario run: the options it is made with and the result it gives.

Pure data, no loop: :mod:`hil.rig.runner` makes runs of them and :mod:`hil.rig.checkpoint`
carries them between a run and the forked copy that continues it, neither importing the other.
Both classes are importable from :mod:`hil.rig` and :mod:`hil.rig.runner` as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hil.record.traces import load_traces


@dataclass(frozen=True)
class RunOptions:
    """How one scenario run is carried out: where it writes, its clock, bus, seed and limits.

    Parameters
    ----------
    out_dir : Path
        Where the run's record, traces and bus log go.
    clock : str
        ``"lockstep"`` (the rig waits for the DUT every control period) or ``"realtime"``.
    bus : str
        ``"softbus"`` starts an embedded software bus, ``"virtual"`` an in-process bus;
        anything else is a bus spec (:func:`hil.bus.open_bus`).
    seed : int or None
        The run's seed; None: the scenario's own.
    step_timeout_s : float
        How long the DUT may stay silent before it counts as stopped answering: the SYNC
        barrier's timeout in lockstep, the longest gap between its command frames in real time.
    csv : bool
        Also write the traces as CSV.
    rig_config : dict
        Overrides of the rig's packaged config (a DUT profile's ``[rig]``).
    rig_config_source : str
        Where those overrides come from, named in errors.
    max_dut_frames_per_period : int or None
        More frames than this from the DUT within one control period ends the run (a DUT that
        floods the bus); a profile's ``timing.max_frames_per_period``. None: no limit.
    extra_meta : dict
        More entries for the record's metadata (the DUT's identity, the test's node id).
    """

    out_dir: Path
    clock: str = "lockstep"
    bus: str = "softbus"
    seed: int | None = None
    step_timeout_s: float = 2.0
    csv: bool = False
    rig_config: dict[str, Any] = field(default_factory=dict)
    rig_config_source: str = ""
    max_dut_frames_per_period: int | None = None
    extra_meta: dict[str, Any] = field(default_factory=dict)
    #: False: no bus log files (a campaign's measurements-only sample)
    record_bus: bool = True
    #: the DUT's command frames as its profile lists them (``wiring.command_ids``; empty: not
    #: listed): checked against the frames the rig waits for once the DUT commands
    #: (:class:`~hil.rig.runner.CommandIdsError`), so a master that configures its slaves'
    #: RPDOs may list where it puts them
    command_ids: frozenset[int] = frozenset()
    #: where ``command_ids`` comes from (the profile), named in the error
    command_ids_source: str = ""
    #: False: the traces and truth arrays stay in memory (:meth:`RunResult.traces`,
    #: :meth:`RunResult.truth_arrays`) and no ``traces.npz``/``truth.npz`` is written (a
    #: campaign's measurements-only sample: compressing and reading them back was ~1.5 s of
    #: CPU per fertilizer sample)
    save_traces: bool = True


@dataclass
class RunResult:
    """What :func:`~hil.rig.runner.run_scenario` returns: the run's record and where it was written.

    Parameters
    ----------
    record : dict
        The run's final record (as in its ``record.json``).
    out_dir : Path
        The run's directory.
    wall_s : float
        Wall-clock duration of the run, in seconds.
    sim_s : float
        Simulated time the run reached, in seconds.
    """

    record: dict[str, Any]
    out_dir: Path
    wall_s: float
    sim_s: float
    #: the traces (arrays, units) and truth arrays held in memory or read once from the files
    _traces: tuple[dict[str, np.ndarray], dict[str, str]] | None = field(
        default=None, repr=False, compare=False)
    _truth: dict[str, np.ndarray] | None = field(default=None, repr=False, compare=False)

    def traces(self) -> tuple[dict[str, np.ndarray], dict[str, str]]:
        """The run's traces: (arrays by name, ``time_s`` included; units by name).

        Kept in memory by a run that saved none, else read from ``traces.npz`` once.
        """
        if self._traces is None:
            self._traces = load_traces(self.out_dir / "traces.npz")
        return self._traces

    def truth_arrays(self) -> dict[str, np.ndarray]:
        """The rig's truth arrays (``truth.npz``; empty when the rig has none).

        Kept in memory or read once, as :meth:`traces`.
        """
        if self._truth is None:
            path = self.out_dir / "truth.npz"
            if path.exists():
                with np.load(path) as data:
                    self._truth = {k: data[k] for k in data.files}
            else:
                self._truth = {}
        return self._truth

    @property
    def verdict(self) -> str:
        """The run's verdict (the record's ``verdict``)."""
        return str(self.record["verdict"])

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second (infinite for a zero wall time)."""
        return self.sim_s / self.wall_s if self.wall_s > 0 else math.inf
