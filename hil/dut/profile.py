"""DUT profiles: one TOML file per controller under test, validated into frozen dataclasses.

A profile says who the DUT is, how to build it, how to start it, how it is wired, its timing,
its parameters and the limits it must meet. Every error names the file and the key; an invalid
profile never starts a run. Layout (``dut_profiles/<rig>-<controller>-<kind>.toml``)::

    [dut]         name, version, build_id, kind (firmware|daemon|inprocess|physical), rig,
                  controller, description
    [build]       firmware only: command (argv), sources (paths hashed into the cache key),
                  artifacts (paths the build must produce)
    [launch]      command (argv) for a process DUT, lockstep_args / realtime_args, env,
                  inprocess ("module:Class", used in lockstep on the inline bus), ready,
                  ready_timeout_s, stop_timeout_s
    [wiring]      node_id, heartbeat_id, command_ids, database, binding
    [timing]      control_period_ms, heartbeat_period_ms, max_frames_per_period
    [parameters]  name = number | string | bool, handed to the controller
    [limits]      "measurement.name" = { low = …, high = …, when = [ { condition = …,
                  high = … }, … ], reason = "…" } (``when``: per-condition limits, first
                  match wins; ``reason``: why a limit looser than the catalogue's default)
    [rig]         overrides of the rig's packaged config for this DUT's installation, e.g.
                  ``flow_sensor = { mode = "sliding" }``: checked by the rig's own loader,
                  applied to every run of this DUT (and recorded in each run's record)
    [campaign]    pass_probability, confidence: what a ``hil campaign`` must demonstrate;
                  sequential_good_probability, sequential_alpha: ``--sequential`` (Wald)
    [fmu]         kind fmu only: path, level (bus|signal), terminal, bus_notifications,
                  variables (FMU variable = rig quantity); see :mod:`hil.dut.fmu`

In ``launch.command`` and ``build.command`` these placeholders are expanded: ``{python}``
(this interpreter), ``{root}`` (the project root), ``{profile_dir}``, ``{build_dir}`` (the
build cache entry of this profile), ``{bus}`` (the bus spec), ``{params}`` (one
``--param key=value`` per parameter, as separate arguments).
"""

from __future__ import annotations

import functools
import hashlib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from hil.condition_limits import ConditionCase, check_band, check_names
from hil.config import check_positive, from_mapping, key_text
from hil.dut.code_identity import code_identity, expand_placeholders, identity_digest
from hil.dut.fmu_section import FmuSection
from hil.dut.paths import PROJECT_ROOT, build_entry
from hil.effective_limits import loosening
from hil.errors import ConfigError
from hil.limits import (
    MEASUREMENTS,
    condition_kinds_of,
    is_conformance,
    known_measurement,
    measurement_names,
)
from hil.validation import check_key

Kind = Literal["firmware", "daemon", "inprocess", "physical", "fmu"]
PROFILE_NAME = re.compile(r"^[a-z0-9]+(-[a-z0-9]+)*$")
PLACEHOLDERS = ("python", "root", "profile_dir", "build_dir", "bus", "params")


@dataclass(frozen=True)
class Identity:
    """The profile's ``[dut]`` table: who the DUT is and which rig it drives.

    Parameters
    ----------
    name : str
        Lower-case words joined by ``-``; the profile's file name without ``.toml``.
    version : str
        The controller's version.
    kind : {"firmware", "daemon", "inprocess", "physical", "fmu"}
        How the rig runs it: a built firmware process, a process, a Python object in the rig's
        process, an ECU on a physical bus the rig does not start, or a Functional Mock-up
        Unit in the rig's process (``[fmu]``).
    rig : str
        The rig it is wired to.
    controller : str
        The controller's name.
    build_id : str, optional
        The build under test (a CI job's commit, say).
    description : str, optional
        One line about it.

    Raises
    ------
    ValueError
        The name is not lower-case words joined by ``-``.
    """

    name: str
    version: str
    kind: Kind
    rig: str
    controller: str
    build_id: str = ""
    description: str = ""

    def __post_init__(self) -> None:
        if not PROFILE_NAME.match(self.name):
            raise ValueError(f"name must be lower-case words joined by '-', got {self.name!r}")


