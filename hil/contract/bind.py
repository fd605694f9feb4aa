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


def candidates(q: Quantity, db: BusDatabase, rows: int) -> list[Candidate]:
    """Signals that may carry ``q``, best first."""
    names = {m.name for m in db.db.messages}
    want = _words(q.name)
    want_syn = _expand(want)
    out: dict[tuple[str, str], Candidate] = {}
    for m in db.db.messages:
        template = _row_template(m.name, names, rows) if q.per_row else None
        if q.per_row and template and template.replace("{row}", "1") != m.name:
            continue                           # one family member speaks for all
        for sig in m.signals:
            if sig.is_multiplexer:
                continue
            have = _words(sig.name) | _words(m.name if not template else
                                             template.replace("{row}", ""))
            comment = _words(sig.comment or "")
            score = 2.0 * len(want & have) + 1.0 * len((want_syn - want) & have) \
                + 0.5 * len(want & comment)
            if score <= 0:
                continue
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
                mux_rows = tuple(sorted(sig.multiplexer_ids))[:rows]
                score += 0.5
            elif q.per_row and not template:
                score -= 2.0                      # one signal for every row: unlikely
            out[(template or m.name, sig.name)] = Candidate(
                template or m.name, sig.name, score, bool(template), mux, mux_rows, unit,
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
    if relative_to is not None:
        try:
            shown = str(where.relative_to(relative_to.resolve()))
        except ValueError:
            shown = str(where)
    else:
        shown = str(where)
    lines = [f"# Binding of the {contract.rig} rig's quantities to {where.name}, written by "
             "`hil profile bind`.",
             "# Check every line; resolve each TODO, then run `hil profile check` on the "
             "profile that names it",
             "# ([wiring] database and binding; docs/guide/binding.md, quantities in "
             "docs/reference/rig-quantities.md).",
             f'rig = "{contract.rig}"', f'database = "{shown}"']
    senders = sorted({s for m in db.db.messages for s in m.senders})
    lines.append(f'# dut_node = "..."   # TODO: the DUT\'s node among {", ".join(senders)}'
                 if senders else '# dut_node = "..."')
    lines += ["", "[quantities]"]
    used: dict[tuple[str, str], str] = {}
    for q in contract.quantities:
        found = candidates(q, db, contract.rows)
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


