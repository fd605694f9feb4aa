"""Software bus throughput and round-trip latency across processes (python-can clients).

Round trip: client A (this process, python-can ``socketcand``) sends a frame, an echo peer
(another process, python-can ``socketcand``) answers with id+1, A receives it. Configurations:

``thread``
    the server is a :class:`SoftwareBus`, a thread of client A's process (shares A's GIL);
``process``
    the server is a :class:`SoftwareBusProcess`, a process of its own;
``process+busy``
    as ``process``, plus a third process spinning in a busy loop (a noisy neighbour);
``process/1cpu``
    as ``process``, with A, the server and the echo peer pinned to one vCPU (the idlest).

Each configuration runs ``RUNS`` times, interleaved round-robin so drift in the machine's load
hits them alike, each run with fresh processes (the kernel places a process when it starts and
it then rarely migrates, so the placement is part of what a run samples). Every run prints
its percentiles, the hypervisor steal and the *foreign* load (CPU time of processes that are
not part of the benchmark) over the run, and where A, the server and the echo peer ran. The
summary gives the median over runs, with the range.

What moves the figures, measured on the 2-vCPU VMs this project develops on (nested
virtualisation, guest halt polling off), 160 runs: waking a process that sleeps on the *other*
vCPU costs ~35-45 µs, charged to the sender's ``send()`` (a few µs on the same vCPU). A round
trip through the server is four hand-offs. On an idle machine the scheduler spreads the three
processes over both vCPUs and leaves them there: p50 ~270 µs, p99 ~550 µs, whatever the server
does. On one vCPU (``process/1cpu``, or packed there by a busy neighbour on the other):
p50 ~120 µs, p99 ~240-270 µs. Other load on *that* vCPU moves p99 to milliseconds (a woken
process waits for a time slice); real-time priority helps only if all three have it. Of the
CPU a packed round trip costs, each python-can client takes ~35-45 µs, the server ~55 µs.

``HIL_BENCH_RUNS`` (default 5) and ``HIL_BENCH_ROUND_TRIPS`` (default 2000) set the sizes.
"""

from __future__ import annotations

import contextlib
import glob
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np
import pytest

from hil.bus import open_bus
from hil.softbus import SoftwareBus, SoftwareBusProcess

HELPERS = Path(__file__).resolve().parents[1] / "tests" / "helpers"
RUNS = int(os.environ.get("HIL_BENCH_RUNS", "5"))
ROUND_TRIPS = int(os.environ.get("HIL_BENCH_ROUND_TRIPS", "2000"))
CONFIGS = ("thread", "process", "process+busy", "process/1cpu")
TARGET_P99_US = 300.0


# -- what the machine was doing -------------------------------------------------------------
def _cpu_times() -> tuple[int, int, int]:
    """(steal, total, busy) jiffies over all CPUs, from /proc/stat."""
    with open("/proc/stat") as f:
        values = [int(v) for v in f.readline().split()[1:]]
    idle = values[3] + values[4]
    return values[7], sum(values), sum(values) - idle


def _task_ns(pid: int, tid: int | None = None) -> int:
    """On-CPU time of all threads of ``pid`` (or of thread ``tid``) in ns (not tick-sampled)."""
    total = 0
    for path in glob.glob(f"/proc/{pid}/task/{tid or '*'}/schedstat"):
        with contextlib.suppress(OSError, ValueError), open(path) as f:
            total += int(f.read().split()[0])
    return total