@dataclass(frozen=True)
class Build:
    """The profile's ``[build]`` table (firmware only): how the DUT is built.

    Parameters
    ----------
    command : tuple of str
        The build command (argv, placeholders expanded), not empty.
    sources : tuple of str, optional
        Paths hashed into the build cache key.
    artifacts : tuple of str, optional
        Paths the build must produce.
    timeout_s : float, optional
        How long the build may take, > 0.
    """

    command: tuple[str, ...]
    sources: tuple[str, ...] = ()
    artifacts: tuple[str, ...] = ()
    timeout_s: float = 600.0

    def __post_init__(self) -> None:
        if not self.command:
            raise ValueError("command must not be empty")
        check_positive(self, "timeout_s")


@dataclass(frozen=True)
class Launch:
    """The profile's ``[launch]`` table: how the DUT is started and when it is ready.

    Parameters
    ----------
    command : tuple of str, optional
        The command of a process DUT (argv, placeholders expanded).
    lockstep_args, realtime_args : tuple of str, optional
        Arguments added under each clock.
    env : dict of str to str, optional
        Environment variables of the process.
    inprocess : str, optional
        ``"module:factory"`` (or a class) building the same controller in-process from the
        parameters as keyword arguments (lockstep on the inline bus).
    ready : str, optional
        How the rig knows the DUT is on the bus: its CANopen boot-up frame (``"bootup"``), a
        line on its stdout (``"stdout:<text>"``), or a fixed delay (``"delay"``).
    ready_timeout_s : float, optional
        How long the rig waits for it to be ready, > 0.
    ready_delay_s : float, optional
        The delay of ``ready = "delay"``.
    stop_timeout_s : float, optional
        How long a stop waits for the process to exit, > 0.

    Raises
    ------
    ValueError
        A bad ``ready``, an unknown placeholder, a bad ``inprocess`` or a non-positive timeout.
    """

    command: tuple[str, ...] = ()
    lockstep_args: tuple[str, ...] = ()
    realtime_args: tuple[str, ...] = ()
    env: dict[str, str] = field(default_factory=dict)
    inprocess: str = ""
    ready: str = "bootup"
    ready_timeout_s: float = 10.0
    ready_delay_s: float = 0.5
    stop_timeout_s: float = 3.0

    def __post_init__(self) -> None:
        # ranges from hil.validation.PROFILE_RANGES (the reference page lists them)
        check_key(self, "launch", "ready_timeout_s", "ready_delay_s", "stop_timeout_s")
        if not (self.ready in ("bootup", "delay") or self.ready.startswith("stdout:")):
            raise ValueError(f"ready must be 'bootup', 'delay' or 'stdout:<text>', "
                             f"got {self.ready!r}")
        for arg in (*self.command, *self.lockstep_args, *self.realtime_args):
            for name in re.findall(r"{(\w+)}", arg):
                if name not in PLACEHOLDERS:
                    raise ValueError(f"unknown placeholder {{{name}}} in {arg!r} "
                                     f"(known: {', '.join(PLACEHOLDERS)})")
        if self.inprocess and not re.match(r"^[\w.]+:\w+$", self.inprocess):
            raise ValueError(f"inprocess must be 'module:Class', got {self.inprocess!r}")


