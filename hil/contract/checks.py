"""What ``hil profile check`` finds wrong with a profile's binding, all at once, before any run.

:func:`check_binding` judges a binding against the rig's contract and the database:

* every quantity the rig needs that the binding does not carry, every name it binds that the
  rig does not have;
* every message or signal (or multiplexer) the database lacks;
* a signal too narrow or too coarse for the quantity's range and resolution, with the numbers;
  a unit the binding states against the database's (a wrong scaling), or none where one is
  needed;
* a frame id that clashes with the rig's own nodes (heartbeats, SDO, SYNC, NMT) or that the
  wiring fixes otherwise (a CANopen device's PDO, the DUT's heartbeat);
* a cycle time the rig cannot serve.

:func:`check_profile_wiring` adds what ties the profile to the binding: ``wiring.database``
(the file conformance judges the DUT against) against the binding's database and, without a
binding, against the frames the rig sends; ``wiring.command_ids`` against the frames the rig
waits for; ``build.sources`` that do not exist.

Each :class:`Problem` names the file, the key, what is wrong and the fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.contract.binding import Binding, DdiCarrier, SignalCarrier
from hil.contract.codec import signal_unit
from hil.contract.database import BusDatabase
from hil.contract.quantity import Contract, Quantity
from hil.contract.units import canonical, factor
from hil.errors import ConfigError, FrameError

__all__ = ["Problem", "check_binding", "check_profile_wiring", "signal_span"]


@dataclass(frozen=True)
class Problem:
    """One thing wrong, where, and what to do about it.

    Attributes
    ----------
    path : str
        The file.
    key : str
        The key in it (``quantities.row_flow.signal``).
    message : str
        What is wrong (with the numbers).
    fix : str
        What to change.
    note : bool
        True: worth knowing, not an error (the run would do what the message says).
    """

    path: str
    key: str
    message: str
    fix: str = ""
    note: bool = False

    def __str__(self) -> str:
        fix = f" (fix: {self.fix})" if self.fix else ""
        return f"{self.path}: [{self.key}] {self.message}{fix}"


def signal_span(sig: Any) -> tuple[float, float, float]:
    """What a signal can carry: (lowest, highest, step) in its own unit.

    The raw field's range through the scale and offset, narrowed by the declared minimum and
    maximum; the step is the scale (float signals: 0).
    """
    if sig.conversion.is_float:
        lo, hi, step = -math.inf, math.inf, 0.0
    else:
        bits = sig.length
        raw_lo, raw_hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if sig.is_signed \
            else (0, (1 << bits) - 1)
        a = raw_lo * sig.scale + sig.offset
        b = raw_hi * sig.scale + sig.offset
        lo, hi, step = min(a, b), max(a, b), abs(sig.scale)
    if sig.minimum is not None:
        lo = max(lo, sig.minimum)
    if sig.maximum is not None:
        hi = min(hi, sig.maximum)
    return lo, hi, step


def check_binding(contract: Contract, binding: Binding, *,
                  db: BusDatabase | None = None) -> list[Problem]:
    """Every problem of ``binding`` under ``contract`` (empty: it can run).

    Parameters
    ----------
    contract : Contract
        The rig's contract (its config's overrides applied).
    binding : Binding
        The binding to judge.
    db : BusDatabase, optional
        Its database, if loaded.

    Returns
    -------
    list of Problem
        In quantity order; notes (``note=True``) are not errors.
    """
    src = binding.source or str(binding.path or "")
    out: list[Problem] = []
    if binding.rig != contract.rig:
        out.append(Problem(src, "rig", f"the binding is for the {binding.rig} rig, the profile's "
                           f"rig is {contract.rig}", f'rig = "{contract.rig}"'))
    if db is None:
        try:
            db = BusDatabase(binding.database)
        except FrameError as exc:
            return [*out, Problem(src, "database", str(exc),
                                  "name a DBC, KCD, ARXML or SYM file cantools reads")]
    quantities = {q.name: q for q in contract.quantities}
    for name in binding.carriers:
        if name not in quantities:
            out.append(Problem(src, f"quantities.{name}",
                               f"the {contract.rig} rig has no quantity {name!r}",
                               "use a name of docs/reference/rig-quantities.md"))
    for q in contract.quantities:
        carrier = binding.carriers.get(q.name)
        if carrier is None:
            if q.required:
                out.append(Problem(src, f"quantities.{q.name}",
                                   f"the rig needs {q.name} ({q.description}) and the binding "
                                   "does not carry it",
                                   f"{q.name} = {{ message = ..., signal = ... }}"))
            continue
        if isinstance(carrier, DdiCarrier):
            out += _check_ddi(q, carrier, src, contract.rows)
            continue
        out += _check_signal(contract, q, carrier, db, src)
    out += _check_ids(contract, binding, db, src)
    out += _check_fixed_layouts(contract, binding, db, src)
    out += _fill_notes(contract, binding, db, src)
    return out


def _layout(sig: Any) -> tuple[Any, ...]:
    return (sig.start, sig.length, sig.byte_order, sig.is_signed, sig.scale, sig.offset)


def _layout_text(sig: Any) -> str:
    order = "little-endian" if sig.byte_order == "little_endian" else "big-endian"
    sign = "signed" if sig.is_signed else "unsigned"
    return (f"bit {sig.start}, {sig.length} bits {order} {sign}, scale {sig.scale:g}, "
            f"offset {sig.offset:g}")


def _check_fixed_layouts(contract: Contract, binding: Binding, db: BusDatabase,
                         src: str) -> list[Problem]:
    """A quantity the wiring fixes goes to a CANopen device that decodes it as its EDS maps it.

    The signal must sit where the rig's own database puts it.
    """
    default = contract.default_binding_file.resolve()
    if not contract.fixed_ids or (binding.path is not None
                                  and binding.path.resolve() == default):
        return []
    try:
        from hil.contract.binding import load_binding

        own = load_binding(contract.default_binding_file)
        own_db = BusDatabase(own.database)
    except (ConfigError, FrameError):
        return []
    out = []
    for name in contract.fixed_ids:
        mine, theirs = own.carriers.get(name), binding.carriers.get(name)
        if not isinstance(mine, SignalCarrier) or not isinstance(theirs, SignalCarrier):
            continue
        if not db.has_message(theirs.message_for(None)):
            continue
        try:
            want = own_db.message(mine.message_for(None)).get_signal_by_name(mine.signal)
            got = db.message(theirs.message_for(None)).get_signal_by_name(theirs.signal)
        except (KeyError, ConfigError):
            continue
        if _layout(want) != _layout(got):
            out.append(Problem(src, f"quantities.{name}.signal",
                               f"{theirs.message}.{theirs.signal} is at {_layout_text(got)}; "
                               f"the rig's device decodes {name} at {_layout_text(want)} "
                               f"({contract.fixed_id_reasons.get(name, 'the wiring')})",
                               "the same layout in the database"))
    return out


def _rows(contract: Contract, q: Quantity) -> list[int | None]:
    return list(range(1, contract.rows + 1)) if q.per_row else [None]


def _check_signal(contract: Contract, q: Quantity, carrier: SignalCarrier, db: BusDatabase,
                  src: str) -> list[Problem]:
    key = f"quantities.{q.name}"
    out: list[Problem] = []
    if carrier.multiplexer and len(carrier.rows) < (contract.rows if q.per_row else 1):
        out.append(Problem(src, f"{key}.rows", f"{len(carrier.rows)} multiplexer values for "
                           f"{contract.rows} rows", "one multiplexer value per row"))
        return out
    if "{row}" in carrier.message and not q.per_row:
        return [Problem(src, f"{key}.message", f"{q.name} is not per row: {{row}} has no value",
                        "name one message")]
    if "{row}" in carrier.signal and not q.per_row:
        return [Problem(src, f"{key}.signal", f"{q.name} is not per row: {{row}} has no value",
                        "name one signal")]
    seen: set[tuple[str, str]] = set()
    for row in _rows(contract, q):
        name = carrier.message_for(row)
        if (name, carrier.signal_for(row)) in seen:
            continue
        seen.add((name, carrier.signal_for(row)))
        if not db.has_message(name):
            out.append(Problem(src, f"{key}.message", f"{db.path.name} has no message {name!r}",
                               "a message of the database: " + _names(db)))
            continue
        message = db.message(name)
        try:
            sig = message.get_signal_by_name(carrier.signal_for(row))
        except (KeyError, ConfigError):
            out.append(Problem(src, f"{key}.signal",
                               f"{name} has no signal {_for_row(carrier.signal, row)!r}",
                               "one of " + ", ".join(s.name for s in message.signals)))
            continue
        if not carrier.multiplexer and sig.multiplexer_ids is not None:
            # a signal that only some multiplexed frames carry cannot be read or written
            # without saying which (the run would fail at the first frame)
            mux_name = next((s.name for s in message.signals if s.is_multiplexer), "?")
            out.append(Problem(src, f"{key}.multiplexer",
                               f"{name}.{sig.name} is multiplexed (frames with {mux_name} = "
                               f"{', '.join(map(str, sorted(sig.multiplexer_ids)))}), and "
                               f"the binding names no multiplexer",
                               f"multiplexer = {mux_name!r} and the values that carry it "
                               f"(rows = [...])"))
            continue
        if carrier.multiplexer:
            try:
                mux = message.get_signal_by_name(carrier.multiplexer)
            except KeyError:
                out.append(Problem(src, f"{key}.multiplexer",
                                   f"{name} has no signal {carrier.multiplexer!r}",
                                   "the message's multiplexer signal"))
                continue
            if not mux.is_multiplexer:
                out.append(Problem(src, f"{key}.multiplexer",
                                   f"{name}.{mux.name} is not a multiplexer", ""))
            ids = sig.multiplexer_ids
            if ids is not None:
                wanted = [carrier.mux_value(row)] if "{row}" in carrier.signal \
                    else list(carrier.rows)
                wrong = [r for r in wanted if r not in ids]
                if wrong:
                    out.append(Problem(src, f"{key}.rows",
                                       f"{name}.{sig.name} is in multiplexed frames "
                                       f"{sorted(ids)}, not {wrong}",
                                       "the multiplexer values that carry the signal"))
        out += _check_fit(q, carrier, sig, f"{name}.{sig.name}", key, src)
        out += _check_cycle(contract, q, carrier, db, name, key, src)
        if len(seen) > 1 and out:
            break                                   # one message's problems say it
    return out


def _check_fit(q: Quantity, carrier: SignalCarrier, sig: Any, where: str, key: str,
               src: str) -> list[Problem]:
    """Unit, range and resolution of one signal against its quantity."""
    lo, hi, step = signal_span(sig)
    if q.kind == "counter":
        return []                     # a rolling counter wraps at the signal's width
    if carrier.values:
        outside = sorted(v for v in carrier.values.values() if not lo <= v <= hi)
        if outside:
            return [Problem(src, f"{key}.values", f"{where} holds {lo:g}..{hi:g}; the values "
                            f"{outside} do not fit", "signal values the signal can hold")]
        if q.kind == "enum":
            missing = sorted(set(q.values) - set(carrier.values))
            if missing:
                names = ", ".join(f"{v} ({q.values[v]})" for v in missing)
                return [Problem(src, f"{key}.values", f"no signal value for {names}",
                                "a signal value for each of the quantity's values", )]
        return []
    db_unit = sig.unit or None
    if carrier.unit is not None and db_unit is not None:
        try:
            if canonical(carrier.unit) != canonical(db_unit):
                return [Problem(src, f"{key}.unit",
                                f"{where} is in {db_unit!r} by the database; the binding says "
                                f"{carrier.unit!r} (a factor of "
                                f"{factor(carrier.unit, db_unit):g} on every value)",
                                "remove unit: the database's is used")]
        except ConfigError:
            pass                      # the database's spelling is not in the table
    unit = signal_unit(carrier, sig)
    if q.kind in ("flag", "enum", "counter") and unit is None:
        f = 1.0
    elif unit is None and canonical(q.unit) not in ("", "1"):
        return [Problem(src, f"{key}.unit", f"{where} has no unit in the database and "
                        f"{q.name} is in {q.unit}", f'unit = "{q.unit}" (or the signal\'s)')]
    else:
        try:
            f = factor(q.unit, unit)
        except ConfigError as exc:
            return [Problem(src, f"{key}.unit", f"{where}: {str(exc).split('] ', 1)[-1]}",
                            f"unit = the signal's unit, in {q.unit}'s dimension")]
    need_lo, need_hi = sorted((q.minimum * f, q.maximum * f))
    out = []
    if need_lo < lo - 1e-9 * max(1.0, abs(lo)) or need_hi > hi + 1e-9 * max(1.0, abs(hi)):
        out.append(Problem(
            src, f"{key}.signal",
            f"{where} holds {lo:g}..{hi:g} {unit or ''}".rstrip() + f"; {q.name} needs "
            f"{q.minimum:g}..{q.maximum:g} {q.unit}".rstrip() +
            (f" = {need_lo:g}..{need_hi:g} {unit}" if f != 1.0 else "") + " (too narrow)",
            "a wider signal (length, scale or minimum/maximum)"))
    if step > 0 and step / abs(f) > q.resolution * (1 + 1e-9):
        out.append(Problem(
            src, f"{key}.signal",
            f"{where} steps by {step:g} {unit or ''}".rstrip() +
            (f" = {step / abs(f):g} {q.unit}" if f != 1.0 else "") +
            f"; {q.name} needs {q.resolution:g} {q.unit}".rstrip() + " (too coarse)",
            "a finer scale"))
    return out


def _check_cycle(contract: Contract, q: Quantity, carrier: SignalCarrier, db: BusDatabase,
                 message: str, key: str, src: str) -> list[Problem]:
    cycle = carrier.cycle_ms
    where = f"{key}.cycle_ms" if cycle is not None else f"{key}.message"
    if cycle is None:
        cycle = db.cycle_ms(message)
    if cycle is None:
        return []
    rig_ms = contract.periods_ms.get(q.name)
    if q.event_driven:
        if carrier.cycle_ms is not None and rig_ms is not None \
                and abs(carrier.cycle_ms - rig_ms) > 1e-9:
            return [Problem(src, where, f"{q.name} is sent when the rig's model produces it, "
                            f"every {rig_ms:g} ms; the binding asks {carrier.cycle_ms:g} ms",
                            "remove cycle_ms (or change the rig's config)")]
        return []
    if q.direction == "from_dut":
        if q.name in _command_quantities(contract) and \
                abs(cycle - contract.control_period_ms) > 1e-9:
            return [Problem(src, where, f"{message} carries {q.name}, which the DUT sends once "
                            f"per control period ({contract.control_period_ms:g} ms); the "
                            f"{'binding' if carrier.cycle_ms else 'database'} says {cycle:g} ms",
                            f"cycle_ms = {contract.control_period_ms:g}")]
        return []
    step = contract.physics_period_ms
    if cycle < step or abs(cycle / step - round(cycle / step)) > 1e-6:
        return [Problem(src, where, f"{message} every {cycle:g} ms: the rig sends on its "
                        f"{step:g} ms physics steps", f"a whole multiple of {step:g} ms")]
    return []


def _command_quantities(contract: Contract) -> set[str]:
    return set(contract.command_quantities)


def _check_ddi(q: Quantity, carrier: DdiCarrier, src: str, rows: int) -> list[Problem]:
    key = f"quantities.{q.name}"
    try:
        from hil.isobus.ddi import lookup
        entry = lookup(carrier.ddi)
    except ImportError:
        return [Problem(src, f"{key}.ddi", "the DDI table (hil.isobus.ddi) is not available")]
    except KeyError:
        return [Problem(src, f"{key}.ddi", f"DDI {carrier.ddi} is not in the rig's DDI table",
                        "a DDI of hil.isobus.ddi")]
    if q.per_row and len(carrier.element) != rows:
        return [Problem(src, f"{key}.element", f"{len(carrier.element)} device elements for "
                        f"{rows} rows", "one element per row, row 1 first")]
    if not q.per_row and len(carrier.element) != 1:
        return [Problem(src, f"{key}.element", f"{q.name} is not per row: one element",
                        "element = N")]
    try:
        f = factor(q.unit, entry.unit)
    except ConfigError as exc:
        return [Problem(src, f"{key}.ddi", f"DDI {carrier.ddi} ({entry.name}) is in "
                        f"{entry.unit!r}: {str(exc).split('] ', 1)[-1]}", "a DDI of "
                        f"{q.unit}'s dimension")]
    lo, hi = sorted((entry.physical(entry.raw_min), entry.physical(entry.raw_max)))
    out = []
    if q.minimum * f < lo or q.maximum * f > hi:
        out.append(Problem(src, f"{key}.ddi", f"DDI {carrier.ddi} holds {lo:g}..{hi:g} "
                           f"{entry.unit}; {q.name} needs {q.minimum * f:g}..{q.maximum * f:g}",
                           "another DDI"))
    if entry.resolution / f > q.resolution * (1 + 1e-9):
        out.append(Problem(src, f"{key}.ddi", f"DDI {carrier.ddi} steps by "
                           f"{entry.resolution:g} {entry.unit} = {entry.resolution / f:g} "
                           f"{q.unit}; {q.name} needs {q.resolution:g}", "another DDI"))
    return out


def _check_ids(contract: Contract, binding: Binding, db: BusDatabase,
               src: str) -> list[Problem]:
    """Ids clashing with the rig's own nodes, and ids the wiring fixes."""
    out = []
    own = {can_id: what for what, can_id in contract.node_ids.items()}
    quantities = {q.name: q for q in contract.quantities}
    reported: set[tuple[str, int]] = set()
    for name, carrier in binding.signal_carriers().items():
        q = quantities.get(name)
        if q is None:
            continue
        for row in _rows(contract, q):
            message = carrier.message_for(row)
            if not db.has_message(message):
                continue
            m = db.message(message)
            expected = contract.fixed_ids.get(q.name)
            if expected is not None and not m.is_extended_frame and m.frame_id != expected:
                out.append(Problem(src, f"quantities.{name}.message",
                                   f"{message} is at {m.frame_id:#x}, but {q.name} can only "
                                   f"reach the rig at {expected:#x} "
                                   f"({contract.fixed_id_reasons.get(q.name, 'the wiring')})",
                                   f"bind a message at {expected:#x} or change the wiring"))
                continue
            what = own.get(m.frame_id)
            if what is not None and not m.is_extended_frame and expected != m.frame_id \
                    and (message, m.frame_id) not in reported:
                reported.add((message, m.frame_id))
                out.append(Problem(src, f"quantities.{name}.message",
                                   f"{message} at {m.frame_id:#x} clashes with the rig's "
                                   f"{what}", "another id in the database"))
    return out


