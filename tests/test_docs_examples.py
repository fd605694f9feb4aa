"""The examples in the docs are run by the tests (issue 7): a doc example that breaks fails CI.

Every fenced code block of ``README.md`` and of every page of the documentation site (``docs/``,
the list ``DOCS``) is extracted and handled by its language:

``sh`` / ``bash`` / ``shell`` / ``console``
    Each command line is run for real, in document order, as a reader would type it (a trailing
    ``\\`` joins lines; ``# comments`` are not part of the command). A comment on the line, or on
    comment-only lines right under it, that says ``exit N`` is the documented exit status and is
    asserted; otherwise the line must exit 0. With ``exit N: a, b`` after a ``hil qualify``, every
    named reason (``steady-state error`` -> ``steady_state_error``) must be in the name of a
    failed measurement of the record.
``python``
    The block runs in a subprocess (``python block.py``). API sketches leave some names to the
    reader (``seed``, ``n``, ``dt``, ``bus`` ...): ``PYTHON_PRELUDES`` defines them per block, and
    nothing else is changed.
``json`` / ``toml``
    Data examples, checked by the function ``DATA_CHECKS`` names for the document: the record
    example of ``docs/reference/record-format.md`` must have the keys a real record has; the
    baseline example of ``docs/reference/baseline-format.md`` and the tolerance file of
    ``docs/guide/gate-and-ci.md`` must load with the gate's own loaders.
no language, or ``text``
    Not examples (layouts, synopses, diagrams); a line in one that looks like a command
    (``hil ...``, ``python ...``, ``bash ...``, ``$ ...``) fails: tag the block.
``{directive}``
    A MyST directive (generated reference tables, API pages): not an example.

Where commands run, and the rules that adapt them (the only ones):

0. **Units.** A document is run as one or more units, one test each (``test_doc_examples[doc]``
   for the first, ``[doc:LINE]`` for the others, LINE its first block's): a block that names a
   path an earlier block writes (``qual/record.json`` after ``--out qual``; the outputs are
   the values of ``--out``, ``--summary``, ``-o``, ``-B``, an updated ``--baseline`` and hil's
   default output directories) is in the earlier block's unit, which runs its blocks in
   document order; any other block is a unit of its own. A long page is not one long test that
   keeps a worker busy after the other is done (the tour was ~50 s: its qualifications now run
   as separate tests). A dependency the rule misses fails the example (a missing file).
1. **A scratch checkout.** Each unit's commands run with ``cwd`` = a fresh directory under
   ``tmp_path`` that mirrors the repository: every tracked top-level entry is a symlink to the
   real one, except what examples write into, which is copied: ``ci/`` (baselines),
   ``dut_profiles/``, and ``firmware/generated/`` (``firmware/`` itself is a real directory of
   symlinks, so ``firmware/build`` lands in the scratch copy). Every output an example names
   (``out``, ``qual``, ``bad``, ``runs/step``, ``base.json``, ``gate.md``,
   ``ci/baselines/*.json``, ``firmware/build``) is therefore written under ``tmp_path``, never
   into the repository; paths in the commands are not rewritten. The venv's ``bin`` comes first
   on ``PATH``; ``GITHUB_STEP_SUMMARY`` is removed (``hil gate`` would append to CI's page) and
   ``MPLBACKEND=Agg`` set.
2. **Placeholders** of the docs are replaced token by token (``PLACEHOLDERS``): the example
   controller ``fertilizer-mycontroller-firmware`` and ``<DUT>`` stand for the reference
   firmware profile ``fertilizer-piecewise-pid-firmware``.
3. **``hil bus serve``** runs in the background with ``--port 0`` (a free port, read from its
   "listening on" line); ``--port P`` in the later lines of the block, P being the port the serve
   line asked for, becomes that port, and so does ``:P/`` inside a socketcand bus spec
   (``socketcand:127.0.0.1:P/can0``). The server is stopped (SIGINT) at the end of the block.
4. **``xdg-open FILE``** asserts that FILE exists and is not empty instead of opening it.
5. **``hil qualify``** with the same arguments apart from ``--out`` runs once per test session,
   for both xdist workers: a later identical line gets a copy of the first one's output
   directory and its exit status (lockstep qualifications are bit-for-bit repeatable; this
   saves ~15 s per repeat).
6. A line that needs a shell (``&&``, ``|``, ``>`` ...) is not run through one: it must be in
   ``SKIPPED`` or have a rule here.
7. **A line ending in ``&``** (a process the example keeps running, such as the controller that
   plays an outside ECU) runs in the background until the end of its block, then gets SIGTERM;
   it must still be running then (a background process that died is a failed example).
8. **A ``hil`` line** (not ``hil bus serve``, which runs in the background) runs in a ``hil``
   process of its own forked from a server that has imported ``hil`` and its libraries once
   (tests/helpers/hil_forkserver.py): the same argv, cwd, environment and ``sys.argv``, exit
   status and output as the ``hil`` script gives, without ~0.45 s of interpreter start-up
   and imports per line (~50 lines in the default run).

``SLOW_UNITS`` lists the lines whose unit runs only on request (``slow``), each with the
default run's test that covers it. ``SKIPPED`` lists, per document, the lines that are not
run, each with its reason. Any other
line is run: a new example either runs or fails until it is listed, and a ``SKIPPED`` entry whose
line left its document fails too. After a command, the outputs its document promises are checked
(``hil qualify``: record.json, junit.xml, report.html, and the ``--build-id`` in the record;
``hil run``: record.json, bus.log, bus.asc, traces.npz, plot.png with ``--plot``; ``hil
gate``: the ``--summary`` file, the baseline written by ``--update-baseline``;
``firmware/generate.sh``: files identical to the committed ones).

``test_readme_main_job`` (marked ``slow``) runs the command that ``scripts/qualify.sh`` execs
(README's main job, ~25 s), after checking that it is the one README quotes; the script itself
reinstalls the venv first, so it is not run as is. Everything else is in the default set:
~70 s on the 2-vCPU VM (three qualifications and the firmware build are most of it), ~95 s
with the slow test; the fertilizer controller guide adds ~40 s (its C example built, its profile
checked, the fast suite qualified over the software bus: ~25 s of it; measured on a quiet
machine).

``test_controller_guide_frames_are_the_databases`` holds the frame tables of the "Writing your
own controller" guides to the rigs' databases, and ``test_example_controller_is_written_without_
agrihil`` keeps the guide's C example to the C library and POSIX (no agrihil code).
``test_byo_controller_page_quotes_the_check`` holds the ``hil profile check`` output quoted
by "Bringing your own controller" to what the check says (that page's commands, a bind, two
checks and a qualification of its step tests, add ~27 s).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import pytest

from tests.helpers.hil_forkserver import HilForkServer, HilTimeout
from tests.helpers.session_shared import built_once

REPO = Path(__file__).resolve().parents[1]

def _documents() -> tuple[str, ...]:
    """README.md and every page of the documentation site (``docs/``), in a stable order."""
    pages = sorted(str(p.relative_to(REPO)) for p in (REPO / "docs").rglob("*.md")
                   if "_build" not in p.parts)
    return ("README.md", *pages)


DOCS = _documents()

#: a document whose commands that also appear, word for word, in another document are checked
#: there (the test of that document runs them under the same rules)
SAME_AS = {"README.md": "docs/getting-started/tour.md"}


@functools.cache
def _commands(doc: str) -> frozenset[str]:
    """Every shell command line of ``doc`` (as :class:`ShellLine` texts)."""
    return frozenset(line.text for block in blocks(doc) if block.lang in SHELL_LANGS
                     for line in shell_lines(block))


SKIPPED: dict[tuple[str, str], str] = {
    ("README.md", "hil isobus serve --bus socketcan:can0 "
     "--path plant_emulators/fertilizer/fields/field-rect.geojson "
     "--map plant_emulators/fertilizer/fields/rates-3zones.geojson"):
        "needs a CAN interface and runs until Ctrl-C: tests/hil/isobus/test_serve.py runs it on "
        "a virtual bus, and the interop runs in the guest on vcan",
    ("docs/guide/isobus.md", "hil isobus serve --bus socketcan:can0 "
     "--path plant_emulators/fertilizer/fields/field-rect.geojson "
     "--map plant_emulators/fertilizer/fields/rates-3zones.geojson "
     "--drive-after 10 --out isobus-out"):
        "needs a CAN interface and runs until Ctrl-C: tests/hil/isobus/test_serve.py runs it on "
        "a virtual bus, and the interop runs in the guest on vcan",
    ("docs/guide/virtual-terminal.md", "hil isobus serve --bus socketcan:can0 "
     "--path field.geojson --map rates.geojson --vt-browser 8080 --out isobus-out"):
        "needs a CAN interface and runs until Ctrl-C: tests/hil/isobus/vt/ runs the serve's VT "
        "and the browser VT on a virtual bus and in Chromium",
    ("README.md", "bash scripts/setup.sh && source .venv/bin/activate"):
        "reinstalls the venv this test runs in (pip install -e); the test already runs inside it",
    ("README.md", "bash scripts/qualify.sh"):
        "its first step reinstalls the venv; test_readme_main_job (slow) checks that the script "
        "execs the command README quotes and runs that command",
    ("README.md", "bash scripts/test.sh"):
        "CI's own command: the whole test suite, this file included (~3 min)",
    ("docs/getting-started/install.md", "bash scripts/qualify.sh"):
        "its first step reinstalls the venv; test_readme_main_job (slow) runs the command it execs",
    ("docs/getting-started/install.md", "bash scripts/test.sh"):
        "CI's own command: the whole test suite, this file included",
    ("docs/getting-started/tour.md", "bash scripts/setup.sh && source .venv/bin/activate"):
        "reinstalls the venv this test runs in; the test already runs inside it",
    ("docs/guide/running-on-can.md",
     "sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0"):
        "needs kernel SocketCAN: tests/kernel runs this inside a user-mode Linux guest",
    ("docs/guide/running-on-can.md",
     "hil qualify dut_profiles/fertilizer-piecewise-pid-firmware.toml --bus socketcan:vcan0 "
     "--out qual"):
        "needs kernel SocketCAN: tests/kernel runs this inside a user-mode Linux guest",
    ("docs/guide/kernel-can.md", "bash scripts/setup.sh --system-packages"):
        "installs system packages with apt (root); CI's setup does it when CI is set",
    ("docs/guide/kernel-can.md", "bash scripts/kernel-can.sh"):
        "boots the guest and runs the kernel_can tests: tests/kernel/test_guest.py does exactly "
        "that in this test run",
    ("docs/guide/kernel-can.md",
     "bash scripts/kernel-can.sh -- hil run --dut dut_profiles/fertilizer-piecewise-pid-firmware"
     ".toml --scenario bench-step-23 --bus socketcan:vcan0 --out /tmp/run"):
        "a lockstep run over vcan in the guest: tests/kernel runs the same inside the guest",
    ("docs/guide/kernel-can.md", "bash scripts/kernel-can.sh --check"):
        "its exit status depends on the machine (0 where the guest starts, 3 where it cannot); "
        "tests/kernel checks both paths",
    ("docs/guide/reference-qualification.md",
     "hil campaign dut_profiles/fertilizer-piecewise-pid-daemon.toml --bus inline --dispersion "
     "none --suite fast,robustness --samples 300 --seed 8100000 --out camp-fert"):
        "300 samples of fast + robustness take ~25 minutes on two cores: the page's evidence; "
        "tests/hil/campaign runs campaigns of 2-4 samples",
    ("docs/guide/reference-qualification.md",
     "python scripts/sweep_summary.py camp-fert/samples.jsonl --tolerances ci/tolerances.toml"):
        "reads the 300-sample campaign of the line above",
    ("docs/guide/physical-ecu.md",
     "hil qualify dut_profiles/physical/fertilizer-physical-ecu.toml --clock realtime "
     "--bus socketcan:can0 --out out/ecu"):
        "needs a physical ECU on can0; tests/kernel/test_physical_ecu.py qualifies one played "
        "by a process over the software bus and over vcan",
    ("docs/guide/campaigns.md",
     "hil campaign dut_profiles/fertilizer-piecewise-pid-firmware.toml --samples 300 --out camp"):
        "300 samples take ~10 minutes on two cores (benchmarks/bench_campaign.py); the next "
        "line runs a two-sample campaign the same way",
    ("docs/guide/gate-and-ci.md", "git diff ci/baselines/"):
        "reviews a change against the repository's history; the scratch checkout has none",
}

PLACEHOLDERS = {
    "fertilizer-mycontroller-firmware": "fertilizer-piecewise-pid-firmware",
    "<DUT>": "dut_profiles/fertilizer-piecewise-pid-firmware.toml",
}

#: names an API sketch leaves to the reader, per (document, n-th python block from 1)
PYTHON_PRELUDES = {
    ("docs/models/fertilizer.md", 1): '''\
import can
import numpy
from plant_emulators.fertilizer.analog_output import AnalogOutputChannel
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.flow_sensor import FlowSensor
from plant_emulators.fertilizer.frames import FertilizerDatabase
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel
from plant_emulators.fertilizer.physics import FertilizerPlant


class _Bus:
    def __init__(self):
        self.sent = []

    def send(self, msg):
        self.sent.append(msg)


bus = _Bus()
seed, n, dt = 0, 100, 0.001
raw_mv, counter = 5000, 0
received_msg = can.Message(arbitration_id=0x710, data=[0x05], is_extended_id=False)
''',
    ("docs/models/sowing-depth.md", 1): "seed, n, dt = 0, 100, 0.001\n",
}

#: units run only on request (``slow``): a unit holding one of these command lines (the whole
#: line as its document gives it), each with the default run's test that covers what it shows.
#: Everything here still runs in ``-m slow``; the default run (6 minutes on two cores) keeps
#: the units no other test covers.
SLOW_UNITS: dict[tuple[str, str], str] = {
    ("docs/guide/campaigns.md", "hil campaign dut_profiles/fertilizer-piecewise-pid-daemon.toml "
     "--samples 2 --bus inline --suite fast --workers 2 --out camp2"):
        "a campaign on two workers (~30 s): tests/hil/campaign/test_campaign_e2e.py runs "
        "campaigns end to end, a must-fail one failed",
    ("docs/guide/dut-profiles.md", "hil qualify dut_profiles/fertilizer-mycontroller-firmware.toml "
     "--bus softbus --out qual"):
        "a firmware qualified over the software bus, then gated against a baseline (~25 s): "
        "the tour (docs/getting-started/tour.md) runs the same three steps on the depth firmware",
    ("docs/guide/own-rig.md", "env PYTHONPATH=motor-meter hil qualify motor-meter/pi-speed.toml "
     "--rig motor-meter/motor-meter.rig.toml --bus inline --suite fast --out qual-pi"):
        "the rig of your own built and both controllers qualified (~15 s): "
        "tests/test_docs_example_own_rig.py builds the page's FMU, checks its rig file and runs "
        "both controllers through the step suite's metric",
    ("docs/guide/qualifying-an-isobus-implement.md", "hil qualify "
     "dut_profiles/fertilizer-piecewise-pid-isobus-daemon.toml --bus inline -k connection "
     "--out qual-isobus"):
        "an ISOBUS implement's connection tests (~12 s): tests/test_discrimination_isobus.py "
        "qualifies the same profile on the whole isobus suite",
    ("docs/examples/byo-depth/README.md", "hil qualify docs/examples/byo-depth/"
     "depthpro-dp200-daemon.toml --bus inline --suite fast -k step --out qual-dp200"):
        "a foreign depth controller's step tests (~12 s): tests/reference_controllers/"
        "test_depth_byo.py runs the DP-200's bindings against the reference's commands and the "
        "drive",
}

SHELL_LANGS = {"sh", "bash", "shell", "console"}
PYTHON_LANGS = {"python", "py"}
SHELL_OPERATORS = {"&&", "||", "|", ";", ">", ">>", "<", "&", "2>", "2>&1"}
#: files next to the scratch checkout's symlinks that examples write into
COPIED = ("ci", "dut_profiles", "firmware/generated")
#: the reference record the qualification-record example is compared with
RECORD_QUALIFY = ["hil", "qualify", "dut_profiles/fertilizer-piecewise-pid-firmware.toml",
                  "--bus", "softbus", "--out", "qual"]
LINE_TIMEOUT_S = 600


# ---------------------------------------------------------------------------------------------
# extraction


@dataclass
class Block:
    doc: str
    lang: str
    lineno: int                              # line of the opening fence
    lines: list[tuple[int, str]]             # (line number, text)

    @property
    def text(self) -> str:
        return "".join(t + "\n" for _, t in self.lines)


@dataclass
class ShellLine:
    doc: str
    lineno: int
    text: str                                # the command, comments cut, whitespace collapsed
    argv: list[str]
    comment: str = ""

    @property
    def where(self) -> str:
        return f"{self.doc}:{self.lineno}: {self.text}"

    @property
    def expected_exit(self) -> int:
        m = re.search(r"\bexit (\d+)", self.comment)
        return int(m.group(1)) if m else 0


FENCE = re.compile(r"^```(.*)$")


def blocks(doc: str) -> list[Block]:
    out: list[Block] = []
    current: Block | None = None
    for no, line in enumerate((REPO / doc).read_text(encoding="utf-8").splitlines(), 1):
        m = FENCE.match(line)
        if current is None:
            if m:
                info = m.group(1).strip()
                current = Block(doc, info.split()[0].lower() if info else "", no, [])
        elif m and not m.group(1).strip():
            out.append(current)
            current = None
        else:
            current.lines.append((no, line))
    assert current is None, f"{doc}:{current.lineno}: code block never closed"
    return out


def shell_lines(block: Block) -> list[ShellLine]:
    out: list[ShellLine] = []
    pending, start = "", 0
    last_was_command = False
    for no, raw in block.lines:
        if not pending:
            start = no
        pending = f"{pending} {raw.strip()}" if pending else raw
        if pending.rstrip().endswith("\\"):
            pending = pending.rstrip()[:-1]
            continue
        logical, pending = pending, ""
        cut = re.search(r"(?:^|\s)#", logical)
        command = logical[:cut.start()] if cut else logical
        comment = logical[cut.end():].strip() if cut else ""
        if not command.strip():
            if comment and last_was_command:          # a comment-only line under a command
                out[-1].comment = f"{out[-1].comment} {comment}".strip()
            last_was_command = last_was_command and bool(comment)
            continue
        out.append(ShellLine(block.doc, start, " ".join(command.split()),
                             shlex.split(command), comment))
        last_was_command = True
    return out


# ---------------------------------------------------------------------------------------------
# the units of a document: its blocks, apart where they can be


#: options whose value is a path the command writes (``hil ... --out``, ``hil gate --summary``,
#: ``hil profile bind -o``, ``cc -o``, ``cmake -B``)
OUTPUT_OPTIONS = ("--out", "--summary", "-o", "-B")
#: where a command writes when it is given no ``--out`` (hil's defaults)
DEFAULT_OUTPUTS = {("hil", "qualify"): "out", ("hil", "campaign"): "campaign",
                   ("hil", "run"): "runs", ("hil", "isobus"): "isobus-out"}


@functools.cache
def _top_level() -> frozenset[str]:
    return frozenset(f.split("/")[0] for f in tracked_files())


def written_names(line: ShellLine) -> set[str]:
    """What ``line`` writes into the scratch checkout, as a later block would name it: the first
    component of a new path (``qual`` for ``qual/record.json``), or the whole path inside a
    directory of the repository (``ci/baselines/x.json``, ``firmware/build``)."""
    argv = [DocRunner.placeholder(t) for t in line.argv]
    paths = [option(argv, name) for name in OUTPUT_OPTIONS]
    if "--update-baseline" in argv:
        paths.append(option(argv, "--baseline"))
    if "--out" not in argv:
        paths.append(DEFAULT_OUTPUTS.get(tuple(argv[:2])))
    names = set()
    for path in filter(None, paths):
        parts = Path(path).parts
        names.add(path if parts[0] in _top_level() else parts[0])
    return names


def mentions(block: Block, name: str) -> bool:
    """Whether ``block`` names the path ``name`` (or something inside it)."""
    return re.search(rf"(?<![\w./-]){re.escape(name)}(?![\w.-])", block.text) is not None


@functools.cache
def units(doc: str) -> tuple[tuple[int, ...], ...]:
    """The blocks of ``doc`` (indices into :func:`blocks`), in the units that must run together
    (rule 0 of the module docstring)."""
    return group_blocks(doc, blocks(doc))


def group_blocks(doc: str, all_blocks: list[Block]) -> tuple[tuple[int, ...], ...]:
    """Rule 0: a block that names what an earlier block writes (:func:`written_names`) joins
    that block's unit; every other block that runs something is a unit of its own. Blocks that
    run nothing (text, directives) go with the first unit, and a document without blocks is one
    empty unit, so every page keeps a test."""
    parent = list(range(len(all_blocks)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    runs = [i for i, b in enumerate(all_blocks)
            if b.lang in SHELL_LANGS | PYTHON_LANGS or b.lang in ("json", "toml")]
    for i in set(range(len(all_blocks))) - set(runs):
        parent[i] = runs[0] if runs else 0
    writes: dict[int, set[str]] = {}
    for j in runs:
        for i, names in writes.items():
            if any(mentions(all_blocks[j], name) for name in names):
                parent[root(j)] = root(i)
        if all_blocks[j].lang in SHELL_LANGS:
            writes[j] = {name for line in shell_lines(all_blocks[j])
                         if (doc, line.text) not in SKIPPED for name in written_names(line)}
    grouped: dict[int, list[int]] = {}
    for i in range(len(all_blocks)):
        grouped.setdefault(root(i), []).append(i)
    return tuple(sorted((tuple(g) for g in grouped.values()), key=lambda g: g[0])) or ((),)


def unit_params() -> list[object]:
    """One test per unit: the document's name for its first unit (a document of one unit keeps
    its old test id), ``doc:LINE`` (the unit's first block) for the others."""
    params = []
    for doc in DOCS:
        for n, unit in enumerate(units(doc)):
            name = doc if n == 0 else f"{doc}:{blocks(doc)[unit[0]].lineno}"
            shell = [blocks(doc)[i] for i in unit if blocks(doc)[i].lang in SHELL_LANGS]
            slow = any((doc, line.text) in SLOW_UNITS
                       for block in shell for line in shell_lines(block))
            params.append(pytest.param(doc, unit, id=name,
                                       marks=[pytest.mark.slow] if slow else []))
    return params


# ---------------------------------------------------------------------------------------------
# the scratch checkout and running commands


def tracked_files() -> list[str]:
    try:
        listing = subprocess.run(["git", "-C", str(REPO), "ls-files", "-z"], check=True,
                                 capture_output=True, timeout=60).stdout.decode()
        files = [f for f in listing.split("\0") if f]
    except (OSError, subprocess.SubprocessError):
        files = []
    if files:
        return files
    # not a git checkout: every entry but hidden ones and the outputs .gitignore names
    ignored = {"out", "runs", "build", "dist", "__pycache__"}
    return [str(p.relative_to(REPO)) for p in REPO.rglob("*")
            if p.is_file() and not any(part.startswith(".") or part in ignored
                                       or part.endswith(".egg-info")
                                       for part in p.relative_to(REPO).parts)]


def make_checkout(dest: Path, files: list[str]) -> Path:
    """``dest`` mirrors the repository: symlinks, except ``COPIED`` (see the module docstring)."""

    def populate(rel: str, target: Path) -> None:
        prefix = f"{rel}/" if rel else ""
        children = sorted({f[len(prefix):].split("/")[0] for f in files if f.startswith(prefix)})
        target.mkdir(parents=True, exist_ok=True)
        for child in children:
            path = f"{prefix}{child}"
            if path in COPIED:
                if (REPO / path).is_dir():
                    shutil.copytree(REPO / path, target / child, symlinks=True)
                else:
                    shutil.copy2(REPO / path, target / child)
            elif any(c.startswith(f"{path}/") for c in COPIED):
                populate(path, target / child)
            elif (REPO / path).exists():
                (target / child).symlink_to(REPO / path)

    populate("", dest)
    return dest


def child_env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("GITHUB_STEP_SUMMARY", None)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["MPLBACKEND"] = "Agg"
    return env


@dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str
    seconds: float


def run(argv: list[str], cwd: Path, hil: HilForkServer | None = None) -> Result:
    """``argv`` in ``cwd`` with :func:`child_env`; a ``hil`` line through ``hil`` (rule 8)."""
    t0 = time.monotonic()
    if hil is not None and argv[0] == "hil":
        try:
            done = hil.run(argv[1:], cwd, timeout_s=LINE_TIMEOUT_S)
        except HilTimeout:
            pytest.fail(f"{shlex.join(argv)} still ran after {LINE_TIMEOUT_S} s")
        return Result(done.returncode, done.stdout, done.stderr, time.monotonic() - t0)
    try:
        proc = subprocess.run(argv, cwd=cwd, env=child_env(), capture_output=True, text=True,
                              timeout=LINE_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except FileNotFoundError as exc:                   # as a shell says: command not found
        return Result(127, "", str(exc), time.monotonic() - t0)
    return Result(proc.returncode, proc.stdout, proc.stderr, time.monotonic() - t0)


def option(argv: list[str], name: str, default: str | None = None) -> str | None:
    for i, token in enumerate(argv[:-1]):
        if token == name:
            return argv[i + 1]
    return default


def without_option(argv: list[str], name: str) -> tuple[str, ...]:
    out, skip = [], False
    for i, token in enumerate(argv):
        if skip:
            skip = False
        elif token == name and i + 1 < len(argv):
            skip = True
        else:
            out.append(token)
    return tuple(out)


class QualifyMemo:
    """Rule 5: one real run per distinct ``hil qualify`` line (``--out`` aside) per test session,
    shared by the session's pytest-xdist workers (:func:`built_once`): the first test that needs
    the line runs it and keeps its result and output directory; a later one, on either worker,
    waits for it if it is still running and gets a copy."""

    def __init__(self, factory: pytest.TempPathFactory, hil: HilForkServer) -> None:
        self.factory = factory
        self.hil = hil

    def run(self, argv: list[str], cwd: Path) -> tuple[Result, bool]:
        out = cwd / (option(argv, "--out", "out") or "out")
        key = "\0".join(without_option(argv, "--out"))
        name = f"qualify-{hashlib.sha256(key.encode()).hexdigest()[:16]}"
        with built_once(self.factory, name) as (entry, built):
            kept, saved = entry / "out", entry / "result.json"
            if built:
                if out.exists():
                    shutil.rmtree(out)
                if kept.exists():
                    shutil.copytree(kept, out)
                return Result(**json.loads(saved.read_text())), True
            result = run(argv, cwd, self.hil)
            if out.exists():
                shutil.copytree(out, kept)
            saved.write_text(json.dumps(asdict(result)))
            return result, False


@pytest.fixture(scope="session")
def hil_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[HilForkServer]:
    """Rule 8: the fork server of this worker's ``hil`` lines, in the examples' environment."""
    with HilForkServer(tmp_path_factory.mktemp("hil-forkserver"), env=child_env(),
                       script=True) as server:
        yield server


@pytest.fixture(scope="session")
def qualify_memo(tmp_path_factory: pytest.TempPathFactory,
                 hil_server: HilForkServer) -> QualifyMemo:
    return QualifyMemo(tmp_path_factory, hil_server)


@pytest.fixture(scope="session")
def repo_files() -> list[str]:
    return tracked_files()


def invalid_bench(argv: list[str], cwd: Path, result: Result) -> bool:
    """A real-time ``hil qualify`` that exited 2 because its bench timing was invalid."""
    if argv[:2] != ["hil", "qualify"] or "realtime" not in argv or result.returncode != 2:
        return False
    out = argv[argv.index("--out") + 1] if "--out" in argv else "qual"
    record = cwd / out / "record.json"
    try:
        return json.loads(record.read_text(encoding="utf-8")).get("verdict") == "invalid-bench"
    except (OSError, ValueError):
        return False


def explain(line: ShellLine, argv: list[str], result: Result) -> str:
    def tail(text: str) -> str:
        return "\n".join(text.strip().splitlines()[-25:])

    return (f"{line.where}\n  ran: {shlex.join(argv)}\n  exit {result.returncode}, documented "
            f"{line.expected_exit}\n--- stdout (tail)\n{tail(result.stdout)}\n"
            f"--- stderr (tail)\n{tail(result.stderr)}")


# ---------------------------------------------------------------------------------------------
# what a document's commands promise


def check_outputs(line: ShellLine, argv: list[str], cwd: Path, result: Result) -> None:
    def must_exist(rel: str, what: str) -> None:
        assert (cwd / rel).is_file() and (cwd / rel).stat().st_size > 0, (
            f"{line.where}\n  {what} {rel} was not written")

    if argv[:2] == ["hil", "qualify"] and result.returncode in (0, 1):
        out = option(argv, "--out", "out")
        for name in ("record.json", "junit.xml", "report.html"):
            must_exist(f"{out}/{name}", "hil qualify:")
        build_id = option(argv, "--build-id")
        if build_id is not None:                 # "dut.build_id: ... or --build-id"
            record = json.loads((cwd / f"{out}/record.json").read_text())
            assert record["dut"]["build_id"] == build_id, (
                f"{line.where}\n  record.json has dut.build_id {record['dut']['build_id']!r}")
        reasons = line.comment.partition(":")[2] if result.returncode == 1 else ""
        if reasons.strip():
            record = json.loads((cwd / f"{out}/record.json").read_text())
            failed = {m["name"] for m in record["measurements"]
                      if m["outcome"] in ("fail", "error")}
            for reason in reasons.split(","):
                token = re.sub(r"[-\s]+", "_", reason.strip())
                assert any(token in name for name in failed), (
                    f"{line.where}\n  documented to fail on {reason.strip()!r}; the failed "
                    f"measurements are {sorted(failed)}")
    elif argv[:2] == ["hil", "run"] and "--list-scenarios" not in argv and result.returncode == 0:
        out = option(argv, "--out", f"runs/{option(argv, '--scenario')}")
        names = ["record.json", "bus.log", "bus.asc", "traces.npz"]
        names += ["plot.png"] * ("--plot" in argv) + ["traces.csv"] * ("--csv" in argv)
        for name in names:
            must_exist(f"{out}/{name}", "hil run:")
    elif argv == ["firmware/generate.sh"]:
        # "an unchanged database regenerates identical files"
        fresh, committed = cwd / "firmware/generated", REPO / "firmware/generated"
        differ = [p.name for p in sorted(committed.iterdir())
                  if p.read_bytes() != (fresh / p.name).read_bytes()]
        assert not differ, f"{line.where}\n  regenerated files differ: {differ}"
    elif argv[:2] == ["hil", "gate"] and result.returncode == 0:
        summary = option(argv, "--summary")
        if summary:
            must_exist(summary, "hil gate --summary:")
        if "--update-baseline" in argv:
            must_exist(option(argv, "--baseline") or "", "hil gate --update-baseline:")


# ---------------------------------------------------------------------------------------------
# the runner of one document


@dataclass
class Server:
    proc: subprocess.Popen[bytes]
    asked_port: str
    port: str
    log: Path


@dataclass
class Background:
    proc: subprocess.Popen[bytes]
    where: str
    log: Path


@dataclass
class DocRunner:
    doc: str
    cwd: Path
    scratch: Path
    memo: QualifyMemo
    ran: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    background: list[Background] = field(default_factory=list)

    def block(self, block: Block) -> None:
        if block.lang in SHELL_LANGS:
            server: Server | None = None
            try:
                for line in shell_lines(block):
                    server = self.line(line, server) or server
            finally:
                self.stop_background()
                if server is not None:
                    self.stop(server)
        elif block.lang in PYTHON_LANGS:
            self.python(block)
        elif block.lang in ("json", "toml"):
            check = DATA_CHECKS.get((self.doc, block.lang))
            assert check is not None, (
                f"{self.doc}:{block.lineno}: a ```{block.lang} block without a check in "
                "DATA_CHECKS: add one (or make it an untagged block if it is not an example)")
            check(self, block)
            self.ran.append(f"{self.doc}:{block.lineno}: ```{block.lang} block ({check.__name__})")
        elif block.lang.startswith("{"):
            pass                                       # a MyST directive: generated content
        elif block.lang in ("", "text"):
            for no, text in block.lines:
                if block.lang == "text" and re.search(r"\bPROFILE\b|\.\.\.|DUT-|\\$", text):
                    continue      # a synopsis (a placeholder, an elision): not a command
                assert not re.match(r"\s*(\$ |hil |python3? |bash )", text), (
                    f"{self.doc}:{no}: a command in an untagged code block: tag it ```sh so "
                    "that it runs")
        else:
            pytest.fail(f"{self.doc}:{block.lineno}: no rule for ```{block.lang} blocks")

    def line(self, line: ShellLine, server: Server | None) -> Server | None:
        reason = SKIPPED.get((self.doc, line.text))
        if reason is None and self.doc in SAME_AS and line.text in _commands(SAME_AS[self.doc]):
            # the README's tour is the tour page, command for command: this very test runs
            # each of them there (same scratch rules), so the run is not made twice
            reason = f"the same command runs in {SAME_AS[self.doc]}'s test"
        if reason is not None:
            self.skipped.append(f"{line.where}  [{reason}]")
            return None
        argv = [self.placeholder(t) for t in line.argv]
        if server is not None and "--port" in argv:
            i = argv.index("--port")
            if i + 1 < len(argv) and argv[i + 1] == server.asked_port:
                argv[i + 1] = server.port
        if server is not None:
            argv = [t.replace(f":{server.asked_port}/", f":{server.port}/")
                    if t.startswith("socketcand:") else t for t in argv]
        if argv and argv[-1] == "&":
            return self.start_background(line, argv[:-1])
        assert not SHELL_OPERATORS & set(argv), (
            f"{line.where}\n  needs a shell: give it a rule in this test or list it in SKIPPED")
        if argv[:3] == ["hil", "bus", "serve"]:
            return self.serve(line, argv)
        if argv[0] == "xdg-open":
            target = self.cwd / argv[1]
            assert target.is_file() and target.stat().st_size > 0, (
                f"{line.where}\n  nothing to open: {argv[1]} does not exist")
            self.ran.append(f"{line.where}  [checked the file exists]")
            return None
        if argv[:2] == ["hil", "qualify"]:
            result, reused = self.memo.run(argv, self.cwd)
        else:
            result, reused = run(argv, self.cwd, self.memo.hil), False
        if invalid_bench(argv, self.cwd, result):
            # a real-time qualification on a shared VM: the rig judged its own timing out of
            # bounds and said so (exit 2, verdict invalid-bench), which is no verdict on the
            # controller and no error in the page; tests/kernel/test_physical_ecu.py handles
            # the same way the run it makes in the guest
            self.ran.append(f"{line.where}  ({result.seconds:.1f} s, exit 2: invalid bench, "
                            "the host's real-time timing was out of bounds)")
            return None
        assert result.returncode == line.expected_exit, explain(line, argv, result)
        check_outputs(line, argv, self.cwd, result)
        note = "  [same qualification as earlier: output reused]" if reused else ""
        self.ran.append(f"{line.where}  ({result.seconds:.1f} s, exit {result.returncode}){note}")
        return None

    @staticmethod
    def placeholder(token: str) -> str:
        for old, new in PLACEHOLDERS.items():
            token = token.replace(old, new)
        return token

    def serve(self, line: ShellLine, argv: list[str]) -> Server:
        asked = option(argv, "--port", "29536") or "29536"
        argv = [*without_option(argv, "--port"), "--port", "0"]
        log = self.scratch / f"serve-{line.lineno}.out"
        with log.open("wb") as sink:
            proc = subprocess.Popen(argv, cwd=self.cwd, env=child_env(), stdout=sink,
                                    stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            m = re.search(r"listening on [^\s:]+:(\d+)", log.read_text(errors="replace"))
            if m:
                self.ran.append(f"{line.where}  [background, --port 0 -> {m.group(1)}]")
                return Server(proc, asked, m.group(1), log)
            if proc.poll() is not None:
                break
            time.sleep(0.05)
        server = Server(proc, asked, "", log)
        self.stop(server)
        pytest.fail(f"{line.where}\n  the server did not start:\n{log.read_text()}")

    def start_background(self, line: ShellLine, argv: list[str]) -> None:
        log = self.scratch / f"background-{line.lineno}.out"
        with log.open("wb") as sink:
            proc = subprocess.Popen(argv, cwd=self.cwd, env=child_env(), stdout=sink,
                                    stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        self.background.append(Background(proc, line.where, log))
        self.ran.append(f"{line.where}  [background until the end of the block]")

    def stop_background(self) -> None:
        died = []
        while self.background:
            job = self.background.pop()
            if job.proc.poll() is not None:
                died.append(f"{job.where}\n  exited {job.proc.returncode} before the end of "
                            f"its block:\n{job.log.read_text(errors='replace')[-3000:]}")
                continue
            job.proc.terminate()
            try:
                job.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                job.proc.kill()
                job.proc.wait(timeout=10)
        assert not died, "\n".join(died)

    @staticmethod
    def stop(server: Server) -> None:
        if server.proc.poll() is None:
            server.proc.send_signal(signal.SIGINT)
            try:
                server.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                server.proc.kill()
                server.proc.wait(timeout=10)
                pytest.fail(f"hil bus serve did not stop on SIGINT:\n{server.log.read_text()}")

    def python(self, block: Block) -> None:
        nth = [b.lineno for b in blocks(self.doc) if b.lang in PYTHON_LANGS].index(block.lineno)
        prelude = PYTHON_PRELUDES.get((self.doc, nth + 1), "")
        script = self.scratch / f"block-{block.lineno}.py"
        script.write_text(prelude + "\n# --- the document's block ---\n" + block.text)
        result = run([sys.executable, str(script)], self.cwd)
        assert result.returncode == 0, (
            f"{self.doc}:{block.lineno}: python block failed (exit {result.returncode})\n"
            f"{result.stderr[-3000:]}")
        self.ran.append(f"{self.doc}:{block.lineno}: ```python block ({result.seconds:.1f} s)")


# ---------------------------------------------------------------------------------------------
# data examples


def check_record_example(runner: DocRunner, block: Block) -> None:
    """The documented record has the keys of a real one (top level and each nested object)."""
    text = re.sub(r"\s+//[^\n]*", "", block.text)
    example = json.loads(text)
    result, _ = runner.memo.run(list(RECORD_QUALIFY), runner.cwd)
    assert result.returncode == 0, f"the reference qualification failed:\n{result.stderr[-3000:]}"
    real = json.loads((runner.cwd / "qual/record.json").read_text())
    assert example["schema"] == real["schema"]
    pairs = [("record", example, real)]
    pairs += [(key, example[key], real[key]) for key in ("dut", "rig")]
    pairs += [(f"{key}[]", example[key][0], real[key][0])
              for key in ("measurements", "tests", "runs")]
    for where, documented, actual in pairs:
        assert set(documented) == set(actual), (
            f"{runner.doc}:{block.lineno}: keys of {where}: documented but not written "
            f"{sorted(set(documented) - set(actual))}, written but not documented "
            f"{sorted(set(actual) - set(documented))}")


def check_tolerance_example(runner: DocRunner, block: Block) -> None:
    """The tolerance file example loads with the gate's loader (names from the catalogue)."""
    from hil.gate.tolerance import load_tolerances

    path = runner.scratch / f"tolerances-{block.lineno}.toml"
    path.write_text(block.text)
    load_tolerances(path)


def check_campaign_toml_example(runner: DocRunner, block: Block) -> None:
    """A dispersion example loads with the campaign's loader; a ``[campaign]`` table example
    loads as part of a real profile."""
    import tomllib

    data = tomllib.loads(block.text)
    if "campaign" in data:
        from hil.dut.profile import load_profile

        profile = (REPO / "dut_profiles/fertilizer-piecewise-pid-daemon.toml").read_text()
        path = runner.scratch / f"{block.lineno}" / "fertilizer-piecewise-pid-daemon.toml"
        path.parent.mkdir()
        path.write_text(profile + "\n" + block.text)
        load_profile(path)
        return
    from hil.campaign.dispersion import load_dispersion

    path = runner.scratch / f"dispersion-{block.lineno}.toml"
    path.write_text(block.text)
    load_dispersion(path, rig="fertilizer")


def check_baseline_example(runner: DocRunner, block: Block) -> None:
    """The baseline example loads with the gate's own loader (keys match name + conditions)."""
    from hil.gate.baseline import load_baseline

    path = runner.scratch / f"baseline-{block.lineno}.json"
    path.write_text(block.text)
    load_baseline(path)


def check_isobus_faults_example(runner: DocRunner, block: Block) -> None:
    """The fault tables load with the network's own parser, every kind the page lists."""
    import tomllib

    from hil.isobus.faults import parse_faults

    entries = tomllib.loads(block.text)["isobus"]["faults"]
    faults = parse_faults(entries, path=f"{block.lineno}")
    assert faults.contend and faults.dropped_cts and faults.aborts and faults.late_packets, faults
    runner.ran.append(f"docs/guide/isobus-network.md:{block.lineno}  [loaded by parse_faults]")


def check_vt_operator_example(runner: DocRunner, block: Block) -> None:
    """The ``[[operator]]`` list loads with the VT's own reader, each kind of step it shows."""
    import tempfile

    from hil.isobus.vt.operator import read_operator_steps

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scenario.toml"
        path.write_text(block.text)
        steps = read_operator_steps(path)
    assert len(steps) == block.text.count("[[operator]]") == 3, steps
    assert [s.at_s for s in steps] == [12.0, 20.0, 40.0], steps
    runner.ran.append(f"docs/guide/virtual-terminal.md:{block.lineno}  "
                      "[loaded by read_operator_steps]")


DATA_CHECKS: dict[tuple[str, str], Callable[[DocRunner, Block], None]] = {
    ("docs/guide/virtual-terminal.md", "toml"): check_vt_operator_example,
    ("docs/guide/isobus-network.md", "toml"): check_isobus_faults_example,
    ("docs/reference/record-format.md", "json"): check_record_example,
    ("docs/reference/baseline-format.md", "json"): check_baseline_example,
    ("docs/guide/gate-and-ci.md", "toml"): check_tolerance_example,
    ("docs/guide/campaigns.md", "toml"): check_campaign_toml_example,
}


# ---------------------------------------------------------------------------------------------
# the tests


@pytest.fixture
def checkout(tmp_path: Path, repo_files: list[str]) -> Iterator[Path]:
    yield make_checkout(tmp_path / "checkout", repo_files)


@pytest.mark.parametrize(("doc", "unit"), unit_params())
def test_doc_examples(doc: str, unit: tuple[int, ...], checkout: Path, tmp_path: Path,
                      qualify_memo: QualifyMemo) -> None:
    runner = DocRunner(doc, checkout, tmp_path, qualify_memo)
    all_blocks = blocks(doc)
    for index in unit:
        runner.block(all_blocks[index])
    print(f"\n{doc}: {len(runner.ran)} run, {len(runner.skipped)} skipped")
    for entry in runner.ran:
        print(f"  ran   {entry}")
    for entry in runner.skipped:
        print(f"  skip  {entry}")


def test_units_keep_a_block_with_the_block_whose_output_it_reads() -> None:
    """Rule 0 on a page of its own: the gate that reads ``qual/record.json`` runs after the
    qualification that writes ``qual`` (even two blocks later, and through a python block's
    string), the qualification of ``bad`` and the bind's ``-o`` output apart, the text block
    with the first unit; and every block is in exactly one unit."""
    def block(lineno: int, lang: str, *lines: str) -> Block:
        return Block("page.md", lang, lineno, [(lineno + 1 + i, t) for i, t in enumerate(lines)])

    page = [block(1, "", "a layout, not an example"),
            block(5, "sh", "hil qualify dut_profiles/x.toml --bus softbus --out qual"),
            block(9, "sh", "hil qualify dut_profiles/y.toml --bus inline --out bad  # exit 1"),
            block(13, "sh", "hil profile bind x.dbc --rig fertilizer -o x.binding.toml"),
            block(17, "sh", "hil gate qual/record.json --baseline base.json --update-baseline"),
            block(21, "python", "import json", "json.load(open('base.json'))"),
            block(25, "sh", "hil run --rig fertilizer --scenario bench-step --out qualms")]
    assert group_blocks("page.md", page) == ((0, 1, 4, 5), (2,), (3,), (6,))
    for doc in DOCS:
        indices = sorted(i for unit in units(doc) for i in unit)
        assert indices == list(range(len(blocks(doc)))), doc


def test_docs_pages_listed_longest_first_exist() -> None:
    """tests/conftest.py hands the units of the longest docs pages out first, by page: a page
    that was renamed or lost its examples would silently stop being."""
    from tests.conftest import DOCS as PREFIX
    from tests.conftest import LONGEST_FIRST

    ids = [f"{PREFIX}[{param.id}]" for param in unit_params()]  # type: ignore[attr-defined]
    named = [entry for entry in LONGEST_FIRST if entry.startswith(f"{PREFIX}[")]
    assert named, "tests/conftest.py names no docs page"
    gone = [entry for entry in named if not any(i.startswith(entry) for i in ids)]
    assert not gone, f"docs pages in tests/conftest.py LONGEST_FIRST without units: {gone}"


def test_skip_table_is_current() -> None:
    """A skipped line that left its document is a stale entry (and hides nothing)."""
    present = {(doc, line.text) for doc in DOCS for block in blocks(doc)
               if block.lang in SHELL_LANGS for line in shell_lines(block)}
    for name, table in (("SKIPPED", SKIPPED), ("SLOW_UNITS", SLOW_UNITS)):
        stale = [f"{doc}: {text}" for doc, text in table if (doc, text) not in present]
        assert not stale, f"{name} entries no document has any more: {stale}"
    assert all(doc in DOCS for doc, _ in PYTHON_PRELUDES), "a prelude for an unlisted document"
    assert all(doc in DOCS for doc, _ in DATA_CHECKS), "a data check for an unlisted document"


def test_every_document_with_examples_is_listed(repo_files: list[str]) -> None:
    """A Markdown file with tagged code blocks must be in DOCS, so its examples run."""
    unlisted = []
    for name in repo_files:
        if name.endswith(".md") and name not in DOCS and (REPO / name).is_file():
            langs = {b.lang for b in blocks(name)} - {""}
            if langs:
                unlisted.append(f"{name} ({', '.join(sorted(langs))})")
    assert not unlisted, f"documents with examples that no test runs (add them to DOCS): {unlisted}"


@pytest.mark.slow
def test_readme_main_job(checkout: Path) -> None:
    """README's main job: what ``bash scripts/qualify.sh`` execs, run as documented (~25 s)."""
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert any(line.text == "bash scripts/qualify.sh" for block in blocks("README.md")
               if block.lang in SHELL_LANGS for line in shell_lines(block))
    quoted = re.search(r"main job runs\s+`([^`]+)`", " ".join(readme.split()))
    assert quoted, "README no longer says which command the main job runs"
    script = (REPO / "scripts/qualify.sh").read_text(encoding="utf-8")
    execs = re.search(r"^exec (.*?)(?: \"\$@\")?$", script, re.M)
    assert execs and execs.group(1) == quoted.group(1), (
        f"scripts/qualify.sh execs {execs and execs.group(1)!r}, README says {quoted.group(1)!r}")
    argv = shlex.split(quoted.group(1))
    result = run(argv, checkout)
    line = ShellLine("scripts/qualify.sh", 0, quoted.group(1), argv, "exit 0")
    assert result.returncode == 0, explain(line, argv, result)
    check_outputs(line, argv, checkout, result)


# ---------------------------------------------------------------------------------------------
# the "Writing your own controller" guides (issue 31.3): their frame tables are the databases'

#: guide -> (its rig's DBC, the DUT's node in it, ids the DBC gives the DUT that the page says
#: the rig never sends, the CiA 301 / EDS ids the page adds to the DBC's)
CONTROLLER_GUIDES = {
    "docs/guide/writing-a-fertilizer-controller.md": (
        "plant_emulators/fertilizer/db/fertilizer.dbc", "Controller",
        {0x000},                                 # the fertilizer rig sends no NMT command
        {0x080}),                                # SYNC
    "docs/guide/writing-a-depth-controller.md": (
        "plant_emulators/sowing_depth/db/sowing_depth.dbc", "DepthController", set(),
        # SYNC, NMT, the DUT's heartbeat; the drive's (node 2) EMCY, SDO, heartbeat, and its
        # PDOs as firmware/generated/servo_cylinder_pdo.dbc has them from its EDS
        {0x080, 0x000, 0x701, 0x082, 0x582, 0x602, 0x702, 0x182, 0x282, 0x382, 0x202, 0x302,
         0x402}),
}
GUIDE_ID = re.compile(r"`(0x[0-9A-Fa-f]+)`(?:-`(0x[0-9A-Fa-f]+)`)?")


def guide_table_ids(doc: str, heading: str) -> set[int]:
    """The identifiers in the first column of the table under ``heading`` (ranges expanded)."""
    text = (REPO / doc).read_text(encoding="utf-8")
    section = text.split(heading, 1)[1].split("\n#", 1)[0]
    ids: set[int] = set()
    for row in section.splitlines():
        if row.startswith("| `"):
            for first, last in GUIDE_ID.findall(row.split("|")[1]):
                ids.update(range(int(first, 16), int(last or first, 16) + 1))
    return ids


@pytest.mark.parametrize("doc", sorted(CONTROLLER_GUIDES))
def test_controller_guide_frames_are_the_databases(doc: str) -> None:
    import cantools

    dbc, node, not_sent, canopen = CONTROLLER_GUIDES[doc]
    db = cantools.database.load_file(REPO / dbc)
    received = guide_table_ids(doc, "### What the controller receives")
    sent = guide_table_ids(doc, "### What the controller must send")
    assert received and sent, f"{doc}: no frame tables found"
    dut_sends = {m.frame_id for m in db.messages if node in m.senders}
    dut_receives = {m.frame_id for m in db.messages if node in m.receivers} - not_sent
    assert dut_sends <= sent, (f"{doc}: the DBC has the DUT send "
                               f"{sorted(hex(i) for i in dut_sends - sent)}, the page does not")
    assert dut_receives <= received, (
        f"{doc}: the DBC has the DUT receive {sorted(hex(i) for i in dut_receives - received)}, "
        "the page does not")
    unknown = (received | sent) - {m.frame_id for m in db.messages} - canopen
    assert not unknown, f"{doc}: ids on the page that no database has: {sorted(map(hex, unknown))}"
    if node == "DepthController":                # the drive's PDOs, from its EDS
        pdo = cantools.database.load_file(REPO / "firmware/generated/servo_cylinder_pdo.dbc")
        assert {m.frame_id for m in pdo.messages} <= canopen


def test_example_controller_is_written_without_agrihil() -> None:
    """The example controller of the fertilizer guide uses no agrihil code: no header of
    firmware/, no generated codec, and its profile builds only its own source."""
    from hil.dut.profile import load_profile

    folder = REPO / "docs/examples/my-fertilizer-controller"
    source = (folder / "my_fert.c").read_text(encoding="utf-8")
    includes = set(re.findall(r'#include\s*[<"]([^>"]+)', source))
    standard = {"errno.h", "math.h", "netdb.h", "netinet/in.h", "netinet/tcp.h", "signal.h",
                "stdbool.h", "stdint.h", "stdio.h", "stdlib.h", "string.h", "sys/socket.h",
                "unistd.h"}
    assert includes <= standard, f"not a C library or POSIX header: {includes - standard}"
    profile = load_profile(folder / "fertilizer-my-controller-firmware.toml")
    assert profile.build is not None
    assert list(profile.build.sources) == ["{profile_dir}/my_fert.c"]
    assert not any("firmware" in arg for arg in profile.build.command)


def test_byo_controller_page_quotes_the_check() -> None:
    """The page "Bringing your own controller" quotes what ``hil profile check`` says of the
    unedited binding: the quote is that output, line for line (paths shortened to ``…``), so a
    change of the check or of ``hil profile bind`` shows here."""
    doc = "docs/guide/bringing-your-own-controller.md"
    profile = "docs/examples/byo-fertilizer/ratemaster-rc400-first-try.toml"
    (quoted,) = [b for b in blocks(doc) if b.lang == "text"
                 and any("hil: error:" in t for _, t in b.lines)]
    result = run([str(Path(sys.executable).with_name("hil")), "profile", "check", profile], REPO)
    assert result.returncode == 2, result.stderr
    said = [re.sub(r"\S*ratemaster[-_]rc400[.-]", "…", line)
            for line in (result.stdout + result.stderr).splitlines() if line.startswith("hil: ")]
    assert said == [t for _, t in quoted.lines]