@dataclass(frozen=True)
class Wiring:
    """The profile's ``[wiring]`` table: how the DUT sits on the bus.

    Parameters
    ----------
    node_id : int
        Its CANopen node id, 1-127.
    command_ids : tuple of int, optional
        Frames the rig waits for after each SYNC in lockstep (empty: the rig's own choice).
    database : str, optional
        Its CAN database (DBC, KCD, ARXML or SYM), absolute or relative to the project root or
        the profile: bus conformance judges the DUT against it.
    binding : str, optional
        A binding file (TOML, :mod:`hil.contract.binding`) of the rig's quantities to that
        database: the rig then speaks the DUT's frames. Empty: the rig's own database and
        default binding.
    isobus : bool, optional
        The DUT is an ISOBUS implement (ISO 11783): it claims an address and takes its rate
        and section states from the rig's Task Controller (field runs under a TC, the
        ``isobus`` suite), not from the rig's own set-point frames; its 29-bit frames are
        judged by the ISOBUS conformance checks.

    Raises
    ------
    ValueError
        A node id out of range or a command id that is not a CAN identifier.
    """

    node_id: int
    command_ids: tuple[int, ...] = ()
    database: str = ""
    binding: str = ""
    isobus: bool = False

    def __post_init__(self) -> None:
        if not 1 <= self.node_id <= 127:
            raise ValueError(f"node_id must be a CANopen node id 1-127, got {self.node_id}")
        for can_id in self.command_ids:
            if not 0 <= can_id <= 0x1FFFFFFF:
                raise ValueError(f"command id 0x{can_id:X} is not a CAN identifier")

    @property
    def heartbeat_id(self) -> int:
        """The COB-ID of the DUT's heartbeat: 0x700 + node id."""
        return 0x700 + self.node_id


@dataclass(frozen=True)
class Timing:
    """The profile's ``[timing]`` table.

    Parameters
    ----------
    control_period_ms : float
        The period the DUT is stepped at; must equal the rig's SYNC period.
    heartbeat_period_ms : float, optional
        The DUT's heartbeat period.
    max_frames_per_period : int, optional
        More frames than this from the DUT in one control period is a flood (a fault).
    """

    control_period_ms: float
    heartbeat_period_ms: float = 100.0
    max_frames_per_period: int = 50

    def __post_init__(self) -> None:
        check_key(self, "timing", "control_period_ms", "heartbeat_period_ms",
                  "max_frames_per_period")


@dataclass(frozen=True)
class Limit:
    """One entry of the profile's ``[limits]``: the band a measurement must fall in.

    Parameters
    ----------
    low, high : float, optional
        The limits, in the measurement's unit; ``low <= high``.
    marginal : float, optional
        A pass closer than this to a limit is flagged marginal (in the measurement's unit;
        default: 5 % of the span for two-sided limits, 1 % of the limit for one-sided ones).
    when : tuple of tables, optional
        Per-condition limits, tried in order: each a table of conditions (the measurement's
        condition names, each with a value or an array of values) and its own ``low``,
        ``high``, ``marginal``, e.g. ``{ to_mm = 20, high = 2.0 }``; the first whose
        conditions all match gives the limit, else ``low``/``high`` apply (else the catalogue's
        default). Parsed into ``cases`` (:class:`hil.condition_limits.ConditionCase`).
    reason : str, optional
        Why the limit is looser than the catalogue's default (a lower ``low``, a higher
        ``high``, a bound dropped, under any of its conditions): required then, and shown by
        ``hil profile check`` and the report. A tighter limit needs none.

    Raises
    ------
    ValueError
        Neither a limit nor a case given, ``low`` above ``high``, a negative ``marginal``, or a
        case that is not a table of conditions with ``low`` or ``high``.
    """

    low: float | None = None
    high: float | None = None
    marginal: float | None = None
    when: tuple[dict[str, Any], ...] = field(default=(), compare=False, repr=False)
    reason: str = ""
    cases: tuple[ConditionCase, ...] = field(init=False, default=())

    def __post_init__(self) -> None:
        if self.low is None and self.high is None and not self.when:
            raise ValueError("a limit needs low, high, when or a combination")
        check_band(self.low, self.high, self.marginal)
        object.__setattr__(self, "cases", tuple(
            ConditionCase.parse(table, key=f"when[{i}]") for i, table in enumerate(self.when)))


