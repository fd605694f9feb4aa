"""``hil profile bind`` on databases Hypothesis builds: every proposal it makes without a TODO is
the signal that carries the quantity and passes ``hil profile check``; whatever it could not
decide, it marks.

Each database is built in code (cantools) from a rig's quantities: the true carriers are named
from the quantity's words (sometimes a synonym, sometimes a word left out), in the quantity's
unit or another of its dimension, in plain or multiplexed messages, per-row quantities as one
message per row, one multiplexed message with a signal per row, or one signal under a
multiplexer value per row. Look-alikes are added around them: the same name in another
dimension, in the other direction, too narrow for the quantity, with a word of something else
(``AuxEnabled``), a second copy elsewhere (nobody can tell the two apart: bind must mark it),
and another sensor's rolling counter and status under another multiplexer value of a frame.
"""

from __future__ import annotations

import functools
import math
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest
from cantools.database.can import Database, Message, Node, Signal
from cantools.database.conversion import BaseConversion
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hil.contract.bind import write_binding
from hil.contract.binding import parse_binding
from hil.contract.checks import check_binding
from hil.contract.quantity import Contract, Quantity
from hil.contract.registry import rig_contract
from hil.contract.units import UNITS, dimension, factor

#: how a word may be spelled in a database (a few of the synonyms a real one uses)
SPELLINGS = {"target": ["Target", "Setpoint", "Sp"], "speed": ["Speed", "Velocity", "Spd"],
             "counter": ["Counter", "Cnt", "Seq", "Alive"], "status": ["Status", "State"],
             "position": ["Position", "Pos"], "measured": ["Measured", "Actual"],
             "command": ["Command", "Cmd"], "distance": ["Distance", "Dist"]}
#: words no quantity uses, for look-alike names
OTHER_WORDS = ["Aux", "Spare", "Temp", "Pressure", "Hours", "Lamp"]
DUT, PEER = "Ctl", "Peer"


@dataclass
class Planned:
    """One signal to build: its name, where it goes and what it truly carries."""

    name: str
    length: int
    scale: float = 1.0
    signed: bool = False
    unit: str = ""
    comment: str = ""
    choices: dict[int, str] | None = None
    quantity: str = ""          # "" for a look-alike
    message: str = ""           # where it went ("" while not built, or no room)


def _camel(words: list[str]) -> str:
    return "".join(w[:1].upper() + w[1:] for w in words)


def _unit_for(q: Quantity, draw: st.DrawFn) -> tuple[str, float]:
    """A unit of the quantity's dimension and the factor from the quantity's unit to it."""
    if not q.unit:
        return "", 1.0
    same = [u for u, (d, _) in UNITS.items() if d == dimension(q.unit) and u.isascii() and u]
    unit = draw(st.sampled_from(sorted(same)))
    return unit, factor(q.unit, unit)


def _true_signal(q: Quantity, name: str, draw: st.DrawFn) -> Planned:
    """A signal that carries ``q`` with room to spare (range and resolution)."""
    if q.kind == "flag":
        return Planned(name, 1, quantity=q.name)
    if q.kind in ("enum", "counter"):
        bits = max(1, math.ceil(math.log2(q.maximum + 1)))
        choices = ({v: _camel(n.split("_")) for v, n in q.values.items()}
                   if q.kind == "enum" and draw(st.booleans()) else None)
        return Planned(name, bits, choices=choices, quantity=q.name)
    unit, f = _unit_for(q, draw)
    lo, hi = sorted((q.minimum * f, q.maximum * f))
    signed = lo < 0
    scale = q.resolution * abs(f) / 2.0
    if max(abs(lo), abs(hi)) / scale > 2 ** 30:
        scale *= 2.0                          # a wide range (a distance): no room to spare
    bits = math.ceil(math.log2(max(abs(lo), abs(hi)) / scale + 1)) + (1 if signed else 0)
    return Planned(name, bits, scale, signed, unit, quantity=q.name)


def _name(q: Quantity, draw: st.DrawFn) -> str:
    words = [w for w in q.name.split("_") if w != "dut"]
    spelled = [draw(st.sampled_from(SPELLINGS.get(w, [w.capitalize()]))) for w in words]
    if len(spelled) > 1 and draw(st.integers(0, 5)) == 0:
        spelled.pop(draw(st.integers(0, len(spelled) - 1)))     # a word left out
    return _camel(spelled)


