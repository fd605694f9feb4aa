"""The rig base class: physics plus devices; the runner does stepping, frames and recording."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import can
import numpy as np

from hil.errors import ConfigError
from hil.rig.device import Device
from hil.rig.scenario import Scenario, load_scenario


class _ReadWatched:
    """A dataclass field that remembers it was read (``<name>_read`` on the instance).

    A descriptor-typed field (see :mod:`dataclasses`): the class-level lookup gives the
    default, an instance's lookup returns the value and sets the flag.
    """

    def __init__(self, default: Any = None) -> None:
        self.default = default

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot, self.flag = f"_{name}", f"{name}_read"

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self.default
        obj.__dict__[self.flag] = True
        return obj.__dict__.get(self.slot, self.default)

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.slot] = value


@dataclass
class RigContext:
    """What a rig gets when it is built for one run."""

    seed: int
    rng: np.random.Generator
    #: record a notable thing that happened (fault injected, DUT heartbeat lost …)
    note: Callable[[float, str, str], None] = field(default=lambda t, kind, detail: None)
    #: overrides of the rig's packaged config (a DUT profile's ``[rig]`` table)
    config_overrides: Mapping[str, Any] = field(default_factory=dict)
    #: where those overrides come from (named in config errors)
    config_source: str = ""
    #: the scenario the rig is built for (a rig that plays an ISOBUS tractor reads its
    #: ``tractor`` table); None: a rig built outside a run. Reading it sets
    #: ``scenario_read``: such a rig may have shaped its state by the scenario's events, so
    #: its runs are never held for later runs with the same prefix (:mod:`hil.rig.checkpoint`)
    scenario: Scenario | None = _ReadWatched()  # type: ignore[assignment]

    @property
    def scenario_read(self) -> bool:
        """Whether the rig read :attr:`scenario` (see there)."""
        return bool(self.__dict__.get("scenario_read", False))

    @property
    def scenario_tractor(self) -> Any:
        """The scenario's ``tractor`` table, read without setting :attr:`scenario_read`.

        None without one or outside a run. A held run's prefix key holds all of its scenario
        but the events (:func:`hil.rig.checkpoint.prefix_key`), so a rig built from its tractor
        table alone may still be held.
        """
        scenario = self.__dict__.get("_scenario")
        return getattr(scenario, "tractor", None) if scenario is not None else None


class Rig(ABC):
    """A plant emulator on the bus: physics plus the devices that speak for it.

    Subclasses fill the physics (:meth:`advance`), the devices, the declared inputs and faults,
    and the trace row. Everything else (stepping, frames, recording) is the runner's
    (:func:`~hil.rig.runner.run_scenario`).

    Parameters
    ----------
    ctx : RigContext
        The run's seed, random generator, note function and config overrides.
    """

    #: the name the registry knows the rig by
    name: str = "rig"
    physics_period_s: float = 0.001
    #: control period the DUT is paced at in lockstep (SYNC every this many seconds)
    control_period_s: float = 0.1
    #: how often the traces get a row
    trace_period_s: float = 0.01
    #: the bit rate of the rig's bus (ISO 11783: 250 kbit/s): the embedded software bus is
    #: paced at it when a scenario loads the bus
    bitrate_bps: int = 250_000
    #: scenario inputs the rig takes: name → unit
    inputs: ClassVar[dict[str, str]] = {}
    #: faults the rig can inject: name → what it does
    faults: ClassVar[dict[str, str]] = {}

    def __init__(self, ctx: RigContext) -> None:
        self.ctx = ctx
        self.devices: list[Device] = []

    @classmethod
    def load_config(cls, overrides: Mapping[str, Any] | None = None, *,
                    source: str = "") -> object:
        """The rig's packaged config with ``overrides`` applied, validated.

        Rigs without a config accept no overrides.

        Parameters
        ----------
        overrides : mapping, optional
            Overrides of the packaged config (a DUT profile's ``[rig]`` table).
        source : str, optional
            Where the overrides come from, named in errors.

        Returns
        -------
        object
            The rig's config object (None for a rig without a config).

        Raises
        ------
        ConfigError
            An override is unknown or invalid (naming ``source`` and the key).
        """
        if overrides:
            raise ConfigError(f"the {cls.name} rig takes no config overrides", path=source,
                              key="rig")
        return None

    # --- what subclasses provide ------------------------------------------------------
    @abstractmethod
    def advance(self, n: int, dt: float) -> None:
        """Step the physics ``n`` times by ``dt``; must equal ``n`` single steps exactly."""

    @abstractmethod
    def set_input(self, name: str, value: float, time_s: float) -> None:
        """Apply a scenario input (a setpoint, the ground speed …)."""

    @abstractmethod
    def set_fault(self, name: str, active: bool, target: int | None, time_s: float) -> None:
        """Inject (``active``) or clear a fault."""

    #: True: after SYNC the step waits for any one of :meth:`command_ids`, not all of them
    await_any_command: bool = False

    @abstractmethod
    def command_ids(self) -> frozenset[int]:
        """The DUT's command frames the lockstep step waits for after each SYNC."""

    @abstractmethod
    def trace_signals(self) -> dict[str, tuple[float, str]]:
        """Name → (value now, unit) for every traced signal; the same names every call."""

    def trace_row(self) -> Sequence[float]:
        """The values of :meth:`trace_signals`, in its order, without the names and units.

        The runner records a row with this every trace period (100 rows a second): rigs may
        override it to skip building the dict, as long as it returns the same values in the
        same order (and has the same side effects) as :meth:`trace_signals`.
        """
        return [value for value, _ in self.trace_signals().values()]

    # --- optional -----------------------------------------------------------------------
    def admits(self, msg: can.Message) -> bool:
        """Whether a received frame reaches the rig's nodes at all (False: a cut wire)."""
        return True

    def on_dut_frame(self, msg: can.Message, time_s: float) -> None:
        """Any frame that no device claimed (the DUT's own status frames, say)."""
        return None

    def truth(self) -> dict[str, object]:
        """Ground truth at the end of the run (grams per row, depth statistics …)."""
        return {}

    def truth_arrays(self) -> dict[str, np.ndarray]:
        """Ground truth as arrays (depth per row along the run …), saved as ``truth.npz``."""
        return {}

    def physics_engines(self) -> dict[str, str]:
        """Which implementation ran each model (``{"plant": "native", ...}``), for the record.

        The engines give the same floats, so this tells how the run was computed, not what it
        computed (see :mod:`plant_emulators.engine`). Empty: one Python implementation.
        """
        return {}

    def dut_environment(self) -> dict[str, str]:
        """Environment a DUT process needs besides the bus (a serial port's path, say)."""
        return {}

    #: panels of ``hil run --plot``: (title, [trace names])
    plot_groups: ClassVar[list[tuple[str, list[str]]]] = []

    @classmethod
    def builtin_controllers(cls) -> dict[str, Callable[[], object]]:
        """Minimal in-process controllers shipped with the rig (``--dut builtin:NAME``)."""
        return {}

    def close(self) -> None:
        """Release resources (serial ports, …)."""
        return None

    def ready_to_hold(self) -> bool:
        """Whether a copy of this process now would continue the run exactly.

        True only when all of the rig's state is in the process or as :meth:`resume_held`
        restores it: a run is held there for later runs with the same prefix
        (:mod:`hil.rig.checkpoint`). False (the default): the rig is never held. A rig that
        read its context's scenario is never held either, whatever this says: its state at
        the first event may depend on the events that follow it (the runner checks
        :attr:`RigContext.scenario_read`).
        """
        return False

    def resume_held(self) -> None:
        """In a copy resumed from a checkpoint: restore what lives outside the process.

        As it was when :meth:`ready_to_hold` said True (an empty serial line, say); the
        process's own state is the checkpoint's.
        """
        return None

    @classmethod
    def scenario_dir(cls) -> Path:
        """The directory of the rig's packaged scenarios (``*.toml``).

        Raises
        ------
        NotImplementedError
            The rig ships no scenarios (subclasses override this).
        """
        raise NotImplementedError

    @classmethod
    def scenario_names(cls) -> list[tuple[str, str]]:
        """(name, description) of every packaged scenario."""
        out = []
        for path in sorted(cls.scenario_dir().glob("*.toml")):
            scenario = load_scenario(path)
            out.append((scenario.name, scenario.description))
        return out

    @classmethod
    def load_scenario(cls, name_or_path: str) -> Scenario:
        """A packaged scenario by name, or a scenario file by path; checked against the rig."""
        path = Path(name_or_path)
        if not path.suffix:
            path = cls.scenario_dir() / f"{name_or_path}.toml"
            if not path.exists():
                names = ", ".join(n for n, _ in cls.scenario_names())
                raise ConfigError(f"no scenario {name_or_path!r} for rig {cls.name}; "
                                  f"available: {names}", key="scenario")
        scenario = load_scenario(path)
        if scenario.rig != cls.name:
            raise ConfigError(f"scenario is for rig {scenario.rig!r}, not {cls.name!r}",
                              path=str(path), key="rig")
        scenario.check_against(cls.inputs, cls.faults, path=str(path))
        return scenario