def _fill_notes(contract: Contract, binding: Binding, db: BusDatabase,
                src: str) -> list[Problem]:
    """Signals of messages the rig sends that no quantity fills and that have no start value."""
    quantities = {q.name: q for q in contract.quantities}
    bound: dict[str, set[str]] = {}
    for name, carrier in binding.signal_carriers().items():
        q = quantities.get(name)
        if q is None or q.direction != "to_dut":
            continue
        for row in _rows(contract, q):
            message = carrier.message_for(row)
            if db.has_message(message):
                bound.setdefault(message, set()).update({carrier.signal_for(row),
                                                         carrier.multiplexer})
    out = []
    for message, signals in bound.items():
        for sig in db.message(message).signals:
            if sig.multiplexer_ids is not None:
                continue                        # sent only with its multiplexer value
            if sig.name not in signals and sig.raw_initial is None:
                out.append(Problem(src, "quantities", f"{message}.{sig.name} carries no rig "
                                   "quantity and has no start value: the rig sends raw 0",
                                   "GenSigStartValue in the database, if 0 is wrong",
                                   note=True))
    return out


def _names(db: BusDatabase) -> str:
    names = sorted(m.name for m in db.db.messages)
    return ", ".join(names[:12]) + (" ..." if len(names) > 12 else "")