@dataclass
class Built:
    """A generated database and what each quantity truly is on it."""

    db: Database
    truth: dict[str, dict]


@functools.cache
def _contract(rig: str) -> Contract:
    return rig_contract(rig)


@st.composite
def databases(draw: st.DrawFn, rig: str) -> Built:
    """A controller's database for ``rig``'s quantities, with look-alikes (see the module's
    docstring)."""
    contract = _contract(rig)
    usable = [q for q in contract.quantities if q.name not in contract.fixed_ids]
    picks = draw(st.lists(st.integers(0, len(usable) - 1), min_size=3, max_size=14,
                          unique=True))
    chosen = [usable[i] for i in picks]
    messages: list[tuple[str, str, list[Planned], list[int] | None, str]] = []
    truth: dict[str, dict] = {}
    used_names: set[str] = set()
    placed: dict[str, Planned] = {}

    def unique(name: str) -> str:
        base, n = name, 1
        while name in used_names:
            n += 1
            name = f"{base}{'X' * n}"
        used_names.add(name)
        return name

    plain: dict[str, list[Planned]] = {"to_dut": [], "from_dut": []}
    muxed: dict[str, dict[int, list[Planned]]] = {"to_dut": {}, "from_dut": {}}
    rows = contract.rows
    for q in chosen:
        name = _name(q, draw)
        sig = _true_signal(q, name, draw)
        if q.per_row:
            layout = draw(st.sampled_from(["family", "mux_signals", "mux_shared"]))
            mname = unique("Row" + _camel([w for w in q.name.split("_")][1:]) or "Row")
            if layout == "family":
                for r in range(1, rows + 1):
                    messages.append((f"{mname}{r}", "to_dut",
                                     [Planned(**{**sig.__dict__})], None, ""))
                truth[q.name] = {"message": f"{mname}{{row}}", "signal": name}
            elif layout == "mux_signals":
                first = draw(st.integers(0, 1))
                sigs = [Planned(**{**sig.__dict__, "name": f"{name}_R{r}"})
                        for r in range(1, rows + 1)]
                messages.append((mname, "to_dut", sigs, [first + r for r in range(rows)],
                                 "per_row"))
                truth[q.name] = {"message": mname, "signal": f"{name}_R{{row}}",
                                 "multiplexer": "Sel", "rows": [first + r for r in range(rows)]}
            else:
                first = draw(st.integers(0, 1))
                messages.append((mname, "to_dut", [sig], [first + r for r in range(rows)],
                                 "shared"))
                truth[q.name] = {"message": mname, "signal": name, "multiplexer": "Sel",
                                 "rows": [first + r for r in range(rows)]}
            continue
        placed[q.name] = sig
        if draw(st.booleans()):
            plain[q.direction].append(sig)
            truth[q.name] = {}
        else:
            value = draw(st.integers(0, 2))
            muxed[q.direction].setdefault(value, []).append(sig)
            truth[q.name] = {"multiplexer": "Sel", "rows": [value]}
    # look-alikes of the chosen quantities
    for q in chosen:
        if q.per_row:
            continue
        kind = draw(st.sampled_from(["none", "dimension", "direction", "narrow", "copy",
                                     "sibling", "prefixed"]))
        name = _name(q, draw)
        other = "from_dut" if q.direction == "to_dut" else "to_dut"
        if kind == "dimension" and q.kind == "number":
            wrong = "deg" if dimension(q.unit) != "angle" else "mm"
            plain[q.direction].append(Planned(name, 16, 1.0, unit=wrong))
        elif kind == "direction" and not _named_both_ways(contract, q):
            plain[other].append(Planned(name, 16, 1.0))
        elif kind == "narrow" and q.kind == "number" and q.maximum - q.minimum > 1:
            plain[q.direction].append(Planned(name, 1, 1.0, unit=q.unit))
        elif kind == "copy":
            # the same signal twice: nothing tells which one the controller reads
            copy = Planned(**{**placed[q.name].__dict__, "quantity": ""})
            muxed[q.direction].setdefault(3, []).append(copy)
        elif kind == "prefixed":
            # the quantity's name with a word of something else (``AuxEnabled``)
            alike = _true_signal(q, draw(st.sampled_from(OTHER_WORDS)) + name, draw)
            alike.quantity = ""
            plain[q.direction].append(alike)
        elif kind == "sibling":
            # another sensor's rolling counter and status, under another multiplexer value
            whose = draw(st.sampled_from(OTHER_WORDS + _other_sensors(contract)))
            muxed[q.direction].setdefault(4, []).extend(
                [Planned(whose + draw(st.sampled_from(SPELLINGS["counter"])), 4),
                 Planned(whose + draw(st.sampled_from(SPELLINGS["status"])), 2)])
    for direction in ("to_dut", "from_dut"):
        extra = draw(st.lists(st.sampled_from(OTHER_WORDS), max_size=2, unique=True))
        plain[direction] += [Planned(w, 8) for w in extra]
    # the DUT receives the most signals (how bind finds it): spare signals to it
    n_to, n_from = (len(plain[d]) + sum(len(s) for s in muxed[d].values())
                    for d in ("to_dut", "from_dut"))
    plain["to_dut"] += [Planned(f"Reserved{'X' * i}", 8) for i in range(n_from - n_to + 1)]
    for direction in ("to_dut", "from_dut"):
        for i, chunk in enumerate(_chunks(plain[direction])):
            messages.append((f"{'In' if direction == 'to_dut' else 'Out'}Frame{i}", direction,
                             chunk, None, ""))
        # multiplexed frames: each value's signals in 56 bits after the multiplexer
        frames: list[dict[int, list[Planned]]] = []
        for v in sorted(muxed[direction]):
            bits = 64
            for sig in muxed[direction][v]:
                if bits + sig.length > 56:
                    index = next((i for i, f in enumerate(frames) if v not in f), len(frames))
                    if index == len(frames):
                        frames.append({})
                    frames[index][v] = []
                    bits = 0
                frames[index][v].append(sig)
                bits += sig.length
        for k, groups in enumerate(frames):
            names: set[str] = set()
            for v in sorted(groups):
                for sig in groups[v]:
                    while sig.name in names:
                        sig.name += "2"       # a look-alike: the digits are no word
                    names.add(sig.name)
            messages.append((f"{'In' if direction == 'to_dut' else 'Out'}Mux{k}", direction,
                             [s for v in sorted(groups) for s in groups[v]],
                             [v for v in sorted(groups) for _ in groups[v]], "by_signal"))
    db = _build(messages, contract)
    for name, sig in placed.items():
        if sig.message:
            truth[name].update(message=sig.message, signal=sig.name)
        else:
            del truth[name]                   # no room left for it
    return Built(db, truth)