@dataclass(frozen=True)
class CampaignRequirement:
    """``[campaign]``: the pass probability a campaign must demonstrate.

    The campaign passes when the exact (Clopper-Pearson) lower bound of its pass rate, at
    ``confidence``, reaches ``pass_probability``, and fails when the upper bound stays below
    it. ``hil campaign --sequential`` runs Wald's sequential probability ratio test instead,
    between a build at ``pass_probability`` (passed by mistake at most ``1 - confidence`` of
    the time) and a good one at ``sequential_good_probability`` (failed by mistake at most
    ``sequential_alpha`` of the time); both keys are needed only for ``--sequential``.

    Parameters
    ----------
    pass_probability : float
        The pass probability the campaign must demonstrate.
    confidence : float, optional
        The confidence of the exact one-sided bound.
    sequential_good_probability : float, optional
        ``--sequential``: the pass probability of a good build, above ``pass_probability``.
    sequential_alpha : float, optional
        ``--sequential``: how often a good build may be failed by mistake, below
        ``confidence``.
    """

    pass_probability: float
    confidence: float = 0.95
    sequential_good_probability: float | None = None
    sequential_alpha: float | None = None

    def __post_init__(self) -> None:
        # ranges from hil.validation.PROFILE_RANGES (the reference page lists them)
        check_key(self, "campaign", "pass_probability", "confidence")
        if self.sequential_good_probability is not None:
            check_key(self, "campaign", "sequential_good_probability")
            if self.sequential_good_probability <= self.pass_probability:
                raise ValueError(f"sequential_good_probability must be above pass_probability"
                                 f" {self.pass_probability:g}, got "
                                 f"{self.sequential_good_probability!r}")
        if self.sequential_alpha is not None:
            check_key(self, "campaign", "sequential_alpha")
            if self.sequential_alpha >= self.confidence:
                raise ValueError(f"sequential_alpha must be below confidence "
                                 f"{self.confidence:g} (Wald's test needs alpha + beta < 1, "
                                 f"beta = 1 - confidence), got {self.sequential_alpha!r}")