def _last_cpu(pid: int, tid: int | None = None) -> str:
    try:
        with open(f"/proc/{pid}/task/{tid}/stat" if tid else f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[36]
    except (OSError, IndexError):
        return "?"


def _pin(pid: int, cpu: int) -> None:
    for task in glob.glob(f"/proc/{pid}/task/*"):
        with contextlib.suppress(OSError):
            os.sched_setaffinity(int(task.rsplit("/", 1)[1]), {cpu})


def _idlest_cpu(sample_s: float = 0.2) -> int:
    def per_cpu() -> dict[int, int]:
        out = {}
        with open("/proc/stat") as f:
            for line in f:
                if line.startswith("cpu") and line[3].isdigit():
                    name, *vals = line.split()
                    out[int(name[3:])] = int(vals[3]) + int(vals[4])
        return out
    before = per_cpu()
    time.sleep(sample_s)
    after = per_cpu()
    allowed = os.sched_getaffinity(0)
    return max((c for c in after if c in allowed), key=lambda c: after[c] - before[c])


# -- one run ----------------------------------------------------------------------------------
@dataclass
class Run:
    config: str
    rtt_us: list[float]
    steal_pct: float
    foreign_pct: float
    placement: str
    server_cpu_us: float  # server CPU time per round trip (its process, or its thread)

    def pct(self, q: float) -> float:
        return float(np.percentile(self.rtt_us, q))


@dataclass
class Echo:
    spec: str
    proc: subprocess.Popen[str] = field(init=False)

    def __enter__(self) -> Echo:
        self.proc = subprocess.Popen([sys.executable, str(HELPERS / "softbus_echo.py"), self.spec],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None and self.proc.stdout.readline().strip() == "ready"
        return self

    def __exit__(self, *exc: object) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)


@contextlib.contextmanager
def _busy_neighbour() -> Iterator[subprocess.Popen[bytes]]:
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield proc
    finally:
        proc.kill()
        proc.wait(10)


def _round_trips(spec: str, n: int, *, server_pid: int, echo: Echo, server_tid: int | None = None,
                 extra_pids: tuple[int, ...] = (), pin_to: int | None = None) -> Run:
    """``n`` round trips from this process; the server is process ``server_pid`` (or its
    thread ``server_tid`` when it runs inside this process)."""
    bus = open_bus(spec)
    own_mask = os.sched_getaffinity(0)
    try:
        if pin_to is not None:
            os.sched_setaffinity(0, {pin_to})
            for pid in {echo.proc.pid, server_pid}:
                _pin(pid, pin_to)
        msg = can.Message(arbitration_id=0x100, data=bytes(8), is_extended_id=False)
        for _ in range(200):  # warm-up: caches, allocator, TCP state
            bus.send(msg)
            assert bus.recv(1.0) is not None
        ours = {os.getpid(), echo.proc.pid, server_pid, *extra_pids}
        cpu0 = {pid: _task_ns(pid) for pid in ours}
        server0 = _task_ns(server_pid, server_tid)
        steal0, total0, busy0 = _cpu_times()
        clock = time.perf_counter_ns
        rtt = []
        for _ in range(n):
            start = clock()
            bus.send(msg)
            reply = bus.recv(1.0)
            rtt.append((clock() - start) / 1000)
            assert reply is not None and reply.arbitration_id == 0x101
        steal1, total1, busy1 = _cpu_times()
        cpu1 = {pid: _task_ns(pid) for pid in ours}
        server1 = _task_ns(server_pid, server_tid)
        where = (f"A@{_last_cpu(os.getpid())} echo@{_last_cpu(echo.proc.pid)} "
                 f"srv@{_last_cpu(server_pid, server_tid)}")
    finally:
        os.sched_setaffinity(0, own_mask)
        bus.shutdown()
    jiffy_ns = 1e9 / os.sysconf("SC_CLK_TCK")
    ours_jiffies = sum(cpu1[p] - cpu0[p] for p in ours) / jiffy_ns
    elapsed = max(1, total1 - total0)
    return Run(config="", rtt_us=rtt, steal_pct=100.0 * (steal1 - steal0) / elapsed,
               foreign_pct=100.0 * max(0.0, (busy1 - busy0) - ours_jiffies) / elapsed,
               placement=where, server_cpu_us=(server1 - server0) / n / 1000)


def _one_run(config: str, n: int) -> Run:
    if config == "thread":
        with SoftwareBus(port=0) as bus, Echo(bus.spec()) as echo:
            assert bus._thread is not None
            time.sleep(0.1)
            run = _round_trips(bus.spec(), n, server_pid=os.getpid(), echo=echo,
                               server_tid=bus._thread.native_id)
    else:
        with SoftwareBusProcess(port=0) as server, Echo(server.spec()) as echo:
            assert server.proc is not None
            time.sleep(0.1)
            if config == "process+busy":
                with _busy_neighbour() as busy:
                    time.sleep(0.1)
                    run = _round_trips(server.spec(), n, server_pid=server.proc.pid, echo=echo,
                                       extra_pids=(busy.pid,))
            else:
                pin = _idlest_cpu() if config == "process/1cpu" else None
                run = _round_trips(server.spec(), n, server_pid=server.proc.pid, echo=echo,
                                   pin_to=pin)
    run.config = config
    return run


def _summary(runs: list[Run]) -> str:
    def spread(values: list[float]) -> str:
        return f"{statistics.median(values):5.0f} [{min(values):.0f}-{max(values):.0f}]"
    p50 = [r.pct(50) for r in runs]
    p99 = [r.pct(99) for r in runs]
    p999 = [r.pct(99.9) for r in runs]
    met = sum(v <= TARGET_P99_US for v in p99)
    return (f"p50 {spread(p50)}  p99 {spread(p99)}  p99.9 {spread(p999)} us; "
            f"steal {statistics.median(r.steal_pct for r in runs):.2f}% "
            f"(max {max(r.steal_pct for r in runs):.2f}%), foreign load "
            f"{statistics.median(r.foreign_pct for r in runs):.0f}%; "
            f"p99 <= {TARGET_P99_US:.0f} us in {met}/{len(runs)} runs")


def test_round_trip_latency(benchmark) -> None:
    runs: dict[str, list[Run]] = {c: [] for c in CONFIGS}

    def measure() -> None:
        for i in range(RUNS):
            order = CONFIGS if i % 2 == 0 else CONFIGS[::-1]
            for config in order:
                run = _one_run(config, ROUND_TRIPS)
                runs[config].append(run)
                print(f"\n  run {i + 1} {config:13s} p50 {run.pct(50):5.0f}  p99 {run.pct(99):5.0f}"
                      f"  p99.9 {run.pct(99.9):6.0f} us  steal {run.steal_pct:.2f}%  foreign "
                      f"{run.foreign_pct:3.0f}%  {run.placement}  server "
                      f"{run.server_cpu_us:.0f} us CPU/RTT", end="")

    benchmark.pedantic(measure, rounds=1, iterations=1)
    print(f"\nsoftware bus round trip, python-can client <-> python-can echo peer, "
          f"{RUNS} runs x {ROUND_TRIPS} round trips, median [range] over runs "
          f"(target p99 <= {TARGET_P99_US:.0f} us):")
    for config in CONFIGS:
        print(f"  {config:13s} {_summary(runs[config])}")
        benchmark.extra_info[config] = {
            "p50_us": statistics.median(r.pct(50) for r in runs[config]),
            "p99_us": statistics.median(r.pct(99) for r in runs[config]),
            "p999_us": statistics.median(r.pct(99.9) for r in runs[config]),
            "steal_pct": statistics.median(r.steal_pct for r in runs[config]),
            "foreign_pct": statistics.median(r.foreign_pct for r in runs[config])}


@pytest.fixture(scope="module")
def server() -> Iterator[SoftwareBusProcess]:
    with SoftwareBusProcess(port=0) as proc:
        yield proc


def test_throughput_cross_process(benchmark, server: SoftwareBusProcess) -> None:
    n = 20_000
    sender = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, can; from hil.bus import open_bus\n"
         "b = open_bus(sys.argv[1]); print('ready', flush=True)\n"
         "for line in sys.stdin:\n"
         "    for i in range(int(line)):\n"
         "        b.send(can.Message(arbitration_id=0x200, data=i.to_bytes(4, 'little'),"
         " is_extended_id=False))\n"
         "b.shutdown()\n", server.spec()],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert sender.stdout is not None and sender.stdout.readline().strip() == "ready"
    receiver = open_bus(server.spec())
    time.sleep(0.1)
    lost = []

    def burst() -> None:
        assert sender.stdin is not None
        sender.stdin.write(f"{n}\n")
        sender.stdin.flush()
        got = 0
        expected = 0
        while got < n:
            msg = receiver.recv(2.0)
            if msg is None:
                break
            seq = int.from_bytes(msg.data, "little")
            if seq != expected:
                lost.append((expected, seq))
            expected = seq + 1
            got += 1
        if got < n:
            lost.append(("short", got))

    steal0, total0, _ = _cpu_times()
    try:
        benchmark.pedantic(burst, rounds=3, iterations=1)
    finally:
        receiver.shutdown()
        assert sender.stdin is not None
        sender.stdin.close()
        sender.wait(10)
    steal1, total1, _ = _cpu_times()
    rate = n / benchmark.stats.stats.median
    benchmark.extra_info.update(frames_per_s=rate, lost=len(lost))
    print(f"\nsoftware bus throughput (2 processes): {rate:,.0f} frames/s, "
          f"{'no loss' if not lost else f'LOSS {lost[:3]}'} (target >= 20,000); steal "
          f"{100.0 * (steal1 - steal0) / max(1, total1 - total0):.2f}%")
    assert not lost  # loss is a correctness failure, not a timing figure