def _stems(name: str) -> set[str]:
    return {w.rstrip("ds").rstrip("e") for w in name.split("_")} - {"dut"}


def _named_both_ways(contract: Contract, q: Quantity) -> bool:
    """Whether a quantity of the other direction has a name like ``q``'s (``enable`` and
    ``dut_enabled``): its name in the other direction is then a fair match for that one."""
    return any(_stems(o.name) <= _stems(q.name) or _stems(q.name) <= _stems(o.name)
               for o in contract.quantities if o.direction != q.direction)


def _other_sensors(contract: Contract) -> list[str]:
    """First words of quantities that with ``counter`` or ``status`` name no quantity
    (``Roller``: roller_position_counter also says ``position``; not ``Wheel``, which with
    ``Counter`` is wheel_counter)."""
    names = [set(q.name.split("_")) - {"dut"} for q in contract.quantities]
    firsts = {q.name.split("_")[0] for q in contract.quantities} - {"dut"}
    return sorted(w.capitalize() for w in firsts
                  if not any(n <= {w, "counter", "status"} for n in names))


def _chunks(signals: list[Planned]) -> list[list[Planned]]:
    """Signals in frames of 64 bits, no name twice in one."""
    out: list[list[Planned]] = [[]]
    bits = 0
    for s in signals:
        if bits + s.length > 64 or s.name in {p.name for p in out[-1]}:
            out.append([])
            bits = 0
        out[-1].append(s)
        bits += s.length
    return [c for c in out if c]