@dataclass(frozen=True)
class DutProfile:
    """A validated DUT profile: one controller under test, as :func:`load_profile` reads it.

    Parameters
    ----------
    dut : Identity
        ``[dut]``.
    wiring : Wiring
        ``[wiring]``.
    timing : Timing
        ``[timing]``.
    launch : Launch, optional
        ``[launch]``.
    build : Build, optional
        ``[build]`` (firmware only).
    parameters : dict, optional
        ``[parameters]``, handed to the controller.
    limits : dict of str to Limit, optional
        ``[limits]`` by measurement name.
    rig_config : dict, optional
        ``[rig]``: overrides of the rig's packaged config for this DUT's wiring (e.g. which
        flow-sensor modules it is wired to), checked by the rig's own config loader.
    campaign : CampaignRequirement, optional
        ``[campaign]``: what ``hil campaign`` must demonstrate (None: no sample may fail).
    fmu : FmuSection, optional
        ``[fmu]`` (kind ``fmu`` only): the FMU and how it is wired (:mod:`hil.dut.fmu`).
    path : Path, optional
        The profile file (set by :func:`load_profile`).
    sha256 : str, optional
        The file's SHA-256 (set by :func:`load_profile`).
    """

    dut: Identity
    wiring: Wiring
    timing: Timing
    launch: Launch = field(default_factory=Launch)
    build: Build | None = None
    parameters: dict[str, float | int | bool | str] = field(default_factory=dict)
    limits: dict[str, Limit] = field(default_factory=dict)
    rig_config: dict[str, Any] = field(default_factory=dict)
    campaign: CampaignRequirement | None = None
    fmu: FmuSection | None = None
    path: Path | None = None
    sha256: str = ""

    @property
    def name(self) -> str:
        """The DUT's name (``[dut] name``)."""
        return self.dut.name

    def limit(self, measurement: str) -> Limit | None:
        """The profile's limit for ``measurement``, or None if it sets none."""
        return self.limits.get(measurement)

    def identity(self) -> dict[str, Any]:
        """The DUT's identity for the record.

        Name, version, the user's ``build_id``, kind, rig, controller, the profile and its
        hash, and ``code``: what identifies the code under test (:meth:`code_identity`).
        """
        return {"name": self.dut.name, "version": self.dut.version,
                "build_id": self.dut.build_id, "kind": self.dut.kind, "rig": self.dut.rig,
                "controller": self.dut.controller,
                "profile": str(self.path) if self.path else "", "profile_sha256": self.sha256,
                "code": self.code_identity()}

    def code_identity(self) -> dict[str, Any]:
        """What identifies the code under test (:mod:`hil.dut.code_identity`).

        The program the DUT's command runs (a firmware's binary once built) with its SHA-256,
        a firmware's source set, and the git revision and dirty flag of the DUT's files.
        """
        where = self.path.resolve().parent if self.path else Path.cwd()
        build: Path | None = None
        sources: list[Path] = []
        digest = ""
        if self.build is not None:
            # as hil.dut.build.source_sha256 hashes them: the cache entry's key
            sources = [_rooted(expand_placeholders(src, profile_dir=where))
                       for src in sorted(self.build.sources)]
            if all(src.exists() for src in sources):
                digest = identity_digest(tuple(self.build.command), tuple(sources))
                build = build_entry(digest)
        argv = [expand_placeholders(a, profile_dir=where, build=build)
                for a in self.launch.command if a != "{params}"]
        built = build is not None and (build / ".built").exists()
        fmu: Path | None = None
        if self.fmu is not None:        # as hil.dut.fmu.fmu_path resolves it
            text = expand_placeholders(self.fmu.path, profile_dir=where, build=build)
            fmu = Path(text) if Path(text).is_absolute() else database_path(text, self.path)
            built = built or "{build_dir}" not in self.fmu.path
        first = self.fmu.path if self.fmu is not None else next(iter(self.launch.command), "")
        return code_identity(kind=self.dut.kind, argv=argv, inprocess=self.launch.inprocess,
                             sources=sources, source_sha256=digest, built=built,
                             shown_as=first if "{build_dir}" in first else "", fmu=fmu)