def check_profile_wiring(profile: Any, contract: Contract, binding: Binding, *,
                         database: Path | None, bound: bool) -> list[Problem]:
    """What ties a DUT profile to its binding (see the module's docstring).

    Parameters
    ----------
    profile : DutProfile
        The loaded profile.
    contract : Contract
        Its rig's contract.
    binding : Binding
        The binding in force.
    database : Path or None
        ``wiring.database`` resolved (None: not set).
    bound : bool
        The profile gives a binding (else the rig's default one is in force).
    """
    src = str(profile.path or "")
    out: list[Problem] = []
    if database is not None and database.resolve() != binding.database.resolve():
        if bound:
            out.append(Problem(src, "wiring.database", f"{database.name} is not the binding's "
                               f"database ({binding.database})",
                               "the same file in both, or leave wiring.database out"))
        else:
            out += _same_ids(src, database, binding, contract)
    waits = set(contract.command_ids)
    try:
        codec_ids = _bound_command_ids(contract, binding)
    except (ConfigError, FrameError):
        codec_ids = set()
    waits = codec_ids or waits
    given = set(profile.wiring.command_ids)
    if given and given != waits:
        out += _command_ids(src, contract, given, waits)
    if contract.dut_node_id and profile.wiring.node_id != contract.dut_node_id:
        out.append(Problem(src, "wiring.node_id", f"the {contract.rig} rig's wiring puts the "
                           f"DUT at node {contract.dut_node_id:#x}, the profile at "
                           f"{profile.wiring.node_id:#x}",
                           f"node_id = {contract.dut_node_id:#x} (or [rig] wiring's)"))
    return out


