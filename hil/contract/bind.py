"""A starting binding from a database: ``hil profile bind DATABASE``.

Each rig quantity is matched to the database's signals by name (the words of the quantity
against the words of the message, the signal and its comment, with a few synonyms: ``target``
~ ``setpoint``, ``speed`` ~ ``velocity`` ...; the quantity's description against the
comments), by unit (a signal whose unit is of another dimension is never proposed for a
number, nor one with fewer steps than the quantity needs), by direction and by layout: a
message name that differs only by a row number (``Flow1`` ... ``Flow4``) becomes ``{row}``; a
signal of a multiplexed message, per row or not, gets the multiplexer and the values the
database puts it under. Signals are handed out best match first over all quantities, so two
look-alikes (two rolling counters of one sensor hub) go each to the quantity it fits best; a
quantity's status and counter prefer the frame (and multiplexer value) of the quantity they
belong to (``roller_position_counter`` beside ``roller_position``).

What cannot be decided is written as a ``# TODO:`` comment under the proposal: another
candidate as good, a word of the quantity that nothing in the database says, a better match
that went to another quantity, a unit to state, a multiplexer order to confirm, enum values
to map, a frame id the wiring fixes elsewhere. A proposal without a TODO is one the database
decides. ``hil profile check`` then says what is still wrong.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from hil.contract.database import BusDatabase
from hil.contract.quantity import Contract, Quantity
from hil.contract.units import canonical, dimension
from hil.errors import ConfigError

__all__ = ["Candidate", "Proposal", "candidates", "counts", "propose", "write_binding"]

#: words that mean the same thing in signal names
_SYNONYMS = {
    "target": {"target", "setpoint", "set", "sp", "demand", "desired", "cmd", "command"},
    "flow": {"flow", "massflow", "rate", "throughput"},
    "rate": {"rate", "application", "dose", "dosage"},
    "speed": {"speed", "velocity", "spd", "vel"},
    "width": {"width", "workingwidth", "boom"},
    "enable": {"enable", "enabled", "on", "active", "run"},
    "mode": {"mode", "state"},
    "counter": {"counter", "count", "cnt", "alive", "rolling", "seq", "sequence"},
    "motor": {"motor", "drive", "actuator", "output", "analog", "pwm", "voltage"},
    "command": {"command", "cmd", "output", "out", "demand"},
    "distance": {"distance", "dist", "odometer"},
    "direction": {"direction", "dir"},
    "wheel": {"wheel", "hall", "ground"},
    "ground": {"ground", "radar", "gbsd"},
    "mass": {"mass", "weight", "grams"},
    "depth": {"depth"},
    "row": {"row", "section", "channel", "ch"},
    "status": {"status", "state", "flags"},
    "measured": {"measured", "actual", "act", "meas", "sensed", "feedback", "fb"},
    "lost": {"lost", "loss", "no", "missing", "invalid"},
    "position": {"position", "pos", "travel"},
    "fault": {"fault", "error", "err", "alarm"},
    "inclinometer": {"inclinometer", "tilt", "incl", "inc", "angle"},
}

#: words a signal name may carry without saying which quantity it is: units, and a few
#: generic ones (``GroundBasedMachineSpeed``)
_NEUTRAL = {"kg", "g", "h", "ha", "mm", "cm", "um", "m", "mv", "v", "kmh", "kph", "ms", "s",
            "sec", "min", "pct", "rpm", "deg", "rad", "hz", "a", "ma", "per", "machine", "value",
            "raw", "signal", "data", "info"}

#: a word of a quantity that the unit of a signal says by itself (a signal in kg/h is a flow)
_DIMENSION_WORDS = {
    "mass flow": {"flow"}, "speed": {"speed"}, "mass per area": {"rate"},
    "length": {"position", "distance", "depth", "width"}, "voltage": {"voltage"},
    "time": {"period", "length"}, "mass": {"mass"}, "count": {"rows", "count"},
}

#: words of a description or comment that say nothing about which quantity it is
_STOP = {"the", "a", "an", "of", "in", "on", "to", "and", "or", "its", "it", "is", "by", "for",
         "from", "per", "at", "with", "what", "that", "this", "when", "as", "be", "are",
         "was", "s", "x", "y", "status", "frame", "frames", "node", "value", "values"}

#: enum value names that mean the same (a signal's value table against the quantity's)
_VALUE_SYNONYMS = [{"notavailable", "na", "unavailable", "undefined", "invalid", "snv"},
                   {"ok", "valid", "good", "normal"},
                   {"aboverange", "overrange", "high"}, {"belowrange", "underrange", "low"},
                   {"error", "fault", "err"}]

#: how much better than the next candidate a proposal must be to go without a TODO
MARGIN = 0.75


def _stem(word: str) -> str:
    """A crude stem: ``measures``, ``measured`` and ``measure`` are one word."""
    for suffix in ("ing", "ed", "es", "s", "e"):
        if len(word) > len(suffix) + 3 and word.endswith(suffix):
            return word[: -len(suffix)]
    return word


def _words(text: str) -> set[str]:
    """Lower-case words of a CamelCase / snake_case / spaced name."""
    parts = re.findall(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+", text or "")
    return {p.lower() for p in parts if not p.isdigit()}


def _stems(words: Iterable[str]) -> set[str]:
    return {_stem(w) for w in words}


def _expand(words: Iterable[str]) -> set[str]:
    out = set()
    for w in words:
        out.add(w)
        out |= _SYNONYMS.get(w, set())
    return out


@dataclass(frozen=True)
class Candidate:
    """A signal proposed for a quantity, with how good a match it is.

    ``uncovered``: the quantity's words nothing of the signal says (its name, its message's,
    their comments, its unit's dimension, the row layout); ``mux_values``: every value of the
    multiplexer that carries the signal; ``notes``: what the proposal must be checked for.
    """

    message: str
    signal: str
    score: float
    row_template: bool
    multiplexer: str
    rows: tuple[int, ...]
    unit: str | None
    reason: str
    frame_id: int = -1
    uncovered: tuple[str, ...] = ()
    mux_values: tuple[int, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def key(self) -> tuple[str, str, tuple[int, ...]]:
        """What two quantities cannot share: the signal (under one multiplexer value)."""
        return (self.message, self.signal, self.rows)

    @property
    def group(self) -> tuple[str, tuple[int, ...]]:
        """The frame it travels in: the message and its multiplexer values."""
        return (self.message, self.rows)


def _row_template(name: str, names: set[str], rows: int) -> str | None:
    """``Flow{row}`` if ``name`` ends a family ``Flow1`` ... ``Flow<rows>`` (or has the row
    number inside, ``Row1Flow``)."""
    for match in re.finditer(r"\d+", name):
        template = name[:match.start()] + "{row}" + name[match.end():]
        if all(template.replace("{row}", str(r)) in names for r in range(1, rows + 1)):
            return template
    return None


def _has_unit(unit: str | None) -> bool:
    """Whether ``unit`` is a physical unit (not a count or nothing)."""
    try:
        return dimension(unit) not in ("dimensionless", "count")
    except ConfigError:
        return bool(unit)


def _steps(sig: Any) -> float:
    """How many steps a signal holds (unit-free: a linear conversion keeps the count)."""
    if sig.conversion.is_float:
        return float("inf")
    lo, hi = (-(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1) if sig.is_signed \
        else (0, (1 << sig.length) - 1)
    if sig.minimum is not None and sig.maximum is not None and sig.scale:
        span = (sig.maximum - sig.minimum) / abs(sig.scale)
        return min(float(hi - lo), span)
    return float(hi - lo)


def dut_node(db: BusDatabase) -> str:
    """The node that receives the most signals: in a controller's own database, the
    controller ("" when no signal names a receiver)."""
    counts: dict[str, int] = {}
    for m in db.db.messages:
        for sig in m.signals:
            for node in sig.receivers:
                counts[node] = counts.get(node, 0) + 1
    return max(sorted(counts), key=lambda n: counts[n]) if counts else ""


def candidates(q: Quantity, db: BusDatabase, rows: int, dut: str = "",
               fixed_id: int | None = None, fixed_why: str = "",
               others: Mapping[str, str] | None = None,
               peers: Mapping[str, str] | None = None) -> list[Candidate]:
    """Signals that may carry ``q``, best first (``dut``: the DUT's node, for direction;
    ``fixed_id``: the frame id the rig's wiring takes ``q`` at, if it fixes one, and
    ``fixed_why`` why; ``others``: the words of the rig's other quantities, word → one of
    them, so that a name that also says another quantity is marked; ``peers``: the same for
    the quantities of ``q``'s direction)."""
    names = {m.name for m in db.db.messages}
    want = _words(q.name) - {"dut"}
    want_syn = _expand(want)
    about = _stems(_words(q.description)) - _stems(_STOP)
    out: dict[tuple[str, str], Candidate] = {}
    for m in db.db.messages:
        if dut and m.senders:
            sent_by_dut = dut in m.senders
            if sent_by_dut != (q.direction == "from_dut"):
                continue                       # the other direction's frame
        template = _row_template(m.name, names, rows) if q.per_row else None
        if q.per_row and template and template.replace("{row}", "1") != m.name:
            continue                           # one family member speaks for all
        signal_names = {s.name for s in m.signals}
        message_words = _words(template.replace("{row}", "") if template else m.name)
        message_comment = _words(m.comment or "")
        at_fixed = fixed_id is not None and m.frame_id == fixed_id and not m.is_extended_frame
        for sig in m.signals:
            if sig.is_multiplexer:
                continue
            sig_template = _row_template(sig.name, signal_names, rows) if not template else None
            if sig_template and (not q.per_row
                                 or sig_template.replace("{row}", "1") != sig.name):
                continue                       # a row's signal: per-row quantities only
            if q.kind in ("flag", "enum", "counter") and _has_unit(sig.unit):
                continue
            if q.kind in ("flag", "enum") and (sig.unit or "1") != "1":
                continue                       # a count (rows, pulses) is no state
            own = _words((sig_template or sig.name).replace("{row}", ""))
            unit, reason = sig.unit or None, "name"
            same_dimension = False
            if q.kind == "number":
                try:
                    if unit is not None and dimension(unit) != dimension(q.unit):
                        continue
                    same_dimension = unit is not None
                except ConfigError:
                    unit = None
                if _steps(sig) < (q.maximum - q.minimum) / q.resolution * (1 - 1e-9) \
                        and q.maximum - q.minimum > 1:
                    continue                   # too few steps whatever its unit
            if not own & want_syn and not (at_fixed and same_dimension):
                continue                       # the signal's own name must say something
            have = own | message_words
            comment = _words(sig.comment or "")
            score = 2.0 * len(want & own) + 1.0 * len(want & (have - own)) \
                + 0.5 * len((want_syn - want) & have) + 0.5 * len(want & comment) \
                + 0.25 * len(about & _stems(comment | own))
            notes: list[str] = []
            if same_dimension:
                score += 1.5
                reason = "name and unit"
            elif sig.length == 1 and q.kind == "flag":
                score += 1.0
            if fixed_id is not None:
                if at_fixed:
                    score += 1.0
                    if not own & want_syn:
                        notes.append(f"chosen for its frame id {fixed_id:#x} and its unit, "
                                     "not its name")
                elif not m.is_extended_frame:
                    notes.append(f"the rig takes {q.name} only at {fixed_id:#x} "
                                 f"({fixed_why or 'its wiring'}); {m.name} is at "
                                 f"{m.frame_id:#x}: another message, or the rig's wiring "
                                 "([rig] wiring in the profile)")
            mux, mux_rows, mux_values = "", (), ()
            if not template and sig.multiplexer_ids:
                mux = sig.multiplexer_signal or ""
                mux_values = tuple(sorted(sig.multiplexer_ids))
                if _is_nested(m, mux):
                    continue                   # a multiplexer under a multiplexer: by hand
                if q.per_row and sig_template:
                    mux_rows = tuple(
                        (m.get_signal_by_name(sig_template.replace("{row}", str(r)))
                         .multiplexer_ids or [0])[0] for r in range(1, rows + 1))
                elif q.per_row:
                    if len(mux_values) < rows:
                        continue               # not a value per row
                    mux_rows = mux_values[:rows]
                else:
                    mux_rows = mux_values[:1]
                    if len(mux_values) > 1:
                        notes.append(f"{sig.name} is in the frames with {mux} = "
                                     f"{', '.join(map(str, mux_values))}: rows = [...] "
                                     "the one that carries it")
                if q.per_row:
                    score += 0.5
                    if rows > 1:
                        notes.append("confirm the multiplexer value of each row, row 1 first")
            elif q.per_row and not template:
                score -= 2.0                      # one signal for every row: unlikely
            # a synonym too, when a quantity of the same direction has it as its own word:
            # GroundSpeed for wheel_speed (ground_based_speed), not WireState for a status
            alien = sorted(w for w in own if w in (others or {}) and _stem(w) not in
                           _stems(want) and (w not in want_syn or w in (peers or {})))
            if alien:
                notes.append(f"{sig.name} also says " + ", ".join(
                    f"{w!r} (as {(others or {})[w]} does)" for w in alien))
            said = want_syn | about | message_words | message_comment | _NEUTRAL \
                | _words(sig.comment or "") \
                | (_DIMENSION_WORDS.get(dimension(unit), set()) if same_dimension else set())
            strange = sorted(w for w in own - set(alien)
                             if not _explained(w, said, _initials(m.name)))
            if strange:
                notes.append(f"{sig.name} also says {', '.join(repr(w) for w in strange)}, "
                             f"which nothing of {q.name} does")
            name = sig_template or sig.name
            covered = own | message_words | comment | message_comment
            if same_dimension:
                covered |= _DIMENSION_WORDS.get(dimension(unit), set())
            if q.per_row and (template or sig_template or mux):
                covered.add("row")
            uncovered = tuple(sorted(w for w in want if not _says(w, covered)))
            out[(template or m.name, name)] = Candidate(
                template or m.name, name, score, bool(template), mux, mux_rows, unit,
                reason, m.frame_id, uncovered, mux_values, tuple(notes))
    return sorted(out.values(), key=lambda c: (-c.score, c.message, c.signal))


def _says(word: str, words: set[str]) -> bool:
    """Whether ``words`` say ``word`` (itself, a synonym, or the same stem)."""
    return bool(({word} | _SYNONYMS.get(word, set())) & words) \
        or _stem(word) in _stems(words)


def _explained(word: str, said: set[str], initials: str) -> bool:
    """Whether ``said`` accounts for ``word``: the word, its stem, a word it abbreviates
    (``inc`` for ``inclinometer``, ``src`` for ``source``), or the message's initials
    (``DC_State`` in ``DepthControllerStatus``). One letter says nothing."""
    return len(word) < 2 or word in said or _stem(word) in _stems(said) \
        or initials.startswith(word) or any(_abbreviates(word, w) for w in said)


def _abbreviates(short: str, word: str) -> bool:
    """``short`` is ``word``'s first letter and some of its others, in order."""
    if not word.startswith(short[:1]):
        return False
    rest = iter(word[1:])
    return all(c in rest for c in short[1:])


def _initials(name: str) -> str:
    """``dcs`` for ``DepthControllerStatus``, ``dps`` for ``DP_SensorHub``."""
    parts = re.findall(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+", name)
    return "".join(p[0] for p in parts).lower()


def _is_nested(message: Any, mux: str) -> bool:
    try:
        return message.get_signal_by_name(mux).multiplexer_ids is not None
    except KeyError:
        return True


@dataclass(frozen=True)
class Proposal:
    """What ``bind`` proposes for one quantity: a candidate (None: nothing) and its TODOs."""

    quantity: Quantity
    candidate: Candidate | None
    todos: tuple[str, ...]
    values: Mapping[int, int] | None = None

    @property
    def decided(self) -> bool:
        """A proposal the database decides (no TODO)."""
        return self.candidate is not None and not self.todos


def _family_base(q: Quantity, names: Iterable[str]) -> str | None:
    """The quantity ``q`` belongs to: the longest other name that is a word-prefix of its
    own (``roller_position`` for ``roller_position_counter``)."""
    bases = [n for n in names if n != q.name and q.name.startswith(n + "_")]
    return max(bases, key=len) if bases else None


def _assign(found: Mapping[str, list[Candidate]]) -> dict[str, Candidate]:
    """Signals handed out best match first over every quantity: a signal goes to the quantity
    it fits best, and that quantity's other candidates to others."""
    pairs = sorted(((c.score, name, i) for name, cs in found.items() for i, c in enumerate(cs)),
                   key=lambda p: (-p[0], p[1], p[2]))
    taken: set[tuple[str, str, tuple[int, ...]]] = set()
    out: dict[str, Candidate] = {}
    for _, name, i in pairs:
        c = found[name][i]
        if name in out or c.key in taken:
            continue
        out[name] = c
        taken.add(c.key)
    return out


def _clear(c: Candidate, found: list[Candidate]) -> bool:
    """A first choice with nothing to mark: the best, alone, every word said, no note."""
    return c.key == found[0].key and not c.uncovered and not c.notes \
        and not any(o.score >= c.score - MARGIN for o in found[1:])


def _with_families(contract: Contract, found: dict[str, list[Candidate]],
                   first: Mapping[str, Candidate]) -> dict[str, list[Candidate]]:
    """A status or counter in the frame (and multiplexer value) of the quantity it belongs to
    scores higher; in another multiplexer value of that message, lower. Only where that
    quantity's own signal is clear (a home that is itself a guess decides nothing)."""
    names = [q.name for q in contract.quantities]
    out = dict(found)
    for q in contract.quantities:
        base = _family_base(q, names)
        home = first.get(base) if base else None
        if home is not None and not _clear(home, found[base]):
            home = None
        if home is None or not found.get(q.name):
            continue
        # a multiplexer value that carries only this family is one sensor's channel: what is
        # in it says the family's words (not in a plain frame, nor beside another sensor)
        strangers = [n for n, c in first.items()
                     if c.group == home.group and n != base and not n.startswith(base + "_")]
        channel = bool(home.multiplexer) and not strangers
        rescored = []
        for c in found[q.name]:
            if c.group == home.group:
                c = replace(c, score=c.score + 1.5,
                            uncovered=tuple(w for w in c.uncovered
                                            if not channel or w not in base.split("_")))
            elif c.message == home.message and c.multiplexer:
                c = replace(c, score=c.score - 1.5)
            rescored.append(c)
        out[q.name] = sorted(rescored, key=lambda c: (-c.score, c.message, c.signal))
    return out


def propose(database: Path | BusDatabase, contract: Contract) -> tuple[str, list[Proposal]]:
    """The DUT's node and a proposal for each of ``contract``'s quantities, in their order."""
    db = database if isinstance(database, BusDatabase) else BusDatabase(database)
    dut = dut_node(db)
    words: dict[str, list[Quantity]] = {}
    for q in contract.quantities:
        for w in sorted(_words(q.name) - {"dut"}):
            words.setdefault(w, []).append(q)

    def others(q: Quantity, same_direction: bool) -> dict[str, str]:
        mine = _words(q.name)
        return {w: qs[0].name for w, qs in words.items() if w not in mine and (
            not same_direction or any(o.direction == q.direction for o in qs))}

    found = {q.name: candidates(q, db, contract.rows, dut, contract.fixed_ids.get(q.name),
                                contract.fixed_id_reasons.get(q.name, ""),
                                others(q, False), others(q, True))
             for q in contract.quantities}
    found = _with_families(contract, found, _assign(found))
    chosen = _assign(found)
    owner = {c.key: (name, c.score) for name, c in chosen.items()}
    out = []
    for q in contract.quantities:
        best = chosen.get(q.name)
        if best is None:
            out.append(Proposal(q, None, ()))
            continue
        todos = []
        top = found[q.name][0]
        if top.key != best.key:
            todos.append(f"its best match {top.message}.{top.signal} went to "
                         f"{owner[top.key][0]}")
        rivals = [c for c in found[q.name] if c.key != best.key
                  and c.score >= best.score - MARGIN
                  and not (c.key in owner and owner[c.key][1] > c.score + MARGIN)]
        if rivals:
            todos.append(f"as good a match: {rivals[0].message}.{rivals[0].signal}")
        if best.uncovered:
            todos.append(f"nothing in {best.message}.{best.signal} says "
                         f"{', '.join(repr(w) for w in best.uncovered)}: is it {q.name}?")
        todos += best.notes
        if q.kind == "number" and best.unit is None and canonical(q.unit):
            todos.append(f"the database gives no unit: state it (unit = ...); "
                         f"{q.name} is in {q.unit}")
        values = None
        if q.kind == "enum":
            values, todo = _value_map(q, db, best)
            if todo:
                todos.append(todo)
        out.append(Proposal(q, best, tuple(todos), values))
    return dut, out


def _norm(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def _same_value(a: str, b: str) -> bool:
    a, b = _norm(a), _norm(b)
    return a == b or any(a in s and b in s for s in _VALUE_SYNONYMS)


def _value_map(q: Quantity, db: BusDatabase, c: Candidate) -> tuple[dict[int, int] | None, str]:
    """The enum's values by the signal's value names (``VAL_``): a map when every one of the
    quantity's values is named there (None for the same numbers), else a TODO."""
    todo = ("if the signal's values differ from "
            + ", ".join(f"{k} {v}" for k, v in q.values.items())
            + ", map them: values = { quantity = signal, ... }")
    try:
        message = db.message(c.message.replace("{row}", "1"))
        sig = message.get_signal_by_name(c.signal.replace("{row}", "1"))
    except (ConfigError, KeyError):
        return None, todo
    choices = {int(v): str(n) for v, n in (sig.choices or {}).items()}
    if not choices:
        return None, todo
    mapping: dict[int, int] = {}
    for value, name in q.values.items():
        hits = [v for v, n in choices.items() if _same_value(name, n)]
        if len(hits) != 1:
            return None, ("map the values (the database names "
                          + ", ".join(f"{v} {n}" for v, n in sorted(choices.items()))
                          + f"; {q.name}: "
                          + ", ".join(f"{k} {v}" for k, v in q.values.items())
                          + "): values = { quantity = signal, ... }")
        mapping[value] = hits[0]
    if len(set(mapping.values())) != len(mapping):
        return None, todo
    return (None if all(k == v for k, v in mapping.items()) else mapping), ""


def write_binding(database: Path, contract: Contract, *, relative_to: Path | None = None) -> str:
    """A starting binding (TOML text) of ``contract``'s quantities to ``database``.

    Parameters
    ----------
    database : Path
        The DUT's database (DBC, KCD, ARXML, SYM).
    contract : Contract
        The rig's contract.
    relative_to : Path, optional
        The directory the binding will be written to (the database is named relative to it).

    Raises
    ------
    hil.errors.FrameError
        The database cannot be read.
    """
    db = BusDatabase(database)
    where = Path(database).resolve()
    # relative to the binding file (how load_binding reads it), so the pair moves together;
    # ``..`` parts included: a binding beside a profile names the database wherever it sits
    shown = (os.path.relpath(where, relative_to.resolve()) if relative_to is not None
             else str(where))
    lines = [f"# Binding of the {contract.rig} rig's quantities to {where.name}, written by "
             "`hil profile bind`.",
             "# Check every line; resolve each TODO, then run `hil profile check` on the "
             "profile that names it",
             "# ([wiring] database and binding; docs/guide/binding.md, quantities in "
             "docs/reference/rig-quantities.md).",
             f'rig = "{contract.rig}"', f'database = "{shown}"']
    dut, proposals = propose(db, contract)
    lines.append(f'dut_node = "{dut}"   # the node that receives the most signals'
                 if dut else '# dut_node = "..."   # TODO: the DUT\'s node in the database')
    lines += ["", "[quantities]"]
    for p in proposals:
        q = p.quantity
        if p.candidate is None:
            need = " (required)" if q.required else ""
            lines.append(f"# TODO{need}: {q.name} = {{ message = ..., signal = ... }}  "
                         f"# {q.description} [{q.unit or q.kind}]")
            continue
        lines.append(f"{q.name} = {_carrier_text(p.candidate, p.values)}")
        lines += [f"#   TODO: {t}" for t in p.todos]
    return "\n".join(lines) + "\n"


def counts(text: str) -> tuple[int, int]:
    """(quantities bound, TODOs) of a binding ``write_binding`` wrote."""
    body = text.split("[quantities]", 1)[-1].splitlines()
    bound = sum(1 for line in body if not line.startswith("#") and " = { " in line)
    return bound, sum(1 for line in body if line.startswith("#") and "TODO" in line)


def _carrier_text(c: Candidate, values: Mapping[int, int] | None = None) -> str:
    parts = [f'message = "{c.message}"', f'signal = "{c.signal}"']
    if c.multiplexer:
        parts += [f'multiplexer = "{c.multiplexer}"', f"rows = {list(c.rows)}"]
    if values:
        parts.append("values = { " + ", ".join(f"{k} = {v}" for k, v in values.items())
                     + " }")
    return "{ " + ", ".join(parts) + " }"