def load_profile(path: str | Path) -> DutProfile:
    """Read and validate a DUT profile.

    Parameters
    ----------
    path : str or Path
        The profile (TOML).

    Returns
    -------
    DutProfile
        The profile, with its path and the file's SHA-256.

    Raises
    ------
    ConfigError
        The file is missing or unreadable, not TOML, or a key is unknown, missing or invalid,
        including a ``[rig]`` override the rig refuses, a control period other than the rig's and
        an unreadable CAN database (naming the file and the key).
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError as exc:
        raise ConfigError("DUT profile not found", path=str(path)) from exc
    except OSError as exc:
        raise ConfigError(f"cannot read DUT profile: {exc}", path=str(path)) from exc
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=str(path)) from exc
    for reserved in ("path", "sha256", "rig_config"):
        if reserved in data:
            raise ConfigError("unknown key", path=str(path), key=reserved)
    rig_config = data.pop("rig", {})
    if not isinstance(rig_config, dict):
        raise ConfigError("expected a table of rig config overrides", path=str(path), key="rig")
    profile = from_mapping(DutProfile, data, path=str(path))
    _check(profile, str(path))
    rig_config = _with_binding(profile, rig_config, path)
    _check_rig_config(profile.dut.rig, rig_config, str(path))
    _check_control_period(profile, rig_config, str(path))
    _check_database(profile, path)
    loaded = DutProfile(dut=profile.dut, wiring=profile.wiring, timing=profile.timing,
                        launch=profile.launch, build=profile.build,
                        parameters=profile.parameters, limits=profile.limits,
                        rig_config=rig_config, campaign=profile.campaign, fmu=profile.fmu,
                        path=path, sha256=hashlib.sha256(raw).hexdigest())
    if loaded.fmu is not None:
        _check_fmu_file(loaded)
    return loaded


def _check_fmu_file(profile: DutProfile) -> None:
    """An FMU DUT's FMU (fmpy's validation, terminals, bindings, parameters), when it exists.

    One that ``[build]`` makes is checked after the build, before the run (:mod:`hil.dut.fmu`);
    where it was built already, here.
    """
    from hil.dut.fmu_check import check_fmu

    assert profile.fmu is not None
    where = profile.path.resolve().parent if profile.path else Path.cwd()
    build: Path | None = None
    if profile.build is not None and "{build_dir}" in profile.fmu.path:
        sources = [_rooted(expand_placeholders(src, profile_dir=where))
                   for src in sorted(profile.build.sources)]
        if not all(src.exists() for src in sources):
            return                    # reported as build.sources
        build = build_entry(identity_digest(tuple(profile.build.command), tuple(sources)))
    text = expand_placeholders(profile.fmu.path, profile_dir=where, build=build)
    target = Path(text) if Path(text).is_absolute() else database_path(text, profile.path)
    if target.exists():
        check_fmu(profile, target)
    elif profile.build is None:
        raise ConfigError(f"the FMU {target} does not exist", path=str(profile.path),
                          key="fmu.path")


#: a must-fail profile's registration line (docs/guide/suites.md, "The coverage rule")
MUST_FAIL_HEADER = re.compile(r"^#\s*must-fail:\s*(.+)$", re.MULTILINE)


def must_fail_claims(path: str | Path) -> set[str]:
    """The measurements a must-fail profile claims to fail.

    Parameters
    ----------
    path : str or Path
        A must-fail DUT profile.

    Returns
    -------
    set of str
        The names its ``# must-fail:`` header lines list (empty when it has none).
    """
    text = Path(path).read_text(encoding="utf-8")
    return {name.strip() for line in MUST_FAIL_HEADER.findall(text)
            for name in line.split(",") if name.strip()}


def _rooted(path: str) -> Path:
    """A profile's path: absolute, else relative to the project root."""
    p = Path(path)
    return p if p.is_absolute() else PROJECT_ROOT / p


def database_path(database: str, profile_path: Path | None) -> Path:
    """Where ``wiring.database`` points.

    Absolute, or relative to the project root (as the shipped profiles write it), else to the
    profile's own directory.

    Parameters
    ----------
    database : str
        The profile's ``wiring.database``.
    profile_path : Path or None
        The profile file.

    Returns
    -------
    Path
        The database file (which may not exist).
    """
    p = Path(database)
    if p.is_absolute():
        return p
    at_root = PROJECT_ROOT / p
    if at_root.exists() or profile_path is None:
        return at_root
    beside = profile_path.parent / p
    return beside if beside.exists() else at_root


def _with_binding(profile: DutProfile, rig_config: dict[str, Any], path: Path) -> dict[str, Any]:
    """``[wiring] binding`` read (errors name its file and key), handed to the rig.

    It goes in as ``[rig] wiring.binding_file``, the way every run, campaign sample and record
    gets the rig's config.
    """
    if not profile.wiring.binding:
        return rig_config
    where = {"path": str(path), "key": "wiring.binding"}
    wiring = rig_config.get("wiring", {})
    if isinstance(wiring, dict) and "binding_file" in wiring:
        raise ConfigError("give the binding once: [wiring] binding, not [rig] "
                          "wiring.binding_file", **where)
    target = database_path(profile.wiring.binding, path)
    if not target.is_file():
        raise ConfigError(f"binding file {profile.wiring.binding!r} not found ({target})",
                          **where)
    from hil.contract.binding import load_binding

    binding = load_binding(target)
    if binding.rig != profile.dut.rig.replace("-", "_"):
        raise ConfigError(f"{target.name} binds the {binding.rig} rig's quantities, the DUT is "
                          f"wired to the {profile.dut.rig} rig", **where)
    wiring = dict(wiring) if isinstance(wiring, dict) else {}
    wiring["binding_file"] = str(target.resolve())
    return {**rig_config, "wiring": wiring}