#: CAN ids CiA 301 reserves (NMT, SYNC, EMCY, TIME, SDO, LSS, NMT error control): no PDO
_RESERVED_COB_IDS = (range(0x000, 0x101), range(0x101, 0x181), range(0x581, 0x600),
                     range(0x601, 0x680), range(0x6E0, 0x700), range(0x701, 0x800))


def _hex_list(ids: set[int]) -> str:
    return ", ".join(f"0x{i:X}" for i in sorted(ids))


def _command_ids(src: str, contract: Contract, given: set[int],
                 waits: set[int]) -> list[Problem]:
    """``wiring.command_ids`` other than the frames the rig waits for by default.

    Where the DUT is the NMT master of the rig's CANopen nodes it configures their RPDOs, and
    the rig's step follows (the depth rig's drive): it may list where it puts its commands,
    any id an RPDO can take (an 11-bit id CiA 301 leaves to PDOs, none of the rig's own
    frames but its nodes' RPDOs); the run checks them against what it configured. Elsewhere the
    frames are the binding's and the list must be theirs.
    """
    what = (f"the frames of {', '.join(sorted(contract.command_quantities))}"
            if contract.command_quantities else "the rig's command frames")
    fix = f"command_ids = [{_hex_list(waits)}] or remove the key"
    if not contract.dut_is_nmt_master:
        return [Problem(src, "wiring.command_ids",
                        f"[{_hex_list(given)}] is not what the rig waits for after each "
                        f"SYNC: [{_hex_list(waits)}] ({what})", fix)]
    own = {can_id: name for name, can_id in contract.node_ids.items() if "RPDO" not in name}
    bad = sorted(i for i in given if i > 0x7FF or i in own
                 or any(i in r for r in _RESERVED_COB_IDS))
    if bad:
        why = "; ".join(f"0x{i:X} is the rig's {own[i]}" if i in own else
                        f"0x{i:X} is no 11-bit id CiA 301 leaves to PDOs" for i in bad)
        return [Problem(src, "wiring.command_ids", f"no RPDO of the rig's CANopen nodes can "
                        f"be configured at {_hex_list(set(bad))} ({why})", fix)]
    moved = given - waits
    if not moved:
        return [Problem(src, "wiring.command_ids",
                        f"[{_hex_list(given)}] is {'one' if len(given) == 1 else 'some'} of "
                        f"the frames the rig waits for by default ([{_hex_list(waits)}], "
                        f"{what}): the rig waits for {'it' if len(given) == 1 else 'them'} "
                        "only, where the node takes a command as its EDS maps it (or as the "
                        "DUT configures it); each run checks that the DUT's command arrives "
                        "there, and a listed id that carries no command stops the run",
                        note=True)]
    return [Problem(src, "wiring.command_ids",
                    f"[{_hex_list(moved)}] is not among the frames the rig waits for by "
                    f"default ([{_hex_list(waits)}], {what}): the DUT must configure the RPDOs "
                    "that carry its commands there; each run checks it once the DUT commands, "
                    "and a listed id that carries no command stops the run", note=True)]


