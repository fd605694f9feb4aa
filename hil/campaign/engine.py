"""The campaign engine: samples over Dask distributed, results kept as they arrive.

Dask does the scheduling: an embedded ``LocalCluster`` of K single-threaded worker processes
by default, or any running cluster by its scheduler address (``dask scheduler`` and ``dask
worker`` on other machines). agrihil only defines a sample (:func:`hil.campaign.sample.run_sample`).
A sample whose worker died (after Dask's own retries) comes back as an error sample naming the
reason; finished samples are appended to ``samples.jsonl`` and ``campaign.json`` is rewritten
as they arrive, so Ctrl-C (or a lost driver) never loses them.
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import os
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.campaign.decision import Decision, decide, sprt_of
from hil.campaign.dispersion import Dispersion
from hil.campaign.record import SAMPLES_NAME, SCHEMA, clean, write_record
from hil.campaign.sample import SampleTask, run_sample
from hil.campaign.summary import summarize
from hil.dut.profile import DutProfile
from hil.errors import HilError

#: rewrite campaign.json at most this often while samples arrive
_REWRITE_S = 5.0


class CampaignError(HilError, RuntimeError):
    """The campaign's machinery failed (no scheduler at the address, the cluster went away)."""


@dataclass
class CampaignPlan:
    """What to run: the profile, how many samples from which seed, on what, dispersed how."""

    profile: DutProfile
    samples: int
    seed: int = 0
    bus: str = "softbus"
    clock: str = "lockstep"
    suites: str = "fast"
    dispersion: Dispersion | None = None
    timeout_s: float = 600.0
    keyword: str | None = None
    #: worst samples rerun per measurement, and the most reruns in all
    worst: int = 1
    max_reruns: int = 10
    isolation: str = "process"
    #: when to stop (hil.campaign.decision): "fixed" (all N), "curtailed" (as soon as the
    #: N-sample verdict is settled) or "sequential" (Wald's SPRT)
    rule: str = "fixed"
    campaign_id: str = field(default_factory=lambda: uuid.uuid4().hex[:12])

    def task(self, index: int, *, record: str = "measurements", out_dir: str = ""
             ) -> SampleTask:
        """Sample ``index``: seed ``seed + index`` and its dispersed parameters."""
        seed = self.seed + index
        overrides = self.dispersion.draw(seed) if self.dispersion else {}
        return SampleTask(profile=str(Path(str(self.profile.path)).resolve()), index=index,
                          seed=seed, bus=self.bus, clock=self.clock, suites=self.suites,
                          overrides=overrides, record=record, out_dir=out_dir,
                          timeout_s=self.timeout_s, keyword=self.keyword,
                          isolation=self.isolation if record == "measurements" else "process")


@contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None,
                connect_timeout_s: float = 10.0) -> Iterator[Any]:
    """A Dask client: of the cluster at ``scheduler`` (given up after ``connect_timeout_s``),
    or of a new ``LocalCluster`` of ``workers`` single-threaded processes (default: the
    cores)."""
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=connect_timeout_s)
        except (OSError, TimeoutError) as exc:
            raise CampaignError(f"no Dask scheduler at {scheduler} (--scheduler): nothing "
                                f"answered within {connect_timeout_s:g} s "
                                f"(--connect-timeout-s)") from exc
        try:
            yield client
        finally:
            client.close()
        return
    # a sample that kills its worker twice is an error sample, not three more dead workers;
    # non-daemonic workers may start the fork server (hil/campaign/forked.py); and the
    # workers keep no long history for a dashboard nobody watches: with Dask's defaults (a
    # system-monitor sample every 0.5 s kept for an hour, 1000-10000 log entries) a worker
    # grew 0.8 MB a minute, ~16 MB over a 300-sample campaign, and stays flat with these
    # (measured with 1-worker clusters of 0.5 s tasks for 3 min: +2.0 MB against +0.2 MB)
    #
    # Each worker holds only the sample it runs (worker-saturation 1.0; Dask's 1.1 gives a
    # one-thread worker a second, queued one): a worker that a sample kills takes no queued
    # sample with it, so a good sample is never charged with the deaths of a killer's worker
    # and its retry's (seen: "2 workers died while trying to run it" on an innocent sample).
    with dask.config.set({"distributed.scheduler.allowed-failures": 1,
                          "distributed.scheduler.worker-saturation": 1.0,
                          "distributed.worker.daemon": False,
                          "distributed.admin.system-monitor.log-length": 120,
                          "distributed.admin.low-level-log-length": 100,
                          "distributed.admin.log-length": 1000,
                          # Ctrl-C reaches the campaign, not the workers (no tracebacks)
                          "distributed.worker.preload": ["hil.campaign.quiet_worker"]}):
        logging.getLogger("distributed").setLevel(logging.ERROR)
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=":0", scheduler_port=0,
                               memory_limit=0, silence_logs=logging.ERROR)
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
            cluster.close()