@functools.lru_cache(maxsize=32)
def _database_ids(path: str, mtime_ns: int, size: int) -> frozenset[int]:
    """The frame ids a CAN database declares (cached per file version).

    Raises ValueError (or cantools' own errors) when the file is not a database.
    """
    import cantools

    db = cantools.database.load_file(path, strict=False)
    if not isinstance(db, cantools.database.can.Database):
        raise ValueError("not a CAN database")
    return frozenset(m.frame_id for m in db.messages)


def _check_database(profile: DutProfile, path: Path) -> None:
    """``wiring.database`` must be a readable CAN database that declares frames.

    (Not every command id is checked against it: the depth rig's drive takes its controlword
    in RPDO 0x202, a CANopen frame its DBC does not list today.)
    """
    database = profile.wiring.database
    if not database:
        return
    where = {"path": str(path), "key": "wiring.database"}
    target = database_path(database, path)
    try:
        stat = target.stat()
    except OSError as exc:
        raise ConfigError(f"CAN database {database!r} not found ({target}: "
                          f"{exc.strerror or exc})", **where) from exc
    if not target.is_file():
        raise ConfigError(f"CAN database {database!r} is not a file ({target})", **where)
    try:
        ids = _database_ids(str(target), stat.st_mtime_ns, stat.st_size)
    except Exception as exc:  # cantools raises many kinds (ParseError, KeyError, …)
        text = "".join(c if c.isprintable() else "?" for c in " ".join(str(exc).split()))
        detail = text[:200] or type(exc).__name__
        raise ConfigError(f"CAN database {database!r} cannot be read: {detail}",
                          **where) from exc
    if not ids:
        raise ConfigError(f"CAN database {database!r} declares no frames", **where)


def rig_control_period_ms(rig: str, overrides: dict[str, Any] | None = None,
                          source: str = "") -> tuple[float, bool]:
    """The rig's control period (its SYNC period) in ms, with the profile's ``[rig]`` overrides.

    Parameters
    ----------
    rig : str
        The rig's name.
    overrides : dict, optional
        The profile's ``[rig]`` table.
    source : str, optional
        Where the overrides come from, named in errors.

    Returns
    -------
    tuple of (float, bool)
        The period in ms, and whether the rig's config sets it
        (``[rig] wiring.sync_period_ms``).
    """
    from hil.rig.registry import load_rig

    rig_cls = load_rig(rig)
    config = rig_cls.load_config(overrides or {}, source=source)
    sync_ms = getattr(getattr(config, "wiring", None), "sync_period_ms", None)
    if isinstance(sync_ms, int | float) and not isinstance(sync_ms, bool):
        return float(sync_ms), True
    return float(rig_cls.control_period_s) * 1000.0, False


def _check_control_period(profile: DutProfile, overrides: dict[str, Any], path: str) -> None:
    """``timing.control_period_ms`` is the period the DUT is stepped at: the rig's SYNC period.

    A profile that says otherwise would be run at a period it does not claim, so it is refused.
    """
    rig_ms, configurable = rig_control_period_ms(profile.dut.rig, overrides, path)
    if not math.isclose(profile.timing.control_period_ms, rig_ms, rel_tol=1e-9):
        hint = " (or the rig's: [rig] wiring = { sync_period_ms = ... })" if configurable else ""
        raise ConfigError(
            f"control period {profile.timing.control_period_ms:g} ms disagrees with the "
            f"{profile.dut.rig} rig's {rig_ms:g} ms (its SYNC period; the DUT is stepped once "
            f"per SYNC): set {rig_ms:g}{hint}", path=path, key="timing.control_period_ms")


