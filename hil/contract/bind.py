"""A starting binding from a database: ``hil profile bind DATABASE``.

Each rig quantity is matched to the database's signals by name (the words of the quantity
against the words of the message, the signal and its comment, with a few synonyms: ``target``
~ ``setpoint``, ``speed`` ~ ``velocity`` ...), by unit (a signal whose unit is of another
dimension is never proposed for a number) and by layout: a message name that differs only by
a row number (``Flow1`` ... ``Flow4``) becomes ``{row}``; a signal of a multiplexed message
gets the multiplexer and its values, one per row. What cannot be decided is written as a
``# TODO:`` comment: no candidate, two candidates as good as each other, a unit to state, a
multiplexer order to confirm. ``hil profile check`` then says what is still wrong.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from hil.contract.database import BusDatabase
from hil.contract.quantity import Contract, Quantity
from hil.contract.units import canonical, dimension
from hil.errors import ConfigError

__all__ = ["Candidate", "candidates", "write_binding"]

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
}


def _words(text: str) -> set[str]:
    """Lower-case words of a CamelCase / snake_case / spaced name."""
    parts = re.findall(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+", text or "")
    return {p.lower() for p in parts if not p.isdigit()}


def _expand(words: Iterable[str]) -> set[str]:
    out = set()
    for w in words:
        out.add(w)
        out |= _SYNONYMS.get(w, set())
    return out


@dataclass(frozen=True)
class Candidate:
    """A signal proposed for a quantity, with how good a match it is."""

    message: str
    signal: str
    score: float
    row_template: bool
    multiplexer: str
    rows: tuple[int, ...]
    unit: str | None
    reason: str


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


def dut_node(db: BusDatabase) -> str:
    """The node that receives the most signals: in a controller's own database, the
    controller ("" when no signal names a receiver)."""
    counts: dict[str, int] = {}
    for m in db.db.messages:
        for sig in m.signals:
            for node in sig.receivers:
                counts[node] = counts.get(node, 0) + 1
    return max(sorted(counts), key=lambda n: counts[n]) if counts else ""


def candidates(q: Quantity, db: BusDatabase, rows: int, dut: str = "") -> list[Candidate]:
    """Signals that may carry ``q``, best first (``dut``: the DUT's node, for direction)."""
    names = {m.name for m in db.db.messages}
    want = _words(q.name) - {"dut"}
    want_syn = _expand(want)
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
        for sig in m.signals:
            if sig.is_multiplexer:
                continue
            sig_template = _row_template(sig.name, signal_names, rows) if not template else None
            if sig_template and (not q.per_row
                                 or sig_template.replace("{row}", "1") != sig.name):
                continue                       # a row's signal: per-row quantities only
            if q.kind in ("flag", "enum", "counter") and _has_unit(sig.unit):
                continue
            own = _words((sig_template or sig.name).replace("{row}", ""))
            if not own & want_syn:
                continue                       # the signal's own name must say something
            have = own | _words(template.replace("{row}", "") if template else m.name)
            comment = _words(sig.comment or "")
            score = 2.0 * len(want & own) + 1.0 * len(want & (have - own)) \
                + 0.5 * len((want_syn - want) & have) + 0.5 * len(want & comment)
            unit, reason = sig.unit or None, "name"
            if q.kind == "number":
                try:
                    if unit is not None and dimension(unit) != dimension(q.unit):
                        continue
                    if unit is not None:
                        score += 1.5
                        reason = "name and unit"
                except ConfigError:
                    unit = None
            elif sig.length == 1 and q.kind == "flag":
                score += 1.0
            mux, mux_rows = "", ()
            if q.per_row and not template and sig.multiplexer_ids:
                mux = sig.multiplexer_signal or ""
                if sig_template:
                    mux_rows = tuple(
                        (m.get_signal_by_name(sig_template.replace("{row}", str(r)))
                         .multiplexer_ids or [0])[0] for r in range(1, rows + 1))
                else:
                    mux_rows = tuple(sorted(sig.multiplexer_ids))[:rows]
                score += 0.5
            elif q.per_row and not template:
                score -= 2.0                      # one signal for every row: unlikely
            name = sig_template or sig.name
            out[(template or m.name, name)] = Candidate(
                template or m.name, name, score, bool(template), mux, mux_rows, unit,
                reason)
    return sorted(out.values(), key=lambda c: (-c.score, c.message, c.signal))


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
    dut = dut_node(db)
    lines.append(f'dut_node = "{dut}"   # the node that receives the most signals'
                 if dut else '# dut_node = "..."   # TODO: the DUT\'s node in the database')
    lines += ["", "[quantities]"]
    used: dict[tuple[str, str], str] = {}
    for q in contract.quantities:
        found = candidates(q, db, contract.rows, dut)
        fresh = [c for c in found if (c.message, c.signal) not in used]
        need = " (required)" if q.required else ""
        if not fresh:
            lines.append(f"# TODO{need}: {q.name} = {{ message = ..., signal = ... }}  "
                         f"# {q.description} [{q.unit or q.kind}]")
            continue
        best = fresh[0]
        used[(best.message, best.signal)] = q.name
        lines.append(f"{q.name} = {_carrier_text(best, q)}")
        notes = []
        if len(fresh) > 1 and fresh[1].score >= best.score - 0.25:
            notes.append(f"TODO: as good a match: {fresh[1].message}.{fresh[1].signal}")
        if best.multiplexer:
            notes.append("TODO: confirm the multiplexer value of each row, row 1 first")
        if q.kind == "number" and best.unit is None and canonical(q.unit):
            notes.append(f"TODO: the database gives no unit: state it (unit = ...); "
                         f"{q.name} is in {q.unit}")
        if q.kind == "enum":
            notes.append("TODO: if the signal's values differ from "
                         + ", ".join(f"{k} {v}" for k, v in q.values.items())
                         + ", map them: values = { quantity = signal, ... }")
        lines += [f"#   {n}" for n in notes]
    return "\n".join(lines) + "\n"


def _carrier_text(c: Candidate, q: Quantity) -> str:
    parts = [f'message = "{c.message}"', f'signal = "{c.signal}"']
    if c.multiplexer:
        parts += [f'multiplexer = "{c.multiplexer}"', f"rows = {list(c.rows)}"]
    return "{ " + ", ".join(parts) + " }"