def _bound_command_ids(contract: Contract, binding: Binding) -> set[int]:
    db = BusDatabase(binding.database)
    ids = set()
    for name in contract.command_quantities:
        carrier = binding.carriers.get(name)
        if isinstance(carrier, SignalCarrier) and db.has_message(carrier.message_for(None)):
            ids.add(db.frame_id(carrier.message_for(None)))
    return ids


def _same_ids(src: str, database: Path, binding: Binding, contract: Contract) -> list[Problem]:
    """Without a binding the rig sends its own frames: the DUT's database must agree."""
    try:
        theirs = BusDatabase(database)
        ours = BusDatabase(binding.database)
    except FrameError as exc:
        return [Problem(src, "wiring.database", str(exc), "a database cantools reads")]
    out = []
    for m in theirs.db.messages:
        if not ours.has_message(m.name):
            continue
        mine = ours.message(m.name)
        if (mine.frame_id, mine.is_extended_frame) != (m.frame_id, m.is_extended_frame):
            out.append(Problem(src, "wiring.database",
                               f"{database.name} has {m.name} at {m.frame_id:#x}; the "
                               f"{contract.rig} rig sends and takes it at {mine.frame_id:#x} "
                               f"({binding.database.name}, ids from the wiring's node ids)",
                               "bind your database ([wiring] binding = FILE; `hil profile bind "
                               f"{database.name} --rig {contract.rig}` writes one) or use the "
                               "rig's ids"))
    return out


def _for_row(signal: str, row: int | None) -> str:
    return signal.replace("{row}", str(row)) if row is not None else signal