def error_sample(task: SampleTask, reason: str) -> dict[str, Any]:
    return {"index": task.index, "seed": task.seed, "overrides": dict(task.overrides),
            "verdict": "error", "error": reason, "measurements": [], "failed_tests": [],
            "worker": None, "wall_s": None}


def map_samples(client: Any, tasks: list[SampleTask],
                on_sample: Callable[[dict[str, Any]], bool | None], *, prefix: str) -> None:
    """Run ``tasks`` on ``client``; call ``on_sample`` with each sample as it finishes, and
    stop (cancelling the samples not finished) when it returns True."""
    from dask.distributed import as_completed

    futures = {client.submit(run_sample, t, key=f"{prefix}-{t.index}", pure=False): t
               for t in tasks}
    try:
        for future in as_completed(list(futures)):
            task = futures[future]
            if future.status == "finished":
                sample = future.result()
            else:
                try:
                    exc = future.exception()
                    reason = f"worker failed: {type(exc).__name__}: {exc}"
                except Exception as other:  # the future itself is gone (cancelled, lost)
                    reason = f"worker failed: {type(other).__name__}: {other}"
                sample = error_sample(task, reason[:800])
            future.release()
            if on_sample(sample):
                break
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending, force=True)


class Campaign:
    """One campaign's state: its samples so far, written out as they arrive."""

    def __init__(self, plan: CampaignPlan, out: Path, *, engine: dict[str, Any]) -> None:
        self.plan = plan
        self.out = out
        self.engine = engine
        self.samples: list[dict[str, Any]] = []
        self.reruns: list[dict[str, Any]] = []
        self.status = "running"
        self.started_at = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        self.t0 = time.perf_counter()
        self._written = 0.0
        #: samples.jsonl, opened with the first sample: a campaign that never began writes
        #: nothing
        self._jsonl: Any = None
        #: the stopping rule's verdict once it decided before the N samples (None: not yet)
        self.decision: Decision | None = None

    def add(self, sample: dict[str, Any]) -> bool:
        """Keep ``sample``: appended to samples.jsonl at once, campaign.json now and then.
        True when the stopping rule has decided (the campaign may stop)."""
        sample = clean(sample)
        self.samples.append(sample)
        if self._jsonl is None:
            self.out.mkdir(parents=True, exist_ok=True)
            self._jsonl = (self.out / SAMPLES_NAME).open("w", encoding="utf-8")
        self._jsonl.write(json.dumps(sample) + "\n")
        self._jsonl.flush()
        decision = decide(self.plan.rule, self.samples, self.plan.samples,
                          self.requirement_dict())
        # a settled pass or fail ends the campaign; a settled inconclusive does not: its
        # samples still show the distributions (and how far the requirement is)
        if decision.verdict in ("pass", "fail") and len(self.samples) < self.plan.samples:
            self.decision = decision
        if time.perf_counter() - self._written > _REWRITE_S:
            self.write()
        return self.decision is not None

    def requirement(self) -> tuple[float | None, float]:
        req = self.plan.profile.campaign
        return (req.pass_probability, req.confidence) if req else (None, 0.95)

    def requirement_dict(self) -> dict[str, Any] | None:
        """The profile's ``[campaign]`` as the record keeps it (None: no requirement)."""
        req = self.plan.profile.campaign
        if req is None:
            return None
        out: dict[str, Any] = {"pass_probability": req.pass_probability,
                               "confidence": req.confidence}
        if req.sequential_good_probability is not None:
            out["sequential_good_probability"] = req.sequential_good_probability
        if req.sequential_alpha is not None:
            out["sequential_alpha"] = req.sequential_alpha
        return out

    def decision_dict(self) -> dict[str, Any]:
        """``decision``: the stopping rule, samples used and saved, and (when it decided) its
        verdict and why."""
        plan = self.plan
        done = len(self.samples)
        decision = self.decision
        if decision is None and plan.rule != "fixed" and self.status == "complete":
            decision = decide(plan.rule, self.samples, plan.samples, self.requirement_dict())
        out: dict[str, Any] = {
            "rule": plan.rule, "samples_requested": plan.samples, "samples_run": done,
            "samples_used": decision.used if decision and decision.verdict else done,
            "samples_saved": plan.samples - done if self.status == "complete" else 0,
            "early": self.decision is not None,
            "verdict": decision.verdict if decision else None,
            "reason": decision.reason if decision and decision.verdict else None}
        if plan.rule == "sequential":
            out["sprt"] = sprt_of(self.requirement_dict() or {}).to_dict()
        return out

    def document(self) -> dict[str, Any]:
        p, confidence = self.requirement()
        samples = sorted(self.samples, key=lambda s: s["index"])
        summary, measurements = summarize(samples, pass_probability=p, confidence=confidence,
                                          worst=max(3, self.plan.worst))
        decision = self.decision_dict()
        if decision["verdict"] is not None and self.status == "complete" \
                and (decision["early"] or self.plan.rule == "sequential"):
            # the rule's verdict: curtailment's is the N-sample verdict (the exact bounds of
            # the samples run agree with it), the SPRT's its own
            summary["verdict"], summary["reason"] = decision["verdict"], decision["reason"]
            if decision["early"]:
                summary["reason"] += (f" (decided after {decision['samples_run']} of "
                                      f"{self.plan.samples} samples)")
        failed_bus = [r for r in self.reruns if r.get("conformance_failed")]
        if failed_bus and summary["verdict"] in ("pass", "inconclusive"):
            # the samples keep no bus log; their reruns with full recording judge the bus
            # conformance, which is the build's, not a seed's luck: one failure fails it all
            first = min(failed_bus, key=lambda r: r["index"])
            summary["verdict"] = "fail"
            summary["reason"] = (
                f"bus conformance failed in the rerun of sample {first['index']} with full "
                f"recording: {', '.join(first['conformance_failed'])} (the samples' "
                f"{summary['reason']})")
        if self.status == "interrupted":
            summary["reason"] += (f" (interrupted after {len(samples)} of "
                                  f"{self.plan.samples} samples)")
        plan = self.plan
        rig = plan.profile.dut.rig
        return clean({
            "schema": SCHEMA,
            "campaign_id": plan.campaign_id,
            "status": self.status,
            "started_at": self.started_at,
            "wall_s": round(time.perf_counter() - self.t0, 3),
            "dut": {**plan.profile.identity(), "parameters": plan.profile.parameters},
            "rig": {"name": rig, "config_overrides": plan.profile.rig_config},
            "bus": plan.bus, "clock": plan.clock, "suites": plan.suites,
            "keyword": plan.keyword, "seed": plan.seed, "samples_requested": plan.samples,
            "dispersion": plan.dispersion.to_dict() if plan.dispersion else None,
            "requirement": self.requirement_dict(),
            "decision": decision,
            "engine": self.engine,
            "summary": summary,
            "measurements": measurements,
            "samples": samples,
            "reruns": sorted(self.reruns, key=lambda r: r["index"]),
        })

    def write(self) -> Path:
        self._written = time.perf_counter()
        self.out.mkdir(parents=True, exist_ok=True)
        if self._jsonl is None:     # no sample yet: an empty samples.jsonl says so
            (self.out / SAMPLES_NAME).touch()
        return write_record(self.out, self.document())

    def close(self) -> None:
        if self._jsonl is not None:
            self._jsonl.close()


def rerun_selection(doc: dict[str, Any], *, worst: int, max_reruns: int) -> list[int]:
    """Samples to rerun with full recording: the failing ones first, then the ``worst`` of
    each measurement, at most ``max_reruns`` in all."""
    chosen: list[int] = list(doc["summary"]["failing_samples"])
    for stats in doc["measurements"].values():
        for index in stats["worst"][:worst]:
            if index not in chosen:
                chosen.append(index)
    return chosen[:max_reruns]


def same_measurements(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> bool:
    """True when two samples measured the same values (bit for bit; NaN equals NaN)."""
    def key(ms: list[dict[str, Any]]) -> list[tuple[str, str, Any, Any]]:
        return sorted((m["name"], json.dumps(m.get("conditions"), sort_keys=True),
                       m.get("value"), m.get("outcome")) for m in ms)
    return key(a) == key(b)