def _build(messages: list[tuple[str, str, list[Planned], list[int] | None, str]],
           contract: Contract) -> Database:
    reserved = set(contract.node_ids.values()) | set(contract.fixed_ids.values())
    ids = (i for i in range(0x6C0, 0x7FF) if i not in reserved)
    built: list[Message] = []
    for name, direction, planned, mux_values, how in messages:
        sender, receiver = (DUT, PEER) if direction == "from_dut" else (PEER, DUT)
        signals: list[Signal] = []
        start = 0
        if mux_values is not None:
            signals.append(Signal("Sel", 0, 8, is_multiplexer=True, receivers=[receiver]))
            start = 8
        offsets: dict[int, int] = {}
        for i, p in enumerate(planned):
            ids_for = None
            if how == "shared":
                ids_for = list(mux_values or [])
            elif mux_values is not None:
                ids_for = [mux_values[i]]
            at = offsets.get(ids_for[0], start) if ids_for and how != "shared" else start
            if at + p.length > 64:
                continue                        # no room left in this multiplexed frame
            signals.append(Signal(
                p.name, at, p.length, is_signed=p.signed,
                conversion=BaseConversion.factory(scale=p.scale, offset=0.0,
                                                  choices=p.choices),
                unit=p.unit or None, comment=p.comment or None, receivers=[receiver],
                multiplexer_ids=ids_for, multiplexer_signal="Sel" if ids_for else None))
            p.message = name
            if ids_for and how != "shared":
                offsets[ids_for[0]] = at + p.length
            else:
                start = at + p.length
        built.append(Message(next(ids), name, 8, signals, senders=[sender]))
    return Database(messages=built, nodes=[Node(DUT), Node(PEER)])


@pytest.fixture(scope="module", params=["fertilizer", "sowing-depth"])
def contract(request: pytest.FixtureRequest) -> Contract:
    return _contract(request.param)


def _carrier(truth: dict) -> dict:
    return {k: truth[k] for k in ("message", "signal", "multiplexer", "rows") if k in truth}


def unmarked(text: str) -> list[str]:
    """The quantities a written binding proposes without a TODO under them."""
    lines = text.split("[quantities]", 1)[1].splitlines()
    out = []
    for i, line in enumerate(lines):
        if line.startswith("#") or " = { " not in line:
            continue
        after = lines[i + 1] if i + 1 < len(lines) else ""
        if not after.startswith("#   TODO: "):     # (a quantity left out is "# TODO")
            out.append(line.split(" = ", 1)[0])
    return out


def wrong_and_unmarked(contract: Contract, truth: dict[str, dict], text: str,
                       folder: Path) -> list[str]:
    """Every proposal of ``text`` without a TODO that is not the true carrier or that
    ``hil profile check`` refuses."""
    binding = parse_binding(tomllib.loads(text), source="bound.toml", base=folder)
    problems = check_binding(contract, binding)
    out = []
    for name in unmarked(text):
        carrier = binding.carriers[name]
        proposed = {k: v for k, v in {"message": carrier.message, "signal": carrier.signal,
                                      "multiplexer": carrier.multiplexer,
                                      "rows": list(carrier.rows)}.items() if v not in ("", [])}
        if name not in truth:
            out.append(f"{name}: proposed {proposed}, the database does not carry it")
        elif proposed != _carrier(truth[name]):
            out.append(f"{name}: proposed {proposed}, carried by {_carrier(truth[name])}")
        out += [f"{name}: {e}" for e in problems
                if not e.note and e.key.split(".")[:2] == ["quantities", name]]
    return out


def _bind(contract: Contract, db: Database, folder: Path) -> str:
    path = folder / "generated.dbc"
    path.write_text(db.as_dbc_string(), encoding="utf-8")
    return write_binding(path, contract, relative_to=folder)


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_proposal_without_a_todo_is_right_and_passes_the_check(contract: Contract,
                                                                 data: st.DataObject) -> None:
    _property(contract, data)


@pytest.mark.slow
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_the_same_on_many_more_databases(contract: Contract, data: st.DataObject) -> None:
    _property(contract, data)