def _check_rig_config(rig: str, overrides: dict[str, Any], path: str) -> None:
    """The ``[rig]`` overrides must make a valid config of that rig (named in errors)."""
    if not overrides:
        return
    from hil.rig.registry import load_rig

    load_rig(rig).load_config(overrides, source=path)


def _check(profile: DutProfile, path: str) -> None:
    """Checks across sections: what each kind needs, rig exists, limit names known."""
    from hil.rig.registry import available_rigs

    ident = profile.dut
    rig = ident.rig.replace("-", "_")
    if rig not in available_rigs():
        raise ConfigError(f"unknown rig {ident.rig!r} (available: "
                          f"{', '.join(available_rigs())})", path=path, key="dut.rig")
    stem = Path(path).stem
    if stem != ident.name:
        raise ConfigError(f"name {ident.name!r} differs from the file name {stem!r}",
                          path=path, key="dut.name")
    launch = profile.launch
    if ident.kind in ("firmware", "daemon") and not launch.command:
        raise ConfigError(f"a {ident.kind} DUT needs a launch command", path=path,
                          key="launch.command")
    if ident.kind == "firmware" and profile.build is None:
        raise ConfigError("a firmware DUT needs a [build] section", path=path, key="build")
    if ident.kind == "inprocess" and not launch.inprocess:
        raise ConfigError("an inprocess DUT needs launch.inprocess = 'module:Class'",
                          path=path, key="launch.inprocess")
    if ident.kind == "fmu" and profile.fmu is None:
        raise ConfigError("an fmu DUT needs an [fmu] section (path, level)", path=path,
                          key="fmu")
    if ident.kind != "fmu" and profile.fmu is not None:
        raise ConfigError(f"[fmu] is for DUTs of kind fmu, this one is {ident.kind}",
                          path=path, key="fmu")
    if ident.kind == "fmu" and (launch.command or launch.inprocess):
        raise ConfigError("an fmu DUT runs its FMU in the rig's process: remove "
                          "launch.command and launch.inprocess", path=path, key="launch")
    if ident.kind == "physical" and (launch.command or profile.build):
        raise ConfigError("a physical DUT is not started by the rig: remove launch.command "
                          "and [build]", path=path, key="launch.command")
    for name, value in profile.parameters.items():
        if not re.match(r"^[a-z][a-z0-9_]*$", name):
            raise ConfigError(f"parameter names are lower_snake_case, got {name!r}",
                              path=path, key=f"parameters.{key_text(name)}")
        del value
    for name, limit in profile.limits.items():
        if not known_measurement(name, rig):
            raise ConfigError(
                f"unknown measurement (the {rig} suites measure: "
                f"{', '.join(measurement_names(rig))})", path=path,
                key=f"limits.{key_text(name)}")
        _check_cases(name, limit, path)
        _check_loosening(name, limit, path)


def _check_loosening(name: str, limit: Limit, path: str) -> None:
    """A limit looser than the catalogue's default must say why (``reason``)."""
    looser = loosening(name, limit)
    if looser and not limit.reason.strip():
        spec = MEASUREMENTS[name]
        raise ConfigError(
            f"loosens the default limit ({'; '.join(looser)}; the default is from "
            f"{spec.source}): say why with reason = \"...\" in the entry, or keep the "
            f"default", path=path, key=f"limits.{key_text(name)}.reason")


def _check_cases(name: str, limit: Limit, path: str) -> None:
    """``when`` cases must name conditions the measurement carries, with values of their kind.

    As the catalogue knows them; where it does not, recording the measurement checks them.
    """
    if not limit.cases:
        return
    key = f"limits.{key_text(name)}"
    if is_conformance(name):
        raise ConfigError("a bus conformance check takes one limit (low, high), not per "
                          "condition: remove 'when'", path=path, key=f"{key}.when")
    spec = MEASUREMENTS[name]
    if spec.conditions is None:
        return
    bad = check_names(limit.cases, condition_kinds_of(spec), what=name)
    if bad:
        raise ConfigError(bad[1], path=path, key=f"{key}.{bad[0]}")