def _property(contract: Contract, data: st.DataObject) -> None:
    built = data.draw(databases(contract.rig.replace('_', '-')))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        text = _bind(contract, built.db, folder)
        wrong = wrong_and_unmarked(contract, built.truth, text, folder)
    assert not wrong, "\n".join(wrong) + "\n" + text


@settings(max_examples=20, deadline=None, derandomize=True, database=None)
@given(data=st.data())
def test_the_generated_true_carriers_pass_the_check(contract: Contract,
                                                    data: st.DataObject) -> None:
    """Else the property above would blame bind for the generator's signals."""
    built = data.draw(databases(contract.rig.replace('_', '-')))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "generated.dbc").write_text(built.db.as_dbc_string(), encoding="utf-8")
        binding = parse_binding({"rig": contract.rig, "database": "generated.dbc",
                                 "quantities": {k: _carrier(v)
                                                for k, v in built.truth.items()}},
                                source="truth.toml", base=folder)
        errors = [str(p) for p in check_binding(contract, binding)
                  if not p.note and not p.message.startswith("the rig needs")]
    assert not errors, errors


#: two sensors' counters in one multiplexed frame (the DP-200's sensor hub, in short)
HUB = Database(messages=[Message(0x6C0, "Hub", 8, [
    Signal("Channel", 0, 8, is_multiplexer=True, receivers=[DUT]),
    Signal("RollerTravel", 8, 24, unit="um", receivers=[DUT], multiplexer_ids=[1],
           multiplexer_signal="Channel"),
    Signal("WireSeq", 32, 4, receivers=[DUT], multiplexer_ids=[1], multiplexer_signal="Channel",
           comment="Draw-wire channel's rolling counter."),
    Signal("TiltSeq", 32, 4, receivers=[DUT], multiplexer_ids=[0], multiplexer_signal="Channel",
           comment="Inclinometer channel's rolling counter.")], senders=[PEER])],
    nodes=[Node(DUT), Node(PEER)])
HUB_TRUTH = {"roller_position": {"message": "Hub", "signal": "RollerTravel",
                                 "multiplexer": "Channel", "rows": [1]},
             "roller_position_counter": {"message": "Hub", "signal": "WireSeq",
                                         "multiplexer": "Channel", "rows": [1]},
             "inclinometer_counter": {"message": "Hub", "signal": "TiltSeq",
                                      "multiplexer": "Channel", "rows": [0]}}


def test_look_alike_counters_are_not_crossed(tmp_path: Path) -> None:
    depth = rig_contract("sowing-depth")
    text = _bind(depth, HUB, tmp_path)
    for name, truth in HUB_TRUTH.items():
        assert f"{name} = {{ message = \"Hub\", signal = \"{truth['signal']}\", " \
               f"multiplexer = \"Channel\", rows = {truth['rows']} }}" in text, text
    assert set(HUB_TRUTH) <= set(unmarked(text))
    assert wrong_and_unmarked(depth, HUB_TRUTH, text, tmp_path) == []


def test_the_property_fails_a_binder_that_crosses_or_drops_a_multiplexer(
        tmp_path: Path) -> None:
    depth = rig_contract("sowing-depth")
    text = _bind(depth, HUB, tmp_path)
    crossed = text.replace('"WireSeq"', '"@"').replace('"TiltSeq"', '"WireSeq"') \
        .replace('"@"', '"TiltSeq"')
    assert {w.split(":")[0] for w in wrong_and_unmarked(depth, HUB_TRUTH, crossed, tmp_path)} \
        == {"inclinometer_counter", "roller_position_counter"}
    plain = text.replace(', multiplexer = "Channel", rows = [1]', "")
    wrong = wrong_and_unmarked(depth, HUB_TRUTH, plain, tmp_path)
    assert any("names no multiplexer" in w for w in wrong), wrong
    # marked, the same guesses are the user's to check
    marked = crossed.replace('signal = "WireSeq", multiplexer = "Channel", rows = [0] }',
                             'signal = "WireSeq", multiplexer = "Channel", rows = [0] }\n'
                             "#   TODO: a guess")
    assert {w.split(":")[0] for w in wrong_and_unmarked(depth, HUB_TRUTH, marked, tmp_path)} \
        == {"roller_position_counter"}
